# afr-bench-seam: a 2 x 2 display wall against one display fed every sample, the seam test's
# measurement (tests/support/wall_seam.h, header-only) with its settings as flags
# (seam_bench.cpp). Included from bench/CMakeLists.txt.
add_executable(afr-bench-seam ${CMAKE_CURRENT_LIST_DIR}/seam_bench.cpp)
target_include_directories(afr-bench-seam PRIVATE ${PROJECT_SOURCE_DIR}/tests)
target_link_libraries(afr-bench-seam PRIVATE afr_display_service afr_sampler afr_protocol
  CLI11::CLI11 fmt::fmt Threads::Threads)
