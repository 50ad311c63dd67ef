# The cut scenes (issue 4): each assets/scenes/cut_*.json replayed end to end with its
# expectations (--check), then DOFs constant and the surface closed after every cut event
# (replay_cut_scene.sh). The full replays take 1-10 s each in Release here and would take most of
# CI's budget instrumented, so under the sanitizers only a short replay of cut_organ runs
# (70 steps: its blade engages at step 20 and first severs links at step 55, so cutting steps
# run), checking the DOFs.
file(GLOB cut_scenes ${PROJECT_SOURCE_DIR}/assets/scenes/cut_*.json)
if(INCISE_SANITIZE STREQUAL "")
  foreach(scene ${cut_scenes})
    get_filename_component(name ${scene} NAME_WE)
    add_test(NAME replay_cut_${name}
             COMMAND bash ${CMAKE_CURRENT_LIST_DIR}/replay_cut_scene.sh $<TARGET_FILE:incise> ${scene}
                     ${CMAKE_CURRENT_BINARY_DIR}/replay_cut_${name})
    set_tests_properties(replay_cut_${name} PROPERTIES TIMEOUT 600 LABELS "scenes")
  endforeach()
else()
  add_test(NAME replay_cut_cut_organ_smoke
           COMMAND bash ${CMAKE_CURRENT_LIST_DIR}/replay_cut_scene.sh $<TARGET_FILE:incise>
                   ${PROJECT_SOURCE_DIR}/assets/scenes/cut_organ.json
                   ${CMAKE_CURRENT_BINARY_DIR}/replay_cut_cut_organ_smoke --smoke 70)
  set_tests_properties(replay_cut_cut_organ_smoke PROPERTIES TIMEOUT 600 LABELS "scenes")
endif()
