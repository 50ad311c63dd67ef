# The explicit integrators (explicit Euler, RK2, RK4, Stoermer and velocity Verlet). Included
# by physics/CMakeLists.txt after add_library(incise_physics ...).
target_sources(incise_physics PRIVATE ${CMAKE_CURRENT_LIST_DIR}/explicit_integrators.cpp)
