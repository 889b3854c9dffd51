// mechanism_sim_node: runs a URDF mechanism in a ROS graph (doc/node.md). The node
// reads its parameters, loads the model, and then drives the shared run loop
// (mechanism_sim/urdf/run_loop.h) paced to wall-clock time (pacer.h), publishing each
// sample (joint_states, actuator_states, tf, violation, markers in constraint_markers.h,
// /clock) and serving effort commands (by joint or by actuator), reset, pause, unpause, advance and diagnostics.
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
#include <trajectory_msgs/JointTrajectory.h>

#include "constraint_markers.h"
#include "mechanism_sim/StepSimulation.h"
#include "mechanism_sim/urdf/model.h"
#include "mechanism_sim/urdf/run_loop.h"
#include "mechanism_sim/urdf/trajectory.h"
#include "pacer.h"

namespace mechanism_sim {

// The node's private parameters (config/default.yaml).
struct NodeParams {
  double step = 1e-3, publish_rate = 100.0, real_time_factor = 1.0;
  bool publish_clock = false, start_paused = false;
  std::string frame_prefix;
  double drive_acceleration = 10.0;  // [rad/s^2 or m/s^2] ramp of ~drive_command
  double reaction_arrow_scale = 0.01;  // [m/N] reaction arrows in ~constraint_markers
  // [rad or m] how far a ~joint_trajectory's first point may lie from the current position
  double trajectory_start_tolerance = kTrajectoryStartTolerance;
  LoadOptions load;  // ~integrator, ~initial_positions, ~initial_velocities
  // Reads them; false (after logging why) when they are out of range.
  bool read(const ros::NodeHandle& pnh);
};

class SimNode {
 public:
  SimNode();
  // Reads parameters and loads the model; false (after logging why) if it cannot run.
  bool init();
  // Steps and publishes until shutdown.
  void run();

 private:
  bool load();
  void publish(bool paused = false);
  void publishStatic();
  geometry_msgs::TransformStamped treeTransform(size_t tree_joint, const ros::Time& time) const;
  void onEffort(const sensor_msgs::JointState::ConstPtr& msg);
  void onActuatorEffort(const sensor_msgs::JointState::ConstPtr& msg);
  void onDriveCommand(const sensor_msgs::JointState::ConstPtr& msg);
  void onTrajectory(const trajectory_msgs::JointTrajectory::ConstPtr& msg);
  // Follows a trajectory from `start` (simulation time), or logs why not (under mutex_).
  void followOrReject(const Trajectory& traj, double start);
  // Advances `steps` steps, switching to a pending trajectory at the step nearest after
  // its start (under mutex_).
  void advance(long steps);
  // ~actuator_limits as it stands now: the saturating mode switched on or off where it
  // changed (under mutex_). cached: through the parameter cache (every wall-clock cycle);
  // otherwise from the parameter server itself (each ~advance, so that a value set before
  // the call holds for its steps).
  void readActuatorLimits(bool cached);
  bool onReset(std_srvs::Empty::Request&, std_srvs::Empty::Response&);
  bool onPause(std_srvs::Empty::Request&, std_srvs::Empty::Response&);
  bool onUnpause(std_srvs::Empty::Request&, std_srvs::Empty::Response&);
  bool onStep(StepSimulation::Request& req, StepSimulation::Response& res);
  void diagnose(diagnostic_updater::DiagnosticStatusWrapper& status);
  ros::Time stamp() const;
  void anchorStampsToWall();

  ros::NodeHandle nh_, pnh_;
  NodeParams params_;
  std::unique_ptr<MechanismModel> model_;
  std::unique_ptr<RunLoop> loop_;
  std::unique_ptr<Pacer> pacer_;
  std::unique_ptr<ConstraintMarkers> markers_;
  std::mutex mutex_;  // guards model_ and loop_
  std::atomic<bool> paused_{false};
  ros::Time time_origin_{0};  // stamp of simulation time 0 (0 when the node owns /clock)
  ros::Time last_stamp_{0};   // the last stamp published (under mutex_)
  ros::Time last_tf_stamp_{ros::TIME_MAX};  // of the last tf sent (TIME_MAX: none yet)
  std::vector<std::pair<int, int>> tree_links_;  // (parent, child) link of each tree joint
  ros::Publisher joint_states_, actuator_states_, clock_, violation_, reactions_, coupling_reactions_;
  ros::Subscriber effort_, actuator_effort_, drive_, trajectory_;
  // The torque last commanded on each actuator (~actuator_effort_command; under mutex_): a
  // transmission's joint efforts follow from all its actuators' torques.
  std::vector<double> actuator_command_;
  // A ~joint_trajectory stamped in the future waits here until its start (under mutex_).
  std::unique_ptr<Trajectory> pending_;
  double pending_start_ = 0.0;
  ros::ServiceServer reset_, pause_, unpause_, step_;
  tf2_ros::TransformBroadcaster tf_;
  tf2_ros::StaticTransformBroadcaster tf_static_;
  std::unique_ptr<diagnostic_updater::Updater> diagnostics_;
};

}  // namespace mechanism_sim
