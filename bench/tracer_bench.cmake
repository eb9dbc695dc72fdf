# afr-bench-tracer: tracer throughput on the built-in scene and a glTF scene (tracer_bench.cpp).
# Included from bench/CMakeLists.txt.
add_executable(afr-bench-tracer ${CMAKE_CURRENT_LIST_DIR}/tracer_bench.cpp)
target_link_libraries(afr-bench-tracer PRIVATE afr_sampler afr_common CLI11::CLI11 fmt::fmt
  Threads::Threads)
