# Baudet's hexahedral mass-spring model (physics/mss, seed 003). Included by
# physics/CMakeLists.txt after add_library(incise_physics ...).
target_sources(incise_physics PRIVATE
  ${CMAKE_CURRENT_LIST_DIR}/hex_mesh.cpp
  ${CMAKE_CURRENT_LIST_DIR}/baudet_stiffness.cpp
  ${CMAKE_CURRENT_LIST_DIR}/hex_mass_spring.cpp
  ${CMAKE_CURRENT_LIST_DIR}/mss_static.cpp
  ${CMAKE_CURRENT_LIST_DIR}/van_gelder.cpp
)
