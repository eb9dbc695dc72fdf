# Fails when a part includes the headers of a part it must not know (docs/architecture.md,
# "Who may know whom"): common stands on nothing of afr; protocol on common; sampler_node and
# display_node each on common and protocol, side by side, neither including the other.
#   cmake -DSOURCE_DIR=<repo> -P cmake/check_layering.cmake
# ZeroMQ is protocol's own: no public header of protocol includes it (the channels expose
# send, receive and wait, not sockets), and neither node's sources include it.

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
# ZeroMQ behind protocol's public headers.
file(GLOB_RECURSE sealed "${SOURCE_DIR}/protocol/include/*.h" "${SOURCE_DIR}/common/*.h"
     "${SOURCE_DIR}/common/*.cpp" "${SOURCE_DIR}/sampler_node/*.h" "${SOURCE_DIR}/sampler_node/*.cpp"
     "${SOURCE_DIR}/display_node/*.h" "${SOURCE_DIR}/display_node/*.cpp")
foreach(f IN LISTS sealed)
  file(STRINGS "${f}" hits REGEX "#include [<\"]zmq(\\.h|\\.hpp|_addon\\.hpp)[>\"]|zmq::")
  foreach(hit IN LISTS hits)
    file(RELATIVE_PATH rel "${SOURCE_DIR}" "${f}")
    message(SEND_ERROR "${rel}: ZeroMQ is afr_protocol's own (use the channels): ${hit}")
    set(failed TRUE)
  endforeach()
endforeach()
if(NOT failed)
  message(STATUS 
    "layering holds: common < protocol < sampler_node | display_node; ZeroMQ inside protocol")
endif()
