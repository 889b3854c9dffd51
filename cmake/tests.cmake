# gtests of the loader and the simulate CLI; rostests of the node.
catkin_add_gtest(test_loader test/urdf/test_loader.cpp test/urdf/test_drive_files.cpp test/urdf/test_real_files.cpp
  test/urdf/test_inertias.cpp test/urdf/test_kinematic.cpp test/urdf/test_couplings.cpp)
target_link_libraries(test_loader mechanism_sim_urdf gtest_main)
target_compile_definitions(test_loader PRIVATE MECHANISM_SIM_SOURCE_DIR="${PROJECT_SOURCE_DIR}")

# Transmissions and actuators (doc/actuators.md).
catkin_add_gtest(test_actuators test/urdf/test_actuators.cpp)
target_link_libraries(test_actuators mechanism_sim_urdf gtest_main)
target_compile_definitions(test_actuators PRIVATE MECHANISM_SIM_SOURCE_DIR="${PROJECT_SOURCE_DIR}")

# Loop closures in other tools' dialects (doc/loop_dialects.md), fixtures in test/dialects/.
catkin_add_gtest(test_dialects test/urdf/test_dialects.cpp)
target_link_libraries(test_dialects mechanism_sim_urdf gtest_main)
target_compile_definitions(test_dialects PRIVATE MECHANISM_SIM_SOURCE_DIR="${PROJECT_SOURCE_DIR}")

catkin_add_gtest(test_plot_cli test/urdf/test_plot_cli.cpp)
target_link_libraries(test_plot_cli gtest_main)
target_compile_definitions(test_plot_cli PRIVATE MECHANISM_SIM_SOURCE_DIR="${PROJECT_SOURCE_DIR}")

catkin_add_gtest(test_simulate_cli test/urdf/test_simulate_cli.cpp)
target_link_libraries(test_simulate_cli gtest_main)
target_compile_definitions(test_simulate_cli PRIVATE MECHANISM_SIM_SOURCE_DIR="${PROJECT_SOURCE_DIR}"
  SIMULATE_BIN="$<TARGET_FILE:simulate>")
add_dependencies(test_simulate_cli simulate)

# scripts/corpus (doc/robots.md, "Running a corpus") on test/corpus/src.
catkin_add_gtest(test_corpus_cli test/urdf/test_corpus_cli.cpp)
target_link_libraries(test_corpus_cli gtest_main)
target_compile_definitions(test_corpus_cli PRIVATE MECHANISM_SIM_SOURCE_DIR="${PROJECT_SOURCE_DIR}"
  SIMULATE_BIN="$<TARGET_FILE:simulate>")
add_dependencies(test_corpus_cli simulate)

# simulate --trajectory (doc/trajectories.md): a recorded run fed back, and bad files.
catkin_add_gtest(test_trajectory_cli test/urdf/test_trajectory_cli.cpp)
target_link_libraries(test_trajectory_cli gtest_main)
target_compile_definitions(test_trajectory_cli PRIVATE MECHANISM_SIM_SOURCE_DIR="${PROJECT_SOURCE_DIR}"
  SIMULATE_BIN="$<TARGET_FILE:simulate>")
add_dependencies(test_trajectory_cli simulate)

catkin_add_gtest(test_bag test/urdf/test_bag.cpp)
target_include_directories(test_bag PRIVATE ${catkin_INCLUDE_DIRS})
target_link_libraries(test_bag gtest_main ${rosbag_storage_LIBRARIES} ${roscpp_serialization_LIBRARIES} ${rostime_LIBRARIES})
target_compile_definitions(test_bag PRIVATE MECHANISM_SIM_SOURCE_DIR="${PROJECT_SOURCE_DIR}"
  SIMULATE_BIN="$<TARGET_FILE:simulate>")
add_dependencies(test_bag simulate ${PROJECT_NAME}_generate_messages_cpp)

# xacro models (ROS's xacro through scripts/xacro, doc/xacro.md): the loader, simulate and scripts/xacro.
catkin_add_gtest(test_xacro test/urdf/test_xacro.cpp)
target_include_directories(test_xacro PRIVATE src/urdf)
target_link_libraries(test_xacro mechanism_sim_urdf gtest_main)
target_compile_definitions(test_xacro PRIVATE MECHANISM_SIM_SOURCE_DIR="${PROJECT_SOURCE_DIR}"
  SIMULATE_BIN="$<TARGET_FILE:simulate>")
add_dependencies(test_xacro simulate)

# The robot zoo (test/zoo/) and MuJoCo as an oracle for its trees (test-only dependency
# libmujoco-dev; without it the oracle is not built).
catkin_add_gtest(test_zoo test/urdf/test_zoo.cpp)
target_link_libraries(test_zoo mechanism_sim_urdf gtest_main)
target_compile_definitions(test_zoo PRIVATE MECHANISM_SIM_SOURCE_DIR="${PROJECT_SOURCE_DIR}")
find_path(MUJOCO_INCLUDE_DIR mujoco/mujoco.h)
find_library(MUJOCO_LIBRARY mujoco)
if(MUJOCO_INCLUDE_DIR AND MUJOCO_LIBRARY)
  catkin_add_gtest(test_mujoco_oracle test/urdf/test_mujoco_oracle.cpp)
  target_include_directories(test_mujoco_oracle PRIVATE ${MUJOCO_INCLUDE_DIR})
  target_link_libraries(test_mujoco_oracle mechanism_sim_urdf ${MUJOCO_LIBRARY} gtest_main)
  target_compile_definitions(test_mujoco_oracle PRIVATE MECHANISM_SIM_SOURCE_DIR="${PROJECT_SOURCE_DIR}")
else()
  message(STATUS "MuJoCo not found (libmujoco-dev): test_mujoco_oracle is not built")
endif()

if(EXISTS ${PROJECT_SOURCE_DIR}/test/rostest/CMakeLists.txt)
  include(${PROJECT_SOURCE_DIR}/test/rostest/CMakeLists.txt)
endif()
