# pytest tests of the particlemesh Python module (tests/python), run with
# /usr/bin/python3 on the module in build/python; one CTest per file.
set(PM_PYTEST_FILES test_volume test_sample test_mesh test_errors test_example)
foreach(f ${PM_PYTEST_FILES})
  if(PM_PYTHON)
    add_test(NAME python_${f}
             COMMAND ${Python3_EXECUTABLE} -m pytest -q -p no:cacheprovider ${CMAKE_SOURCE_DIR}/tests/python/${f}.py)
    set_tests_properties(python_${f} PROPERTIES LABELS python TIMEOUT 600
      ENVIRONMENT "PYTHONPATH=${PM_PYTHON_DIR};PM_SOURCE_DIR=${CMAKE_SOURCE_DIR};PM_BIN=${CMAKE_BINARY_DIR}/bin;PM_NO_TQDM=1;OMP_NUM_THREADS=1")
  else()
    add_test(NAME python_${f} COMMAND ${CMAKE_COMMAND} -E echo
             "python_${f}: skipped: the particlemesh module is not built (needs python3-dev and pybind11-dev, PM_PYTHON=ON)")
    set_tests_properties(python_${f} PROPERTIES LABELS python SKIP_REGULAR_EXPRESSION "skipped")
  endif()
endforeach()
