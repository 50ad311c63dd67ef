# Promayon's discrete models (physics/promayon, seed 002): shape memory, spring network, exact
# volume projection, the seed's step, the stiffness calibration; and their scenes through the
# engine (test_promayon_scenes).
add_executable(test_promayon ${CMAKE_CURRENT_LIST_DIR}/test_shape_memory.cpp
  ${CMAKE_CURRENT_LIST_DIR}/test_promayon_compression.cpp
  ${CMAKE_CURRENT_LIST_DIR}/test_promayon_sphere.cpp)
target_link_libraries(test_promayon PRIVATE incise_physics GTest::gtest_main)
gtest_discover_tests(test_promayon DISCOVERY_TIMEOUT 60 PROPERTIES LABELS "physics")

add_executable(test_promayon_scenes ${CMAKE_CURRENT_LIST_DIR}/test_promayon_scenes.cpp)
target_link_libraries(test_promayon_scenes PRIVATE incise_engine GTest::gtest_main)
target_compile_definitions(test_promayon_scenes PRIVATE INCISE_SOURCE_DIR="${PROJECT_SOURCE_DIR}")
gtest_discover_tests(test_promayon_scenes DISCOVERY_TIMEOUT 60)

# The needle (physics/needle, seed 002 §2.3) on a still lattice, and through the engine into the
# shape-memory cube (test_needle_scene: assets/scenes/needle_cube.json).
add_executable(test_needle ${CMAKE_CURRENT_LIST_DIR}/test_needle.cpp)
target_link_libraries(test_needle PRIVATE incise_physics GTest::gtest_main)
gtest_discover_tests(test_needle DISCOVERY_TIMEOUT 60 PROPERTIES LABELS "physics")

add_executable(test_needle_scene ${CMAKE_CURRENT_LIST_DIR}/test_needle_scene.cpp)
target_link_libraries(test_needle_scene PRIVATE incise_engine GTest::gtest_main)
target_compile_definitions(test_needle_scene PRIVATE INCISE_SOURCE_DIR="${PROJECT_SOURCE_DIR}")
# The cube scene runs 39000 steps of the Moore shape memory (112 s of CPU, Release only).
gtest_discover_tests(test_needle_scene DISCOVERY_TIMEOUT 60 PROPERTIES TIMEOUT 1500 COST 150)

# Several needles on one trajectory (tool.needles) into the fast cube (needle_cube_fast.json),
# and the brachytherapy protocols (needle_brachytherapy.json: four runs of 6 needles).
add_executable(test_needle_template ${CMAKE_CURRENT_LIST_DIR}/test_needle_template.cpp)
target_link_libraries(test_needle_template PRIVATE incise_engine GTest::gtest_main)
target_compile_definitions(test_needle_template PRIVATE INCISE_SOURCE_DIR="${PROJECT_SOURCE_DIR}")
gtest_discover_tests(test_needle_template DISCOVERY_TIMEOUT 60 PROPERTIES TIMEOUT 600 COST 20)

add_executable(test_needle_brachytherapy ${CMAKE_CURRENT_LIST_DIR}/test_needle_brachytherapy.cpp)
target_link_libraries(test_needle_brachytherapy PRIVATE incise_engine GTest::gtest_main)
target_compile_definitions(test_needle_brachytherapy PRIVATE INCISE_SOURCE_DIR="${PROJECT_SOURCE_DIR}")
gtest_discover_tests(test_needle_brachytherapy DISCOVERY_TIMEOUT 60 PROPERTIES TIMEOUT 1500 COST 100)

# The needle on the EFG body (physics/needle/needle_efg.hpp): integration points as its tissue.
add_executable(test_needle_efg ${CMAKE_CURRENT_LIST_DIR}/test_needle_efg.cpp)
target_link_libraries(test_needle_efg PRIVATE incise_physics GTest::gtest_main)
gtest_discover_tests(test_needle_efg DISCOVERY_TIMEOUT 60 PROPERTIES LABELS "physics")
