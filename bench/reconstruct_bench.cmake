# afr-bench-reconstruct: reconstruction time versus resolution and N for the CPU and OpenGL
# backends (reconstruct_bench.cpp). Included from bench/CMakeLists.txt.
add_executable(afr-bench-reconstruct ${CMAKE_CURRENT_LIST_DIR}/reconstruct_bench.cpp)
target_link_libraries(afr-bench-reconstruct PRIVATE afr_display afr_common CLI11::CLI11
  fmt::fmt Threads::Threads)
# Only the libraries it calls: without OpenImageIO's tree it runs from a small bundle on a GPU
# server that lacks afr's build dependencies (bench/gpu.sh, deploy/bundle.sh).
target_link_options(afr-bench-reconstruct PRIVATE -Wl,--as-needed)

# afr-bench-binned-gather: a floor under a splat pass that bins on the CPU and gathers on the GL
# device (binned_gather_bench.cpp; docs/benchmarks.md, "GPU reconstructor"). It builds its
# program with the GL backend's helper (display_node/src/gl_program.h).
add_executable(afr-bench-binned-gather ${CMAKE_CURRENT_LIST_DIR}/binned_gather_bench.cpp)
target_include_directories(afr-bench-binned-gather PRIVATE ${PROJECT_SOURCE_DIR}/display_node/src)
target_link_libraries(afr-bench-binned-gather PRIVATE afr_display afr_common CLI11::CLI11 fmt::fmt)
target_link_options(afr-bench-binned-gather PRIVATE -Wl,--as-needed)
