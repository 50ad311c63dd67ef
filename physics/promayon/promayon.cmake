# Promayon's discrete models (seed 002, digest seed-002-promayon.md): the volumetric shape
# memory, the classical spring network it is compared with, the exact volume projection and
# the seed's explicit step. Included by physics/CMakeLists.txt after add_library(incise_physics ...).
target_sources(incise_physics PRIVATE
  ${CMAKE_CURRENT_LIST_DIR}/lattice.cpp
  ${CMAKE_CURRENT_LIST_DIR}/shape_memory.cpp
  ${CMAKE_CURRENT_LIST_DIR}/spring_network.cpp
  ${CMAKE_CURRENT_LIST_DIR}/volume_projection.cpp
  ${CMAKE_CURRENT_LIST_DIR}/seed_step.cpp
  ${CMAKE_CURRENT_LIST_DIR}/promayon_body.cpp
  ${CMAKE_CURRENT_LIST_DIR}/calibration.cpp
  ${CMAKE_CURRENT_LIST_DIR}/truth_cube.cpp
  ${CMAKE_CURRENT_LIST_DIR}/three_atom.cpp
)
