# Fails, listing the files, when any C++ source differs from what clang-format would write.
# Run: cmake -DCLANG_FORMAT=clang-format -DROOT=. -P cmake/format_check.cmake
get_filename_component(ROOT "${ROOT}" ABSOLUTE)
file(GLOB_RECURSE files RELATIVE ${ROOT}
  ${ROOT}/common/*.h ${ROOT}/common/*.cpp ${ROOT}/protocol/*.h ${ROOT}/protocol/*.cpp
  ${ROOT}/sampler_node/*.h ${ROOT}/sampler_node/*.cpp ${ROOT}/display_node/*.h
  ${ROOT}/display_node/*.cpp ${ROOT}/tools/*.h ${ROOT}/tools/*.cpp ${ROOT}/bench/*.h
  ${ROOT}/bench/*.cpp ${ROOT}/tests/*.h ${ROOT}/tests/*.cpp)
set(bad "")
foreach(f ${files})
  execute_process(COMMAND ${CLANG_FORMAT} --dry-run --Werror ${ROOT}/${f}
    RESULT_VARIABLE rc OUTPUT_QUIET ERROR_QUIET)
  if(NOT rc EQUAL 0)
    list(APPEND bad ${f})
  endif()
endforeach()
if(bad)
  list(JOIN bad "\n  " lines)
  message(FATAL_ERROR "not clang-formatted (run tools/format.sh):\n  ${lines}")
endif()
list(LENGTH files n)
message(STATUS "format check: ${n} files clean")
