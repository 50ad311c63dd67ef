# Precompiled headers (CI's wall time): Eigen's dense and sparse modules, nlohmann json,
# GoogleTest and the standard headers most files use are parsed once per build, not once per
# translation unit (147 of the 234 include Eigen; about 0.8 s of parsing each, 8 to 16 % of a
# file's compile). Two headers, each compiled once by an anchor target with the project's
# flags and shared through REUSE_FROM: one for the libraries and programs, one that adds gtest
# for the test programs. GCC checks every use (-Winvalid-pch, which CMake adds); a file whose
# flags do not match gets the headers themselves, so a PCH never changes what compiles.
# Off by default (-DINCISE_PCH=ON turns it on): its gain (about 1 s a file in single-file A/Bs,
# 14.6 % on 69 files built side by side) is not yet measured on a whole CI run. ccache caches
# these files only with CCACHE_SLOPPINESS=pch_defines,time_macros,include_file_mtime,include_file_ctime
# (no source uses __DATE__ or __TIME__).
# Included from the top-level CMakeLists.txt after every target is declared.
# Imported targets are seen in the directory that found them: find them here too.
find_package(nlohmann_json 3.10 REQUIRED)
find_package(GTest REQUIRED)
set(incise_pch_headers
  <Eigen/Dense> <Eigen/Sparse> <nlohmann/json.hpp>
  <algorithm> <array> <cmath> <cstdint> <filesystem> <fstream> <functional> <limits> <map>
  <memory> <optional> <sstream> <stdexcept> <string> <utility> <vector>)

add_library(incise_pch STATIC ${CMAKE_CURRENT_LIST_DIR}/pch_anchor.cpp)
target_link_libraries(incise_pch PRIVATE Eigen3::Eigen nlohmann_json::nlohmann_json)
target_precompile_headers(incise_pch PRIVATE ${incise_pch_headers})

add_library(incise_test_pch STATIC ${CMAKE_CURRENT_LIST_DIR}/pch_anchor.cpp)
target_link_libraries(incise_test_pch PRIVATE Eigen3::Eigen nlohmann_json::nlohmann_json GTest::gtest)
target_precompile_headers(incise_test_pch PRIVATE ${incise_pch_headers} <gtest/gtest.h>)

# The libraries and programs whose files include Eigen (the small std-only ones are left as
# they are), and every test program that links gtest_main.
foreach(target incise_physics incise_cut incise_gpu incise_engine incise_bench incise_batch
               incise_report incise cp_cube_drop)
  if(TARGET ${target})
    target_link_libraries(${target} PRIVATE Eigen3::Eigen nlohmann_json::nlohmann_json)
    target_precompile_headers(${target} REUSE_FROM incise_pch)
  endif()
endforeach()
get_directory_property(incise_test_targets DIRECTORY ${PROJECT_SOURCE_DIR}/tests BUILDSYSTEM_TARGETS)
foreach(target ${incise_test_targets})
  get_target_property(libraries ${target} LINK_LIBRARIES)
  if(libraries AND "GTest::gtest_main" IN_LIST libraries)
    target_link_libraries(${target} PRIVATE Eigen3::Eigen nlohmann_json::nlohmann_json)
    target_precompile_headers(${target} REUSE_FROM incise_test_pch)
  endif()
endforeach()
