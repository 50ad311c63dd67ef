# The needle (seed 002 §2.3, Marchal 2006): a rigid needle of aligned nodes acting on a body's
# nodes through zones of influence (puncture, cutting, friction, stick-slip), no collision
# detection and no remeshing. Included by physics/CMakeLists.txt after add_library(incise_physics ...).
target_sources(incise_physics PRIVATE
  ${CMAKE_CURRENT_LIST_DIR}/needle_tissue.cpp
  ${CMAKE_CURRENT_LIST_DIR}/needle_zones.cpp
  ${CMAKE_CURRENT_LIST_DIR}/needle.cpp
  ${CMAKE_CURRENT_LIST_DIR}/needle_efg.cpp
)
