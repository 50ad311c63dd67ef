# Dionne's constraint particles (physics/cp, seed 000). Included by physics/CMakeLists.txt
# after add_library(incise_physics ...).
target_sources(incise_physics PRIVATE
  ${CMAKE_CURRENT_LIST_DIR}/constraints.cpp
  ${CMAKE_CURRENT_LIST_DIR}/constraint_particles.cpp
  ${CMAKE_CURRENT_LIST_DIR}/cp_step.cpp
  ${CMAKE_CURRENT_LIST_DIR}/cube_drop.cpp
)
