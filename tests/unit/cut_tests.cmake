# Tests of the cutting library (physics/cut): the continuous edge-edge test, its broad
# phase, and volume cutting. Included from tests/CMakeLists.txt, which has already run find_package(GTest) and
# include(GoogleTest).
add_executable(test_cut
  ${CMAKE_CURRENT_LIST_DIR}/test_cut_ccd.cpp
  ${CMAKE_CURRENT_LIST_DIR}/test_cut_volume.cpp
  ${CMAKE_CURRENT_LIST_DIR}/test_cut_voxel_boundary.cpp
  ${CMAKE_CURRENT_LIST_DIR}/test_cut_front_surface.cpp
  ${CMAKE_CURRENT_LIST_DIR}/test_cut_front_mapping.cpp
  ${CMAKE_CURRENT_LIST_DIR}/test_cut_accuracy.cpp
  ${CMAKE_CURRENT_LIST_DIR}/test_cut_triangulate_2d.cpp
  ${CMAKE_CURRENT_LIST_DIR}/test_cut_copy.cpp
  ${CMAKE_CURRENT_LIST_DIR}/test_cut_thin_fin.cpp
)
target_link_libraries(test_cut PRIVATE incise_cut GTest::gtest_main)
gtest_discover_tests(test_cut DISCOVERY_TIMEOUT 60 PROPERTIES LABELS "physics")

# The accuracy report's cut beams against the conforming FEM (uses the bench library, whose
# reference solves use CHOLMOD; under ThreadSanitizer they fall back to SimplicialLDLT, see
# solve_static_loads).
add_executable(test_cut_beam_accuracy ${CMAKE_CURRENT_LIST_DIR}/test_cut_beam_accuracy.cpp)
target_link_libraries(test_cut_beam_accuracy PRIVATE incise_bench GTest::gtest_main)
gtest_discover_tests(test_cut_beam_accuracy DISCOVERY_TIMEOUT 60 PROPERTIES LABELS "physics" TIMEOUT 900)
