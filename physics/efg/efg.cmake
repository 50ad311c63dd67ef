# The corotated EFG model (physics/efg). Included by physics/CMakeLists.txt after
# add_library(incise_physics ...). Its element loops run on the model's physics::Executor.
target_sources(incise_physics PRIVATE
  ${CMAKE_CURRENT_LIST_DIR}/mls.cpp
  ${CMAKE_CURRENT_LIST_DIR}/corotational_efg.cpp
  ${CMAKE_CURRENT_LIST_DIR}/efg_neighbourhoods.cpp
  ${CMAKE_CURRENT_LIST_DIR}/efg_cut_visibility.cpp
  ${CMAKE_CURRENT_LIST_DIR}/efg_cut_edits.cpp
  ${CMAKE_CURRENT_LIST_DIR}/efg_step.cpp
  ${CMAKE_CURRENT_LIST_DIR}/rotation_extraction.cpp
  ${CMAKE_CURRENT_LIST_DIR}/efg_embedding.cpp
  ${CMAKE_CURRENT_LIST_DIR}/efg_static.cpp
  ${CMAKE_CURRENT_LIST_DIR}/efg_rest_stiffness.cpp
  ${CMAKE_CURRENT_LIST_DIR}/efg_current_stiffness.cpp
)
