# afr-bench-protocol: codec cost per sample and loopback PUSH/PULL throughput of sample batches
# (protocol_bench.cpp, Google Benchmark). Included from bench/CMakeLists.txt.
add_executable(afr-bench-protocol ${CMAKE_CURRENT_LIST_DIR}/protocol_bench.cpp)
target_link_libraries(afr-bench-protocol PRIVATE afr_protocol afr_zeromq benchmark::benchmark
  Threads::Threads)
