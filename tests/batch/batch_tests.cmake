# `incise batch` (issue 36): shards merged equal the whole batch, failures recorded, resume,
# mpirun's ranks, and manifests refused naming file and field. Jobs of 10 steps: seconds.
add_test(NAME batch_shards
         COMMAND bash ${CMAKE_CURRENT_LIST_DIR}/batch_shards.sh $<TARGET_FILE:incise>
                 ${CMAKE_CURRENT_LIST_DIR}/sweep.json ${CMAKE_CURRENT_BINARY_DIR}/batch_shards)
set_tests_properties(batch_shards PROPERTIES TIMEOUT 300 LABELS "batch")

# The incision score in a batch's summary (assets/batch/incision.json: four default incisions,
# 40 s here), in Release only like the other full replays of the default scene.
if(INCISE_SANITIZE STREQUAL "")
  add_test(NAME batch_score
           COMMAND bash ${CMAKE_CURRENT_LIST_DIR}/batch_score.sh $<TARGET_FILE:incise>
                   ${PROJECT_SOURCE_DIR}/assets/batch/incision.json ${CMAKE_CURRENT_BINARY_DIR}/batch_score)
  set_tests_properties(batch_score PROPERTIES TIMEOUT 600 LABELS "batch" COST 40)
endif()

# The quick stability sweep in 3 parts on the batch path, joined and compared with the
# unsharded sweep that bench_stability_quick writes (its fixture); Release only, like it.
if(INCISE_SANITIZE STREQUAL "")
  add_test(NAME batch_bench_parts
           COMMAND bash ${CMAKE_CURRENT_LIST_DIR}/batch_bench_parts.sh $<TARGET_FILE:incise>
                   ${CMAKE_CURRENT_BINARY_DIR}/bench_stability_quick/stability.csv ${CMAKE_CURRENT_BINARY_DIR}/batch_bench_parts)
  set_tests_properties(batch_bench_parts PROPERTIES TIMEOUT 600 LABELS "batch" FIXTURES_REQUIRED stability_sweep)
endif()

# The quick accuracy report in 3 parts on the batch path, joined and compared with the unsharded
# report the test runs first (no fixture writes one); Release only, like the stability sweep.
if(INCISE_SANITIZE STREQUAL "")
  add_test(NAME batch_bench_accuracy_parts
           COMMAND bash ${CMAKE_CURRENT_LIST_DIR}/batch_bench_accuracy_parts.sh $<TARGET_FILE:incise>
                   ${CMAKE_CURRENT_BINARY_DIR}/batch_bench_accuracy_parts)
  set_tests_properties(batch_bench_accuracy_parts PROPERTIES TIMEOUT 900 LABELS "batch" COST 99)
endif()

# mpirun and the single-node Slurm in Release only: OpenMPI's runtime is not clean under the
# sanitizers (LSan counts what it keeps until exit), and what they add to incise (ranks.cpp,
# shell scripts) is not code the sanitizers look into; batch_shards runs the batch code there.
if(INCISE_SANITIZE STREQUAL "")
  if(NOT MPIEXEC_EXECUTABLE)
    set(MPIEXEC_EXECUTABLE none)
  endif()
  add_test(NAME batch_mpi
           COMMAND bash ${CMAKE_CURRENT_LIST_DIR}/batch_mpi.sh $<TARGET_FILE:incise>
                   ${CMAKE_CURRENT_LIST_DIR}/sweep.json ${CMAKE_CURRENT_BINARY_DIR}/batch_mpi
                   ${INCISE_HAVE_MPI} ${MPIEXEC_EXECUTABLE})
  set_tests_properties(batch_mpi PROPERTIES TIMEOUT 300 LABELS "batch" SKIP_RETURN_CODE 77)
  # A 4-task array and its merge on slurmctld + slurmd started for the test (root only); the
  # daemons' ports are fixed, so it runs alone.
  add_test(NAME batch_slurm
           COMMAND bash ${PROJECT_SOURCE_DIR}/scripts/slurm/test_local $<TARGET_FILE:incise>
                   ${CMAKE_CURRENT_LIST_DIR}/sweep.json ${CMAKE_CURRENT_BINARY_DIR}/batch_slurm 4)
  set_tests_properties(batch_slurm PROPERTIES TIMEOUT 600 LABELS "batch" SKIP_RETURN_CODE 77 RUN_SERIAL TRUE)
endif()

file(GLOB broken_manifests ${CMAKE_CURRENT_LIST_DIR}/broken/*.json)
foreach(manifest ${broken_manifests})
  get_filename_component(name ${manifest} NAME_WE)
  file(READ ${manifest} text)
  string(REGEX MATCH "expect_error: ([^\"\\\\]*(\\\\\"[^\"\\\\]*)*)" _ "${text}")
  string(REPLACE "\\\"" "\"" expected "${CMAKE_MATCH_1}")
  add_test(NAME batch_refused_${name}
           COMMAND ${CMAKE_COMMAND} -DINCISE=$<TARGET_FILE:incise> -DMANIFEST=${manifest}
                   -DOUT=${CMAKE_CURRENT_BINARY_DIR}/batch_refused_${name} "-DEXPECTED=${expected}"
                   -P ${CMAKE_CURRENT_LIST_DIR}/expect_refusal.cmake)
  set_tests_properties(batch_refused_${name} PROPERTIES LABELS "batch")
endforeach()
