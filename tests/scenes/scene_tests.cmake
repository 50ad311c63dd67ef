# Integration: the `incise` command on the shipped scenes and on broken inputs.
file(GLOB shipped_scenes ${PROJECT_SOURCE_DIR}/assets/scenes/*.json)
foreach(scene ${shipped_scenes})
  get_filename_component(name ${scene} NAME_WE)
  add_test(NAME scene_check_${name} COMMAND incise check ${scene})
endforeach()

# Each broken scene must be refused (non-zero exit) with its field named (the expected text
# follows "expect_error: " in the file's description).
file(GLOB broken_scenes ${CMAKE_CURRENT_LIST_DIR}/broken/*.json)
foreach(scene ${broken_scenes})
  get_filename_component(name ${scene} NAME_WE)
  file(READ ${scene} text)
  string(REGEX MATCH "expect_error: ([^\"]*)" _ "${text}")
  add_test(NAME scene_refused_${name}
           COMMAND ${CMAKE_COMMAND} -DINCISE=$<TARGET_FILE:incise> -DSCENE=${scene}
                   "-DEXPECTED=${CMAKE_MATCH_1}" -P ${CMAKE_CURRENT_LIST_DIR}/expect_refusal.cmake)
endforeach()

add_test(NAME replay_default_smoke
         COMMAND bash ${CMAKE_CURRENT_LIST_DIR}/replay_smoke.sh $<TARGET_FILE:incise>
                 ${PROJECT_SOURCE_DIR}/assets/scenes/default.json ${CMAKE_CURRENT_BINARY_DIR}/replay_smoke)
set_tests_properties(replay_default_smoke PROPERTIES TIMEOUT 600)

# The quick stability sweep (issue 7). Not under the sanitizers: it is a minute of pure
# arithmetic in Release and would take most of CI's budget instrumented; the physics it runs
# is covered by the unit tests there.
if(INCISE_SANITIZE STREQUAL "")
  add_test(NAME bench_stability_quick
           COMMAND bash ${CMAKE_CURRENT_LIST_DIR}/bench_stability_quick.sh $<TARGET_FILE:incise>
                   ${CMAKE_CURRENT_BINARY_DIR}/bench_stability_quick)
  set_tests_properties(bench_stability_quick PROPERTIES TIMEOUT 600 LABELS "bench" FIXTURES_SETUP stability_sweep COST 146)
endif()
include(${CMAKE_CURRENT_LIST_DIR}/cut_scenes.cmake)

# A tetrahedral mesh from a file as the FEM body (issue 32): Gmsh MSH 4 in mm with y up, probed
# for 3 s, its `expect` block checked. A few seconds in Release.
add_test(NAME replay_probe_tet_mesh
         COMMAND incise replay ${PROJECT_SOURCE_DIR}/assets/scenes/probe_tet_mesh.json --check --capture-every 0
                 --quiet --out ${CMAKE_CURRENT_BINARY_DIR}/replay_probe_tet_mesh)
set_tests_properties(replay_probe_tet_mesh PROPERTIES TIMEOUT 600 LABELS "scenes")

# The needle in the EFG lobe (issue 30): the replay's `expect` block (puncture peak, resistance
# growing with depth, friction only on retraction), and `incise session` on it (the scripted
# virtual device, the needle's force through the haptic loop). A few seconds each in Release.
add_test(NAME replay_needle_lobe
         COMMAND incise replay ${PROJECT_SOURCE_DIR}/assets/scenes/needle_lobe.json --check --capture-every 0
                 --quiet --out ${CMAKE_CURRENT_BINARY_DIR}/replay_needle_lobe)
add_test(NAME session_needle_lobe
         COMMAND incise session ${PROJECT_SOURCE_DIR}/assets/scenes/needle_lobe.json --quiet
                 --out ${CMAKE_CURRENT_BINARY_DIR}/session_needle_lobe)
set_tests_properties(replay_needle_lobe session_needle_lobe PROPERTIES TIMEOUT 600 LABELS "scenes")

# The GPU backend from the command line (issue 6), on llvmpipe here: cut_organ until its
# first cuts (step 60; links are first severed at step 55), and the refusal when compute is
# unavailable. Under the sanitizers a shorter replay (the compute runs uninstrumented in Mesa).
if(INCISE_SANITIZE STREQUAL "")
  set(incise_gpu_replay_steps 60)
else()
  set(incise_gpu_replay_steps 8)
endif()
add_test(NAME replay_gpu
         COMMAND bash ${CMAKE_CURRENT_LIST_DIR}/replay_gpu.sh $<TARGET_FILE:incise>
                 ${PROJECT_SOURCE_DIR}/assets/scenes/cut_organ.json ${CMAKE_CURRENT_BINARY_DIR}/replay_gpu
                 ${incise_gpu_replay_steps})
set_tests_properties(replay_gpu PROPERTIES TIMEOUT 600 LABELS "gpu")

# Every shipped scene replays to the state hash recorded in state_hashes.txt (issue 28: the
# redesign leaves the simulation bit for bit as it was). A minute of replays in Release; the
# sanitizers run the same code through the unit tests and the short replays above.
if(INCISE_SANITIZE STREQUAL "")
  add_test(NAME scene_state_hashes
           COMMAND bash ${CMAKE_CURRENT_LIST_DIR}/check_state_hashes.sh $<TARGET_FILE:incise>
                   ${PROJECT_SOURCE_DIR}/assets/scenes ${CMAKE_CURRENT_LIST_DIR}/state_hashes.txt
                   ${CMAKE_CURRENT_BINARY_DIR}/scene_state_hashes)
  set_tests_properties(scene_state_hashes PROPERTIES TIMEOUT 900 LABELS "scenes" COST 60)
endif()
