# The URDF loader (urdfdom + tinyxml2, no roscpp), the batch simulator and the node.
add_library(mechanism_sim_urdf
  src/urdf/xml_input.cpp
  src/urdf/joint_specs.cpp
  src/urdf/rigid_bodies.cpp
  src/urdf/loader.cpp
  src/urdf/loader_joints.cpp
  src/urdf/loader_start.cpp
  src/urdf/loop_dialects.cpp
  src/urdf/massless_gimbals.cpp
  src/urdf/couplings.cpp
  src/urdf/model.cpp
  src/urdf/run_loop.cpp
  src/urdf/trajectory.cpp
  src/urdf/xacro.cpp
  src/urdf/transmissions.cpp
  src/urdf/yaml_file.cpp
  src/urdf/actuators.cpp
)
target_include_directories(mechanism_sim_urdf PUBLIC include ${urdfdom_INCLUDE_DIRS})
target_link_libraries(mechanism_sim_urdf mechanism_sim_core ${urdfdom_LIBRARIES} ${TINYXML2_TARGET} console_bridge)
# "Extended URDF" closures files (src/urdf/loop_dialects.cpp): Debian libyaml-cpp-dev.
find_package(yaml-cpp REQUIRED)
target_link_libraries(mechanism_sim_urdf yaml-cpp)
# .xacro models run scripts/xacro (ROS's xacro) from the source tree; MECHANISM_SIM_XACRO overrides it.
target_compile_definitions(mechanism_sim_urdf PRIVATE MECHANISM_SIM_XACRO_SCRIPT="${PROJECT_SOURCE_DIR}/scripts/xacro")

add_executable(simulate src/cli/simulate.cpp src/cli/csv_writer.cpp src/cli/bag_writer.cpp)
# --bag: librosbag_storage and the message headers (this package's JointReactions too), no roscpp.
target_include_directories(simulate PRIVATE ${catkin_INCLUDE_DIRS})
target_link_libraries(simulate mechanism_sim_urdf ${rosbag_storage_LIBRARIES} ${roscpp_serialization_LIBRARIES}
  ${rostime_LIBRARIES})
add_dependencies(simulate ${catkin_EXPORTED_TARGETS} ${PROJECT_NAME}_generate_messages_cpp)
# --plot runs scripts/plot (matplotlib) from the source tree; MECHANISM_SIM_PLOT overrides it.
target_compile_definitions(simulate PRIVATE MECHANISM_SIM_PLOT_SCRIPT="${PROJECT_SOURCE_DIR}/scripts/plot"
  MECHANISM_SIM_ACTUATOR_PLOT_SCRIPT="${PROJECT_SOURCE_DIR}/scripts/actuator_plot")  # --actuator-plot, doc/actuators.md

if(EXISTS ${PROJECT_SOURCE_DIR}/src/node/main.cpp)
  add_executable(mechanism_sim_node src/node/main.cpp src/node/sim_node.cpp src/node/pacer.cpp
    src/node/constraint_markers.cpp)
  target_include_directories(mechanism_sim_node PRIVATE ${catkin_INCLUDE_DIRS})
  target_link_libraries(mechanism_sim_node mechanism_sim_urdf ${catkin_LIBRARIES})
  add_dependencies(mechanism_sim_node ${catkin_EXPORTED_TARGETS})

  add_executable(constraint_monitor src/node/constraint_monitor.cpp)
  target_include_directories(constraint_monitor PRIVATE ${catkin_INCLUDE_DIRS})
  target_link_libraries(constraint_monitor ${catkin_LIBRARIES} gtest)
  add_dependencies(constraint_monitor ${catkin_EXPORTED_TARGETS})
  install(TARGETS mechanism_sim_node constraint_monitor RUNTIME DESTINATION ${CATKIN_PACKAGE_BIN_DESTINATION})
endif()

install(TARGETS simulate RUNTIME DESTINATION ${CATKIN_PACKAGE_BIN_DESTINATION})
install(TARGETS mechanism_sim_core mechanism_sim_urdf
  ARCHIVE DESTINATION ${CATKIN_PACKAGE_LIB_DESTINATION}
  LIBRARY DESTINATION ${CATKIN_PACKAGE_LIB_DESTINATION})
install(DIRECTORY include/ DESTINATION ${CATKIN_GLOBAL_INCLUDE_DESTINATION})
install(DIRECTORY launch urdf config DESTINATION ${CATKIN_PACKAGE_SHARE_DESTINATION})
