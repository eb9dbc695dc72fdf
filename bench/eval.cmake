# The evaluation (docs/evaluation.md): library afr_eval (bench/eval/) and program afr-eval.
# Included from bench/CMakeLists.txt when the display node (afr_display) is built.
add_subdirectory(${CMAKE_CURRENT_LIST_DIR}/eval ${CMAKE_CURRENT_BINARY_DIR}/eval)

add_executable(afr-eval ${CMAKE_CURRENT_LIST_DIR}/afr_eval_main.cpp)
target_link_libraries(afr-eval PRIVATE afr_eval CLI11::CLI11 fmt::fmt)
# Default locations of the camera paths and outputs are relative to the source tree.
target_compile_definitions(afr-eval PRIVATE AFR_SOURCE_DIR="${PROJECT_SOURCE_DIR}")
