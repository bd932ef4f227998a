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
set(D ${CMAKE_SOURCE_DIR}/tests/data)
set(VC $<TARGET_FILE:volconv>)
pm_cli_test(volconv.missing_file "volconv: error: .*nope.nrrd.*no such file" ${VC} ${D}/nope.nrrd /tmp/x.nrrd)
pm_cli_test(volconv.not_3d "volconv: error: .*plane2d.nrrd.*expected 3 axes, got 2" ${VC} ${D}/plane2d.nrrd /tmp/pm_x.nrrd)
pm_cli_test(volconv.four_d "volconv: error: .*hyper4d.nrrd.*expected 3 axes, got 4" ${VC} ${D}/hyper4d.nrrd /tmp/pm_x.nrrd)
pm_cli_test(volconv.nan "volconv: error: .*nan.nrrd.*voxel \\(0,1,0\\) is nan; expected finite" ${VC} ${D}/nan.nrrd /tmp/pm_x.nrrd)
pm_cli_test(volconv.truncated "volconv: error: .*truncated.nrrd" ${VC} ${D}/truncated.nrrd /tmp/pm_x.nrrd)
pm_cli_test(volconv.truncated_header "volconv: error: .*truncated_header.nrrd" ${VC} ${D}/truncated_header.nrrd /tmp/pm_x.nrrd)
pm_cli_test(volconv.zero_axis "volconv: error: .*zero_axis.nrrd.*" ${VC} ${D}/zero_axis.nrrd /tmp/pm_x.nrrd)
pm_cli_test(volconv.unknown_type "volconv: error: .*unknown_type.mha.*MET_FOO" ${VC} ${D}/unknown_type.mha /tmp/pm_x.nrrd)
pm_cli_test(volconv.bad_extension "volconv: usage error: .*unknown volume extension" ${VC} ${D}/onevoxel.nrrd /tmp/pm_x.xyz)
pm_cli_test(volconv.no_output "volconv: usage error: an output file is required" ${VC} ${D}/onevoxel.nrrd)
pm_cli_test(volconv.bad_flag "volconv: usage error" ${VC} --frobnicate)
pm_cli_test(volconv.unwritable "volconv: error: .*does not exist" ${VC} ${D}/onevoxel.nrrd /nonexistent/dir/x.nrrd)
pm_cli_test(volconv.open_mesh "volconv: error: .*open_tet.off.*not closed \\(3 boundary edges" ${VC} ${D}/open_tet.off /tmp/pm_x.nrrd --sdf --voxel 0.1)
pm_cli_test(volconv.sdf_no_voxel "volconv: usage error: --sdf needs --voxel" ${VC} ${D}/tet.off /tmp/pm_x.nrrd --sdf)
pm_cli_test(volconv.labels_absent "volconv: error: .*none of the labels 7 occurs; labels present: 0 1" ${VC} ${D}/onevoxel.nrrd /tmp/pm_x.nrrd --labels 7)
pm_cli_test(volconv.bad_merge "volconv: usage error: merge rule .*malformed" ${VC} ${D}/onevoxel.nrrd /tmp/pm_x.nrrd --merge "1,2")
pm_cli_test(volconv.help_example "Example:.*volconv" ${VC} --help)
pm_cli_script(volconv.workflow volconv_test.sh)
# == particles
# == render
# == morph
# == gradlimit
# == mcinit
# == tighten
# == medialaxis
# == sizingfield
