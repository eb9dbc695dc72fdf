# afr-bench-stability: drift between reconstructions that differ only in the samples' arrival
# order, or between two sample streams (stability_bench.cpp, on tests/support/order_stability.h).
# Included from bench/CMakeLists.txt.
add_executable(afr-bench-stability ${CMAKE_CURRENT_LIST_DIR}/stability_bench.cpp)
target_include_directories(afr-bench-stability PRIVATE ${PROJECT_SOURCE_DIR}/tests)
target_link_libraries(afr-bench-stability PRIVATE afr_bench afr_display afr_common CLI11::CLI11
  fmt::fmt)
