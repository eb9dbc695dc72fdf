# afr-bench-reconstruct: reconstruction time versus resolution and N for the CPU and OpenGL
# backends (reconstruct_bench.cpp). Included from bench/CMakeLists.txt.
add_executable(afr-bench-reconstruct ${CMAKE_CURRENT_LIST_DIR}/reconstruct_bench.cpp)
target_link_libraries(afr-bench-reconstruct PRIVATE afr_display afr_common CLI11::CLI11
  fmt::fmt Threads::Threads)
