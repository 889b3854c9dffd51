// mechanism_sim_node: runs a URDF mechanism in a ROS graph (README "The node").
#pragma once
#include <atomic>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include <diagnostic_updater/diagnostic_updater.h>
#include <geometry_msgs/TransformStamped.h>
#include <ros/ros.h>
#include <sensor_msgs/JointState.h>
#include <std_srvs/Empty.h>
#include <tf2_ros/static_transform_broadcaster.h>
#include <tf2_ros/transform_broadcaster.h>

#include "mechanism_sim/StepSimulation.h"
#include "mechanism_sim/urdf/model.h"

namespace mechanism_sim {

class SimNode {
 public:
  SimNode();
  // Reads parameters and loads the model; false (after logging why) if it cannot run.
  bool init();
  // Steps and publishes until shutdown.
  void run();

 private:
  void publish(bool paused = false);
  void publishStatic();
  geometry_msgs::TransformStamped treeTransform(const TreeJoint& j, const ros::Time& time) const;
  void onEffort(const sensor_msgs::JointState::ConstPtr& msg);
  bool onReset(std_srvs::Empty::Request&, std_srvs::Empty::Response&);
  bool onPause(std_srvs::Empty::Request&, std_srvs::Empty::Response&);
  bool onUnpause(std_srvs::Empty::Request&, std_srvs::Empty::Response&);
  bool onStep(StepSimulation::Request& req, StepSimulation::Response& res);
  void diagnose(diagnostic_updater::DiagnosticStatusWrapper& status);
  ros::Time stamp() const;
  void anchorStampsToWall();
  void restartPacing();

  ros::NodeHandle nh_, pnh_;
  std::unique_ptr<MechanismModel> model_;
  std::mutex mutex_;  // guards model_ and the pacing state
  double dt_ = 1e-3, publish_rate_ = 100.0, rtf_target_ = 1.0;
  bool publish_clock_ = false;
  std::atomic<bool> paused_{false};
  std::string prefix_;
  ros::Time time_origin_{0};  // stamp of simulation time 0 (0 when the node owns /clock)
  ros::WallTime pace_wall_;
  double pace_sim_ = 0.0, rtf_achieved_ = 0.0, step_time_ = 0.0;
  double worst_position_ = 0.0, worst_velocity_ = 0.0;
  bool behind_ = false;
  ros::Publisher joint_states_, clock_, violation_, markers_;
  std::vector<int> loop_joints_;  // Mechanism joints that close loops (not tf edges)
  ros::Subscriber effort_;
  ros::ServiceServer reset_, pause_, unpause_, step_;
  tf2_ros::TransformBroadcaster tf_;
  tf2_ros::StaticTransformBroadcaster tf_static_;
  std::unique_ptr<diagnostic_updater::Updater> diagnostics_;
};

}  // namespace mechanism_sim
