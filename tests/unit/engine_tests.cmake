# The threads physics runs its loops on (engine/thread_pool.hpp); run under ThreadSanitizer.
add_executable(test_thread_pool ${CMAKE_CURRENT_LIST_DIR}/test_thread_pool.cpp)
target_link_libraries(test_thread_pool PRIVATE incise_thread_pool GTest::gtest_main)
gtest_discover_tests(test_thread_pool DISCOVERY_TIMEOUT 60)

add_executable(test_engine
  ${CMAKE_CURRENT_LIST_DIR}/test_scene.cpp
  ${CMAKE_CURRENT_LIST_DIR}/test_model_registry.cpp
  ${PROJECT_SOURCE_DIR}/fuzz/fuzz_models.cpp
  ${CMAKE_CURRENT_LIST_DIR}/test_publication.cpp
  ${CMAKE_CURRENT_LIST_DIR}/test_mesh_import.cpp
  ${CMAKE_CURRENT_LIST_DIR}/test_surface_readers.cpp
  ${CMAKE_CURRENT_LIST_DIR}/test_tet_mesh_import.cpp
  ${CMAKE_CURRENT_LIST_DIR}/test_surface_queries.cpp
  ${CMAKE_CURRENT_LIST_DIR}/test_world.cpp
  ${CMAKE_CURRENT_LIST_DIR}/test_world_cut.cpp
  ${CMAKE_CURRENT_LIST_DIR}/test_cutting_resistance.cpp
  ${CMAKE_CURRENT_LIST_DIR}/test_world_copy.cpp
  ${CMAKE_CURRENT_LIST_DIR}/test_incision_score.cpp
  ${CMAKE_CURRENT_LIST_DIR}/test_surface_snap.cpp)
target_link_libraries(test_engine PRIVATE incise_engine GTest::gtest_main)
target_compile_definitions(test_engine PRIVATE INCISE_SOURCE_DIR="${PROJECT_SOURCE_DIR}")
gtest_discover_tests(test_engine DISCOVERY_TIMEOUT 60)

# The haptic loop in the engine (issue 5): engine/haptic_session.hpp.
add_executable(test_haptic_session ${CMAKE_CURRENT_LIST_DIR}/test_haptic_session.cpp)
target_link_libraries(test_haptic_session PRIVATE incise_engine GTest::gtest_main)
target_compile_definitions(test_haptic_session PRIVATE INCISE_SOURCE_DIR="${PROJECT_SOURCE_DIR}")
gtest_discover_tests(test_haptic_session DISCOVERY_TIMEOUT 60 PROPERTIES LABELS "haptics")

# The needle's force at 1 kHz (issue 30): a session on assets/scenes/needle_lobe.json.
add_executable(test_haptic_needle ${CMAKE_CURRENT_LIST_DIR}/test_haptic_needle.cpp)
target_link_libraries(test_haptic_needle PRIVATE incise_engine GTest::gtest_main)
target_compile_definitions(test_haptic_needle PRIVATE INCISE_SOURCE_DIR="${PROJECT_SOURCE_DIR}")
gtest_discover_tests(test_haptic_needle DISCOVERY_TIMEOUT 60 PROPERTIES LABELS "haptics")
