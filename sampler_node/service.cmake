# The sampler_node program: the service around the sampler library (joining a display, scene
# transfer and cache, clock, region changes, reconnection). docs/service.md.
add_library(afr_sampler_service
  ${CMAKE_CURRENT_LIST_DIR}/src/service/sampler_service.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/service/scene_cache.cpp
)
target_include_directories(afr_sampler_service PUBLIC ${CMAKE_CURRENT_LIST_DIR}/include)
target_link_libraries(afr_sampler_service PUBLIC afr_sampler afr_protocol Threads::Threads)

add_executable(sampler_node ${CMAKE_CURRENT_LIST_DIR}/main.cpp)
target_link_libraries(sampler_node PRIVATE afr_sampler_service CLI11::CLI11)
