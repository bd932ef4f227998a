# CLI tests: run the real tools. Each tool has its own section; a bad-input
# test expects a non-zero exit and a message matched by PASS_REGULAR_EXPRESSION.
# Helper: pm_cli_test(NAME EXPECT_REGEX cmd args...) passes when the output
# matches the regex (and WILL_FAIL semantics are not used: the regex decides).
function(pm_cli_test name regex)
  add_test(NAME cli.${name} COMMAND ${ARGN})
  set_tests_properties(cli.${name} PROPERTIES PASS_REGULAR_EXPRESSION "${regex}" LABELS cli)
endfunction()
# Script-driven tests: a bash script that exits 0 on success.
function(pm_cli_script name script)
  add_test(NAME cli.${name} COMMAND bash ${CMAKE_SOURCE_DIR}/tests/cli/${script} $<TARGET_FILE_DIR:volconv> ${CMAKE_SOURCE_DIR} ${ARGN})
  set_tests_properties(cli.${name} PROPERTIES LABELS cli)
endfunction()

# == volconv
# == particles
# == render
