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
)
target_link_libraries(test_haptics PRIVATE incise_haptics GTest::gtest_main)
# The bridge round-trip test runs the real incise-bridge program.
add_dependencies(test_haptics incise-bridge)
target_compile_definitions(test_haptics PRIVATE INCISE_BRIDGE_PATH="$<TARGET_FILE:incise-bridge>")
gtest_discover_tests(test_haptics DISCOVERY_TIMEOUT 60 PROPERTIES LABELS "haptics")
