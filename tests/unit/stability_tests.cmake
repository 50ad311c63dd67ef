# Tests of the explicit integrators and the stability seed check (issue 7). Included from
# tests/CMakeLists.txt, which has already run find_package(GTest) and include(GoogleTest).
add_executable(test_stability
  ${CMAKE_CURRENT_LIST_DIR}/test_integrator_explicit.cpp
)
target_link_libraries(test_stability PRIVATE incise_physics GTest::gtest_main)
gtest_discover_tests(test_stability DISCOVERY_TIMEOUT 60 PROPERTIES LABELS "physics")
