# The GPU backend of the deformation step (physics/gpu): OpenGL 4.5 compute through EGL
# without a display. Its own library, incise_gpu, so that only what runs a gpu scene needs
# EGL and GL at all. Included by physics/CMakeLists.txt.
pkg_check_modules(INCISE_GPU_EGL REQUIRED IMPORTED_TARGET egl)
pkg_check_modules(INCISE_GPU_OPENGL REQUIRED IMPORTED_TARGET opengl)
add_library(incise_gpu STATIC
  ${CMAKE_CURRENT_LIST_DIR}/compute_context.cpp
  ${CMAKE_CURRENT_LIST_DIR}/efg_kernels.cpp
  ${CMAKE_CURRENT_LIST_DIR}/efg_step.cpp
  ${CMAKE_CURRENT_LIST_DIR}/efg_step_device.cpp
  ${CMAKE_CURRENT_LIST_DIR}/efg_step_rows.cpp
)
target_link_libraries(incise_gpu PUBLIC incise_physics PRIVATE PkgConfig::INCISE_GPU_EGL PkgConfig::INCISE_GPU_OPENGL)
