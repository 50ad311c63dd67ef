# The fuzz targets' harnesses (fuzz/) over their corpora (fuzz/corpus/, with the regression
# input of every finding), replayed without libFuzzer in every test build: a fixed finding
# stays fixed without clang. scripts/fuzz is what searches for new ones.
foreach(target scene trajectory trajectory_csv udp_pose mesh_obj mesh_stl mesh_ply tet_mesh)
  add_executable(fuzz_corpus_${target} ${PROJECT_SOURCE_DIR}/fuzz/${target}_fuzzer.cpp ${PROJECT_SOURCE_DIR}/fuzz/replay_main.cpp)
  target_include_directories(fuzz_corpus_${target} PRIVATE ${PROJECT_SOURCE_DIR})
  target_link_libraries(fuzz_corpus_${target} PRIVATE incise_engine)
  add_test(NAME fuzz_corpus_${target} COMMAND fuzz_corpus_${target} ${PROJECT_SOURCE_DIR}/fuzz/corpus/${target})
  # The mesh regressions are files assimp never returned from: a hang fails by the timeout.
  set_tests_properties(fuzz_corpus_${target} PROPERTIES TIMEOUT 120)
endforeach()
