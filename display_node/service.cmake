# The display_node program and its service parts: coordinator (membership, regions), display
# clock and views, ingest, metrics over HTTP, overlays, the display wall. docs/service.md,
# docs/wall.md.
find_package(PkgConfig REQUIRED)
find_package(prometheus-cpp REQUIRED)
pkg_check_modules(AFR_HTTPLIB REQUIRED IMPORTED_TARGET cpp-httplib)

add_library(afr_display_service
  ${CMAKE_CURRENT_LIST_DIR}/src/service/coordinator.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/service/dashboard.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/service/dashboard_page.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/service/display_app.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/service/display_service.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/service/fly_camera.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/service/latency_histogram.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/service/member_gate.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/service/metrics.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/service/metrics_exposition.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/service/metrics_server.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/service/overlays.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/service/wall.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/service/wall_exchange.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/service/wall_follower.cpp
)
target_include_directories(afr_display_service PUBLIC ${CMAKE_CURRENT_LIST_DIR}/include)
target_link_libraries(afr_display_service
  PUBLIC afr_display afr_protocol Threads::Threads
  PRIVATE PkgConfig::AFR_HTTPLIB nlohmann_json::nlohmann_json glfw prometheus-cpp::core)

add_executable(display_node ${CMAKE_CURRENT_LIST_DIR}/main.cpp)
target_link_libraries(display_node PRIVATE afr_display_service CLI11::CLI11)
