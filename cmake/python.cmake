# The Python module (doc/python.md): mechanism_sim._mechanism_sim (pybind11, Debian
# pybind11-dev) beside the package's Python sources (python/mechanism_sim, catkin_python_setup)
# and its messages in the devel space's dist-packages, so that `import mechanism_sim` works
# after sourcing devel/setup.bash. Its tests (pytest) and scripts/sweep's (doc/sweeps.md).
# Python3 is already found (ament, by ws_build's -DPython3_EXECUTABLE=/usr/bin/python3):
# pybind11 then builds with FindPython3 and needs its Development part.
find_package(Python3 REQUIRED COMPONENTS Interpreter Development.Module)
find_package(pybind11 CONFIG REQUIRED)
pybind11_add_module(_mechanism_sim src/python/module.cpp src/python/simulation.cpp)
target_link_libraries(_mechanism_sim PRIVATE mechanism_sim_urdf)
set_target_properties(_mechanism_sim PROPERTIES
  LIBRARY_OUTPUT_DIRECTORY ${CATKIN_DEVEL_PREFIX}/${CATKIN_PACKAGE_PYTHON_DESTINATION})
install(TARGETS _mechanism_sim LIBRARY DESTINATION ${CATKIN_PACKAGE_PYTHON_DESTINATION})

if(CATKIN_ENABLE_TESTING)
  # pytest files under the devel environment (CATKIN_ENV); the JUnit XML lands beside the
  # gtests' in test_results/mechanism_sim, where scripts/test counts it. test_sweep runs
  # scripts/sweep in this workspace (MECHANISM_SIM_WS) and a Dask cluster on 127.0.0.1.
  # test_pinocchio_oracle runs test/oracle/pinocchio_oracle.py in .venv-oracle (doc/testing.md).
  foreach(name test_python test_sweep test_pinocchio_oracle)
    catkin_run_tests_target(pytest ${name} pytest-${name}.xml
      COMMAND "MECHANISM_SIM_SIMULATE=$<TARGET_FILE:simulate> MECHANISM_SIM_WS=${CATKIN_DEVEL_PREFIX}/.. /usr/bin/python3 -m pytest -p no:cacheprovider -q ${PROJECT_SOURCE_DIR}/test/python/${name}.py --junitxml=${CATKIN_TEST_RESULTS_DIR}/${PROJECT_NAME}/pytest-${name}.xml"
      DEPENDENCIES _mechanism_sim simulate)
  endforeach()
endif()
