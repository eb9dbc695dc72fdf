# Fails when a program that never reads or writes an image file records OpenImageIO among the
# shared libraries it needs. OpenImageIO brings some 260 libraries, and resolving their symbols
# costs every process that loads them about 0.25 s and 130 MB (0.5 s under AddressSanitizer),
# each test process included. Only image_io.cpp calls it, in an object of its own
# (common/CMakeLists.txt), and programs link --as-needed (CMakeLists.txt), so a program that does
# not call write_image or read_image drops it. To see the difference (a test binary with and one
# without OpenImageIO, running no test):
#   for t in afr_image_test afr_common_test; do ldd build/tests/common/$t | wc -l
#     /usr/bin/time -f "%e s %M KB" build/tests/common/$t --gtest_filter=None >/dev/null; done
#   cmake -DREADELF=<readelf> -DPROGRAMS="<file>;<file>..." -P cmake/check_needed_libraries.cmake

if(NOT READELF OR NOT PROGRAMS)
  message(FATAL_ERROR "usage: cmake -DREADELF=<readelf> -DPROGRAMS=<files> -P ${CMAKE_SCRIPT_MODE_FILE}")
endif()

set(failed FALSE)
foreach(program IN LISTS PROGRAMS)
  if(NOT EXISTS "${program}")
    message(SEND_ERROR "${program}: no such program (build it first)")
    set(failed TRUE)
    continue()
  endif()
  execute_process(COMMAND "${READELF}" --dynamic "${program}"
    OUTPUT_VARIABLE dynamic RESULT_VARIABLE rc ERROR_VARIABLE error)
  if(NOT rc EQUAL 0)
    message(SEND_ERROR "${program}: readelf failed: ${error}")
    set(failed TRUE)
    continue()
  endif()
  string(REGEX MATCHALL "Shared library: \\[[^]]*\\]" needed "${dynamic}")
  list(LENGTH needed count)
  if(count EQUAL 0)
    message(SEND_ERROR "${program}: readelf lists no shared libraries (not a dynamic program?)")
    set(failed TRUE)
    continue()
  endif()
  get_filename_component(name "${program}" NAME)
  set(bad FALSE)
  foreach(entry IN LISTS needed)
    if(entry MATCHES "\\[(.*OpenImageIO.*)\\]")
      message(SEND_ERROR "${name} needs ${CMAKE_MATCH_1}: it never reads or writes an image file, and "
        "should start without OpenImageIO's libraries (an object of afr_common that calls "
        "OpenImageIO was pulled in: see common/CMakeLists.txt)")
      set(bad TRUE)
      set(failed TRUE)
    endif()
  endforeach()
  if(NOT bad)
    message(STATUS "${name}: ${count} shared libraries, none of them OpenImageIO")
  endif()
endforeach()

if(failed)
  message(FATAL_ERROR "a program records OpenImageIO that should not")
endif()
