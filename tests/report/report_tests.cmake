# issue 33: a run's report page rendered by headless Chromium (skipped when it is missing).
add_executable(report_screenshot_check ${CMAKE_CURRENT_LIST_DIR}/screenshot_check.cpp)
add_test(NAME report_page
         COMMAND bash ${CMAKE_CURRENT_LIST_DIR}/report_page.sh $<TARGET_FILE:incise>
                 ${PROJECT_SOURCE_DIR}/assets/scenes/default.json ${CMAKE_CURRENT_BINARY_DIR}/report_page
                 $<TARGET_FILE:report_screenshot_check>)
set_tests_properties(report_page PROPERTIES TIMEOUT 600 SKIP_RETURN_CODE 77 LABELS "report")
