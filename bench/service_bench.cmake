# afr-bench-service: the display's ingest cost per sample and sustained ingest rate over TCP
# loopback, SampleStore append alone, and the synthetic sender / ingest-only receiver of
# deploy/lan/goodput.sh (service_bench.cpp). Included from bench/CMakeLists.txt.
add_executable(afr-bench-service ${CMAKE_CURRENT_LIST_DIR}/service_bench.cpp)
target_link_libraries(afr-bench-service PRIVATE afr_display_service afr_protocol
  benchmark::benchmark CLI11::CLI11 fmt::fmt Threads::Threads)
