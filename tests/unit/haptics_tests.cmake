# Tests of the haptics library (haptics/): protocol, devices (udp over loopback, replay,
# virtual), the lock-free channels, and the 1 kHz loop. No timing assertions: the timing test
# prints period percentiles beside a bare loop's, and checks nothing about them.
# Included from tests/CMakeLists.txt after find_package(GTest) and include(GoogleTest).
add_executable(test_haptics
  ${CMAKE_CURRENT_LIST_DIR}/test_haptics_protocol.cpp
  ${CMAKE_CURRENT_LIST_DIR}/test_haptics_udp.cpp
  ${CMAKE_CURRENT_LIST_DIR}/test_haptics_devices.cpp
  ${CMAKE_CURRENT_LIST_DIR}/test_haptics_channels.cpp
  ${CMAKE_CURRENT_LIST_DIR}/test_haptics_loop.cpp
  ${CMAKE_CURRENT_LIST_DIR}/test_haptics_passivity.cpp
  ${CMAKE_CURRENT_LIST_DIR}/test_haptics_needle.cpp
)
# incise_bench for the bench's scripted hand (bench/scripted_stroke.hpp), read through a PathDevice.
target_link_libraries(test_haptics PRIVATE incise_haptics incise_bench GTest::gtest_main)
# The bridge round-trip test runs the real incise-bridge program.
add_dependencies(test_haptics incise-bridge)
target_compile_definitions(test_haptics PRIVATE INCISE_BRIDGE_PATH="$<TARGET_FILE:incise-bridge>")
gtest_discover_tests(test_haptics DISCOVERY_TIMEOUT 60 PROPERTIES LABELS "haptics")

# Its own program: it replaces the global operator new to count the tick's allocations.
add_executable(test_haptics_allocation ${CMAKE_CURRENT_LIST_DIR}/test_haptics_allocation.cpp)
target_link_libraries(test_haptics_allocation PRIVATE incise_haptics GTest::gtest_main)
gtest_discover_tests(test_haptics_allocation DISCOVERY_TIMEOUT 60 PROPERTIES LABELS "haptics")

# The window end to end with the haptic session (needs a display; scripts/test provides Xvfb).
if(INCISE_WITH_WINDOW)
  add_executable(test_window_session ${CMAKE_CURRENT_LIST_DIR}/test_window_session.cpp)
  target_link_libraries(test_window_session PRIVATE incise_engine GTest::gtest_main)
  add_dependencies(test_window_session incise)
  target_compile_definitions(test_window_session PRIVATE INCISE_SOURCE_DIR="${PROJECT_SOURCE_DIR}"
                                                         INCISE_BINARY="$<TARGET_FILE:incise>")
  gtest_discover_tests(test_window_session DISCOVERY_TIMEOUT 60 PROPERTIES LABELS "haptics;render" TIMEOUT 600)
endif()
