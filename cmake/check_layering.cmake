# Fails when a part includes the headers of a part it must not know (docs/architecture.md,
# "Who may know whom"): common stands on nothing of afr; protocol on common; sampler_node and
# display_node each on common and protocol, side by side, neither including the other.
#   cmake -DSOURCE_DIR=<repo> -P cmake/check_layering.cmake
# (protocol's public headers still include ZeroMQ: channels.h hands out sockets.)

# folder, then the parts (include prefix afr/<part>/, folder <folder of part>) it must not know.
set(must_not_know_common protocol:protocol sampler:sampler_node display:display_node)
set(must_not_know_protocol sampler:sampler_node display:display_node)
set(must_not_know_sampler_node display:display_node)
set(must_not_know_display_node sampler:sampler_node)

set(failed FALSE)
foreach(folder common protocol sampler_node display_node)
  file(GLOB_RECURSE sources "${SOURCE_DIR}/${folder}/*.h" "${SOURCE_DIR}/${folder}/*.cpp")
  file(GLOB_RECURSE builds "${SOURCE_DIR}/${folder}/*.cmake" "${SOURCE_DIR}/${folder}/CMakeLists.txt")
  foreach(entry IN LISTS must_not_know_${folder})
    string(REPLACE ":" ";" entry "${entry}")
    list(GET entry 0 part)
    list(GET entry 1 part_folder)
    foreach(f IN LISTS sources)
      file(STRINGS "${f}" hits REGEX "#include [<\"]afr/${part}/")
      foreach(hit IN LISTS hits)
        file(RELATIVE_PATH rel "${SOURCE_DIR}" "${f}")
        message(SEND_ERROR "${rel}: ${folder}/ must not include afr/${part}/: ${hit}")
        set(failed TRUE)
      endforeach()
    endforeach()
    # An include path into the other part is the same leak.
    foreach(f IN LISTS builds)
      file(STRINGS "${f}" hits REGEX "include_directories.*${part_folder}/include")
      foreach(hit IN LISTS hits)
        file(RELATIVE_PATH rel "${SOURCE_DIR}" "${f}")
        message(SEND_ERROR "${rel}: ${folder}/ must not use ${part_folder}/include: ${hit}")
        set(failed TRUE)
      endforeach()
    endforeach()
  endforeach()
endforeach()
if(NOT failed)
  message(STATUS "layering holds: common < protocol < sampler_node | display_node")
endif()
