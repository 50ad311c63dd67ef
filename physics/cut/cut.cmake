# Cutting (physics/cut): continuous collision, its broad phase, and volume cutting of the
# EFG model (seed 004 §2.1-2.4). Included by physics/CMakeLists.txt after
# add_library(incise_physics ...); the top level has already run find_package(PkgConfig).
#
# Its own library because the broad phase uses Bullet's btDbvt (STYLE.md: use it rather
# than writing another AABB tree); the rest of physics stays Eigen only.
add_library(incise_cut STATIC
  ${CMAKE_CURRENT_LIST_DIR}/continuous_collision.cpp
  ${CMAKE_CURRENT_LIST_DIR}/broad_phase.cpp
  ${CMAKE_CURRENT_LIST_DIR}/volume_cut.cpp
  ${CMAKE_CURRENT_LIST_DIR}/rest_cut.cpp
  ${CMAKE_CURRENT_LIST_DIR}/surface_topology.cpp
  ${CMAKE_CURRENT_LIST_DIR}/linked_across.cpp
  ${CMAKE_CURRENT_LIST_DIR}/voxel_boundary.cpp
  ${CMAKE_CURRENT_LIST_DIR}/cut_body.cpp
  ${CMAKE_CURRENT_LIST_DIR}/detect_cuts.cpp
  ${CMAKE_CURRENT_LIST_DIR}/cutting_resistance.cpp
  ${CMAKE_CURRENT_LIST_DIR}/apply_topology.cpp
  ${CMAKE_CURRENT_LIST_DIR}/remap_surface.cpp
  ${CMAKE_CURRENT_LIST_DIR}/front_surface.cpp
  ${CMAKE_CURRENT_LIST_DIR}/front_edge_table.cpp
  ${CMAKE_CURRENT_LIST_DIR}/front_binning.cpp
  ${CMAKE_CURRENT_LIST_DIR}/front_face_reuse.cpp
  ${CMAKE_CURRENT_LIST_DIR}/front_recompute.cpp
  ${CMAKE_CURRENT_LIST_DIR}/front_crossings.cpp
  ${CMAKE_CURRENT_LIST_DIR}/front_outline.cpp
  ${CMAKE_CURRENT_LIST_DIR}/front_split.cpp
  ${CMAKE_CURRENT_LIST_DIR}/front_lattice.cpp
  ${CMAKE_CURRENT_LIST_DIR}/front_cut_face.cpp
  ${CMAKE_CURRENT_LIST_DIR}/front_mapping.cpp
  ${CMAKE_CURRENT_LIST_DIR}/triangulate_2d.cpp
)
target_link_libraries(incise_cut PUBLIC incise_physics)
target_compile_features(incise_cut PUBLIC cxx_std_20)

# Bullet's pkg-config file names all four of its libraries; the tree needs only
# BulletCollision (btDbvt) and LinearMath (btVector3, btAlignedAllocator). Take the include
# directories and flags from pkg-config (they fix btScalar's precision, which must match the
# library) and link the two libraries alone when they are where pkg-config says.
pkg_check_modules(BULLET REQUIRED IMPORTED_TARGET bullet)
find_library(INCISE_BULLET_COLLISION BulletCollision HINTS ${BULLET_LIBRARY_DIRS} NO_CACHE)
find_library(INCISE_BULLET_LINEAR_MATH LinearMath HINTS ${BULLET_LIBRARY_DIRS} NO_CACHE)
if(INCISE_BULLET_COLLISION AND INCISE_BULLET_LINEAR_MATH)
  target_include_directories(incise_cut SYSTEM PUBLIC ${BULLET_INCLUDE_DIRS})
  target_compile_options(incise_cut PUBLIC ${BULLET_CFLAGS_OTHER})
  target_link_libraries(incise_cut PUBLIC ${INCISE_BULLET_COLLISION} ${INCISE_BULLET_LINEAR_MATH})
else()
  target_link_libraries(incise_cut PUBLIC PkgConfig::BULLET)
endif()
