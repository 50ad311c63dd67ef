# Included by tests/CMakeLists.txt after find_package(GTest) and include(GoogleTest).
# The batch's pieces without a replay: overrides, grid expansion, manifest errors, shards.
add_executable(test_batch ${CMAKE_CURRENT_LIST_DIR}/test_batch.cpp)
target_link_libraries(test_batch PRIVATE incise_batch GTest::gtest_main)
gtest_discover_tests(test_batch)
