# afr-bench-reconstruct: reconstruction time versus resolution and N for the CPU and OpenGL
# backends (reconstruct_bench.cpp). Included from bench/CMakeLists.txt.
add_executable(afr-bench-reconstruct ${CMAKE_CURRENT_LIST_DIR}/reconstruct_bench.cpp)
target_link_libraries(afr-bench-reconstruct PRIVATE afr_display afr_common CLI11::CLI11
  fmt::fmt Threads::Threads)
# Only the libraries it calls: without OpenImageIO's tree it runs from a small bundle on a GPU
# server that lacks afr's build dependencies (bench/gpu.sh, deploy/bundle.sh).
target_link_options(afr-bench-reconstruct PRIVATE -Wl,--as-needed)
