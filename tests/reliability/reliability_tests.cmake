# Reliability (issue 35): recordings that survive kill -9. Release only: the test is about the
# file the process leaves, which instrumentation does not change, and the sanitizer builds run
# the session several times slower (the trajectory reader and writer run under them in
# test_trajectory and the fuzz corpora).
if(INCISE_SANITIZE STREQUAL "")
  add_test(NAME kill_while_recording
           COMMAND bash ${CMAKE_CURRENT_LIST_DIR}/kill_while_recording.sh $<TARGET_FILE:incise>
                   ${PROJECT_SOURCE_DIR}/assets/scenes/haptics_block.json ${CMAKE_CURRENT_BINARY_DIR}/kill_while_recording
                   20 3 35)
  set_tests_properties(kill_while_recording PROPERTIES TIMEOUT 600 LABELS "reliability" COST 81)
endif()

# The soak (issue 35): two minutes of the haptic session on the lobe, cutting and rebuilding;
# RSS must stay flat after the warm-up and no value may be non-finite. Release only here; the
# TSan build runs the same two minutes from .ci/run (its shadow memory makes RSS no measure).
if(INCISE_SANITIZE STREQUAL "")
  add_test(NAME bench_soak_2min
           COMMAND bash ${CMAKE_CURRENT_LIST_DIR}/soak.sh $<TARGET_FILE:incise> ${CMAKE_CURRENT_BINARY_DIR}/bench_soak 120)
  set_tests_properties(bench_soak_2min PROPERTIES TIMEOUT 400 LABELS "reliability;bench" COST 130)
endif()
