# issue 33: a run's report page rendered by headless Chromium (skipped when it is missing).
add_executable(report_screenshot_check ${CMAKE_CURRENT_LIST_DIR}/screenshot_check.cpp)
add_test(NAME report_page
         COMMAND bash ${CMAKE_CURRENT_LIST_DIR}/report_page.sh $<TARGET_FILE:incise>
                 ${PROJECT_SOURCE_DIR}/assets/scenes/default.json ${CMAKE_CURRENT_BINARY_DIR}/report_page
                 $<TARGET_FILE:report_screenshot_check>)
set_tests_properties(report_page PROPERTIES TIMEOUT 600 SKIP_RETURN_CODE 77 LABELS "report")

# `bench performance` writes a page of its own (issue 33); checked on a recorded CSV, since
# the bench itself takes minutes.
add_test(NAME report_bench_performance
         COMMAND bash ${CMAKE_CURRENT_LIST_DIR}/performance_report.sh $<TARGET_FILE:incise>
                 ${CMAKE_CURRENT_LIST_DIR}/performance_sample.csv ${CMAKE_CURRENT_BINARY_DIR}/report_bench_performance
                 $<TARGET_FILE:report_screenshot_check>)
set_tests_properties(report_bench_performance PROPERTIES TIMEOUT 300 SKIP_RETURN_CODE 77 LABELS "report")

# A hand-written run folder: tool positions in steps.csv (the cut path over the organ from
# above), a score.json, a failed expectation, no frames.
add_test(NAME report_synthetic_run
         COMMAND bash ${CMAKE_CURRENT_LIST_DIR}/report_synthetic.sh $<TARGET_FILE:incise>
                 ${CMAKE_CURRENT_BINARY_DIR}/report_synthetic_run)
set_tests_properties(report_synthetic_run PROPERTIES TIMEOUT 120 SKIP_RETURN_CODE 77 LABELS "report")
