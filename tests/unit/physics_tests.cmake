# Tests of the physics library. Included from tests/CMakeLists.txt, which has already run
# find_package(GTest) and include(GoogleTest).
add_executable(test_fem
  ${CMAKE_CURRENT_LIST_DIR}/test_fem_generators.cpp
  ${CMAKE_CURRENT_LIST_DIR}/test_fem_static.cpp
  ${CMAKE_CURRENT_LIST_DIR}/test_fem_corotational.cpp
  ${CMAKE_CURRENT_LIST_DIR}/test_fem_cantilever.cpp
)
target_link_libraries(test_fem PRIVATE incise_physics GTest::gtest_main)
gtest_discover_tests(test_fem DISCOVERY_TIMEOUT 60 PROPERTIES LABELS "physics")

add_executable(test_integrator
  ${CMAKE_CURRENT_LIST_DIR}/test_integrator_cg.cpp
  ${CMAKE_CURRENT_LIST_DIR}/test_integrator_implicit_euler.cpp
  ${CMAKE_CURRENT_LIST_DIR}/test_rest_preconditioner.cpp
  ${CMAKE_CURRENT_LIST_DIR}/test_coarse_space.cpp
  ${CMAKE_CURRENT_LIST_DIR}/test_multigrid.cpp
  ${CMAKE_CURRENT_LIST_DIR}/test_current_system.cpp
  ${CMAKE_CURRENT_LIST_DIR}/test_current_vcycle.cpp
  ${CMAKE_CURRENT_LIST_DIR}/test_element_assembly.cpp
  ${CMAKE_CURRENT_LIST_DIR}/test_supernodal_factor.cpp
  ${CMAKE_CURRENT_LIST_DIR}/test_half_float.cpp
  ${CMAKE_CURRENT_LIST_DIR}/test_warm_start.cpp
)
target_link_libraries(test_integrator PRIVATE incise_physics GTest::gtest_main)
gtest_discover_tests(test_integrator DISCOVERY_TIMEOUT 60 PROPERTIES LABELS "physics")

# Baudet's hexahedral mass-spring model (physics/mss, seed 003).
add_executable(test_mass_spring ${CMAKE_CURRENT_LIST_DIR}/test_mass_spring.cpp)
target_link_libraries(test_mass_spring PRIVATE incise_physics GTest::gtest_main)
gtest_discover_tests(test_mass_spring DISCOVERY_TIMEOUT 60 PROPERTIES LABELS "physics")

# Baudet's mass-spring against the 10-node FEM (D6 elongation, D8 bending) and Van Gelder's
# springs as the negative control (D9), digest seed-000-003.md part D.
add_executable(test_mass_spring_fem ${CMAKE_CURRENT_LIST_DIR}/test_mass_spring_fem.cpp)
target_link_libraries(test_mass_spring_fem PRIVATE incise_physics GTest::gtest_main)
gtest_discover_tests(test_mass_spring_fem DISCOVERY_TIMEOUT 60 PROPERTIES LABELS "physics")

# Dionne's constraint particles (physics/cp, seed 000), with its settings block and the world.
add_executable(test_constraint_particles ${CMAKE_CURRENT_LIST_DIR}/test_constraint_particles.cpp)
target_link_libraries(test_constraint_particles PRIVATE incise_engine GTest::gtest_main)
gtest_discover_tests(test_constraint_particles DISCOVERY_TIMEOUT 60 PROPERTIES LABELS "physics")

# The constraint particles' calibration in the accuracy report (uses the bench library).
add_executable(test_constraint_particles_accuracy ${CMAKE_CURRENT_LIST_DIR}/test_constraint_particles_accuracy.cpp)
target_link_libraries(test_constraint_particles_accuracy PRIVATE incise_bench GTest::gtest_main)
gtest_discover_tests(test_constraint_particles_accuracy DISCOVERY_TIMEOUT 60 PROPERTIES LABELS "physics")

# Baudet's correction forces in the implicit step's matrix (issue 31).
add_executable(test_mass_spring_implicit ${CMAKE_CURRENT_LIST_DIR}/test_mass_spring_implicit.cpp)
target_link_libraries(test_mass_spring_implicit PRIVATE incise_physics GTest::gtest_main)
gtest_discover_tests(test_mass_spring_implicit DISCOVERY_TIMEOUT 60 PROPERTIES LABELS "physics")

# The surface grid of the nearest-triangle scans (mark_engaged, held_contact) against a scan of
# every triangle.
add_executable(test_triangle_grid ${CMAKE_CURRENT_LIST_DIR}/test_triangle_grid.cpp)
target_link_libraries(test_triangle_grid PRIVATE incise_physics GTest::gtest_main)
gtest_discover_tests(test_triangle_grid DISCOVERY_TIMEOUT 60 PROPERTIES LABELS "physics")
