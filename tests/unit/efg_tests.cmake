# Tests of the corotated EFG model (physics/efg). Included from tests/CMakeLists.txt, which
# has already run find_package(GTest) and include(GoogleTest).
add_executable(test_efg
  ${CMAKE_CURRENT_LIST_DIR}/test_efg_mls.cpp
  ${CMAKE_CURRENT_LIST_DIR}/test_efg_model.cpp
  ${CMAKE_CURRENT_LIST_DIR}/test_efg_cantilever.cpp
  ${CMAKE_CURRENT_LIST_DIR}/test_efg_thin_fin.cpp
  ${CMAKE_CURRENT_LIST_DIR}/test_efg_llt3.cpp
  ${CMAKE_CURRENT_LIST_DIR}/test_efg_rotation_extraction.cpp
)
# incise_thread_pool: the thread-count comparisons run the model on the engine's executor.
target_link_libraries(test_efg PRIVATE incise_physics incise_thread_pool GTest::gtest_main)
gtest_discover_tests(test_efg DISCOVERY_TIMEOUT 60 PROPERTIES LABELS "physics")
