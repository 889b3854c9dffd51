// ~constraint_markers for rviz: the constraint state as text, and both joint points of
// each loop closure (parent side, child side), which coincide while the loop holds.
#pragma once
#include <string>

#include <ros/ros.h>
#include <std_msgs/Header.h>

#include "mechanism_sim/urdf/model.h"
#include "mechanism_sim/urdf/run_loop.h"

namespace mechanism_sim {

class ConstraintMarkers {
 public:
  ConstraintMarkers(ros::NodeHandle& pnh, const MechanismModel& model);
  // header: stamp and the (prefixed) root frame, in which the sample's poses are given.
  void publish(const Sample& sample, const std_msgs::Header& header);

 private:
  const MechanismModel& model_;
  ros::Publisher publisher_;
};

}  // namespace mechanism_sim
