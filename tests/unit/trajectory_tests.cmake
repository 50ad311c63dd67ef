# Included by tests/CMakeLists.txt after find_package(GTest) and include(GoogleTest).
add_executable(test_trajectory ${CMAKE_CURRENT_LIST_DIR}/test_trajectory.cpp)
target_link_libraries(test_trajectory PRIVATE incise_engine GTest::gtest_main)
gtest_discover_tests(test_trajectory)
