# `incise batch` (issue 36): shards merged equal the whole batch, failures recorded, resume,
# mpirun's ranks, and manifests refused naming file and field. Jobs of 10 steps: seconds.
add_test(NAME batch_shards
         COMMAND bash ${CMAKE_CURRENT_LIST_DIR}/batch_shards.sh $<TARGET_FILE:incise>
                 ${CMAKE_CURRENT_LIST_DIR}/sweep.json ${CMAKE_CURRENT_BINARY_DIR}/batch_shards)
set_tests_properties(batch_shards PROPERTIES TIMEOUT 300 LABELS "batch")

if(NOT MPIEXEC_EXECUTABLE)
  set(MPIEXEC_EXECUTABLE none)
endif()
add_test(NAME batch_mpi
         COMMAND bash ${CMAKE_CURRENT_LIST_DIR}/batch_mpi.sh $<TARGET_FILE:incise>
                 ${CMAKE_CURRENT_LIST_DIR}/sweep.json ${CMAKE_CURRENT_BINARY_DIR}/batch_mpi
                 ${INCISE_HAVE_MPI} ${MPIEXEC_EXECUTABLE})
set_tests_properties(batch_mpi PROPERTIES TIMEOUT 300 LABELS "batch" SKIP_RETURN_CODE 77)

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
