# The corotated EFG model (physics/efg). Included by physics/CMakeLists.txt after
# add_library(incise_physics ...). Its element loops use std::thread.
target_sources(incise_physics PRIVATE
  ${CMAKE_CURRENT_LIST_DIR}/mls.cpp
  ${CMAKE_CURRENT_LIST_DIR}/worker_pool.cpp
  ${CMAKE_CURRENT_LIST_DIR}/corotational_efg.cpp
  ${CMAKE_CURRENT_LIST_DIR}/efg_static.cpp
)
if(NOT TARGET Threads::Threads)
  find_package(Threads REQUIRED)
endif()
target_link_libraries(incise_physics PUBLIC Threads::Threads)
