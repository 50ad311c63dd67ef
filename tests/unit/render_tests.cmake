# Included by tests/CMakeLists.txt after find_package(GTest) and include(GoogleTest).

add_executable(incise_render_tests ${CMAKE_CURRENT_LIST_DIR}/test_render_capture.cpp)
target_link_libraries(incise_render_tests PRIVATE incise_render GTest::gtest_main)
if(TARGET incise_window)
    target_sources(incise_render_tests PRIVATE ${CMAKE_CURRENT_LIST_DIR}/test_render_window.cpp)
    target_link_libraries(incise_render_tests PRIVATE incise_window)
endif()
# PNGs the tests write, kept in the build tree for a person to look at.
target_compile_definitions(incise_render_tests PRIVATE
    INCISE_RENDER_TEST_OUTPUT="${CMAKE_CURRENT_BINARY_DIR}/render_test_output")

set(incise_render_test_properties LABELS render)
# Under ThreadSanitizer, scripts/test sets TSAN_OPTIONS with tests/tsan.supp (Mesa's own races).
gtest_discover_tests(incise_render_tests
    DISCOVERY_MODE PRE_TEST
    PROPERTIES ${incise_render_test_properties})
