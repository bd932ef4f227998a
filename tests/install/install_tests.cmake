# cmake --install into a temporary prefix, then configure, build and run a
# ten-line consumer project (tests/install/consumer) against it.
add_test(NAME install_consumer
         COMMAND bash ${CMAKE_SOURCE_DIR}/tests/install/install_test.sh ${CMAKE_COMMAND} ${CMAKE_BINARY_DIR}
                 ${CMAKE_SOURCE_DIR}/tests/install/consumer ${CMAKE_CXX_COMPILER})
set_tests_properties(install_consumer PROPERTIES LABELS install TIMEOUT 600)
