// ~constraint_markers for rviz: the constraint state as text, both joint points of each
// loop closure (parent side, child side), which coincide while the loop holds, and the
// joint reactions as arrows (namespace "reactions": the force each joint exerts on its
// child link, from the joint origin, ~reaction_arrow_scale metres per newton).
#pragma once
#include <string>

#include <ros/ros.h>
#include <std_msgs/Header.h>

#include "mechanism_sim/urdf/model.h"
#include "mechanism_sim/urdf/run_loop.h"

namespace mechanism_sim {

class ConstraintMarkers {
 public:
  ConstraintMarkers(ros::NodeHandle& pnh, const MechanismModel& model, double arrow_scale);
  // header: stamp and the (prefixed) root frame, in which the sample's poses are given.
  void publish(const Sample& sample, const std_msgs::Header& header);

 private:
  const MechanismModel& model_;
  double arrow_scale_;
  ros::Publisher publisher_;
};

}  // namespace mechanism_sim
