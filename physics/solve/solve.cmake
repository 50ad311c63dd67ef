# Linear solvers beyond the CG (physics/solve): BiCGSTAB for non-symmetric steps, the rest-shape
# factor and its warp. Included by physics/CMakeLists.txt after add_library(incise_physics ...).
# The factor is CHOLMOD's (SuiteSparse, OpenBLAS behind it; Debian: libsuitesparse-dev
# libopenblas-dev).
target_sources(incise_physics PRIVATE
  ${CMAKE_CURRENT_LIST_DIR}/bicgstab.cpp
  ${CMAKE_CURRENT_LIST_DIR}/block_matrix.cpp
  ${CMAKE_CURRENT_LIST_DIR}/block_product.cpp
  ${CMAKE_CURRENT_LIST_DIR}/block_system.cpp
  ${CMAKE_CURRENT_LIST_DIR}/coarse_space.cpp
  ${CMAKE_CURRENT_LIST_DIR}/coarse_transfer.cpp
  ${CMAKE_CURRENT_LIST_DIR}/current_product.cpp
  ${CMAKE_CURRENT_LIST_DIR}/current_system.cpp
  ${CMAKE_CURRENT_LIST_DIR}/current_vcycle.cpp
  ${CMAKE_CURRENT_LIST_DIR}/element_assembly.cpp
  ${CMAKE_CURRENT_LIST_DIR}/element_assembly_edit.cpp
  ${CMAKE_CURRENT_LIST_DIR}/element_groups.cpp
  ${CMAKE_CURRENT_LIST_DIR}/galerkin.cpp
  ${CMAKE_CURRENT_LIST_DIR}/half_float.cpp
  ${CMAKE_CURRENT_LIST_DIR}/jacobi_scaling.cpp
  ${CMAKE_CURRENT_LIST_DIR}/paired_blocks.cpp
  ${CMAKE_CURRENT_LIST_DIR}/multigrid.cpp
  ${CMAKE_CURRENT_LIST_DIR}/rest_factor.cpp
  ${CMAKE_CURRENT_LIST_DIR}/supernodal_factor.cpp
  ${CMAKE_CURRENT_LIST_DIR}/warped_preconditioner.cpp
  ${CMAKE_CURRENT_LIST_DIR}/rest_preconditioner.cpp
  ${CMAKE_CURRENT_LIST_DIR}/rest_vcycle.cpp
)
# The block products' and the element assembly's two kernels (AVX2 and portable) must round
# alike: no contraction of a multiply and an add into one fused operation, whatever -march a
# build adds.
set_source_files_properties(${CMAKE_CURRENT_LIST_DIR}/block_product.cpp ${CMAKE_CURRENT_LIST_DIR}/current_product.cpp
                            ${CMAKE_CURRENT_LIST_DIR}/paired_blocks.cpp ${CMAKE_CURRENT_LIST_DIR}/supernodal_factor.cpp
                            ${CMAKE_CURRENT_LIST_DIR}/element_assembly.cpp
                            PROPERTIES COMPILE_OPTIONS -ffp-contract=off)
find_path(INCISE_CHOLMOD_INCLUDE_DIR cholmod.h PATH_SUFFIXES suitesparse)
find_library(INCISE_CHOLMOD_LIBRARY cholmod)
find_library(INCISE_OPENBLAS_LIBRARY openblas)
if(NOT INCISE_CHOLMOD_INCLUDE_DIR OR NOT INCISE_CHOLMOD_LIBRARY OR NOT INCISE_OPENBLAS_LIBRARY)
  message(FATAL_ERROR "incise_physics needs CHOLMOD and OpenBLAS (Debian: libsuitesparse-dev libopenblas-dev; scripts/setup installs them)")
endif()
target_include_directories(incise_physics SYSTEM PUBLIC ${INCISE_CHOLMOD_INCLUDE_DIR})
target_link_libraries(incise_physics PUBLIC ${INCISE_CHOLMOD_LIBRARY} ${INCISE_OPENBLAS_LIBRARY})
