# Tests of the GPU backend (physics/gpu, and its use by the engine); they run on Mesa's
# llvmpipe where there is no GPU.
add_executable(test_gpu
  ${CMAKE_CURRENT_LIST_DIR}/test_gpu_step.cpp
  ${CMAKE_CURRENT_LIST_DIR}/test_gpu_world.cpp)
target_link_libraries(test_gpu PRIVATE incise_gpu incise_engine GTest::gtest_main)
# Under ThreadSanitizer, scripts/test sets TSAN_OPTIONS with tests/tsan.supp (Mesa's own races).
gtest_discover_tests(test_gpu DISCOVERY_TIMEOUT 60 PROPERTIES LABELS "gpu")
