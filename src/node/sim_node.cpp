#include "sim_node.h"

#include <cmath>
#include <map>
#include <vector>

#include <geometry_msgs/TransformStamped.h>
#include <geometry_msgs/Vector3Stamped.h>
#include <rosgraph_msgs/Clock.h>
#include <visualization_msgs/MarkerArray.h>

#include <cstdio>
#include <set>

#include "ros_conversions.h"

namespace mechanism_sim {

SimNode::SimNode() : pnh_("~") {}

bool SimNode::init() {
  pnh_.param("step", dt_, 1e-3);
  pnh_.param("publish_rate", publish_rate_, 100.0);
  pnh_.param("real_time_factor", rtf_target_, 1.0);
  pnh_.param("publish_clock", publish_clock_, false);
  pnh_.param<std::string>("frame_prefix", prefix_, "");
  bool start_paused = false;
  pnh_.param("start_paused", start_paused, false);
  paused_ = start_paused;
  if (!(dt_ > 0) || dt_ > 0.1 || !(publish_rate_ > 0) || !(rtf_target_ >= 0)) {
    ROS_FATAL("mechanism_sim: ~step must be in (0, 0.1] s, ~publish_rate > 0 and ~real_time_factor >= 0");
    return false;
  }

  LoadOptions options;
  pnh_.param<std::string>("integrator", options.integrator, "");
  std::map<std::string, double> positions, velocities;
  pnh_.getParam("initial_positions", positions);
  pnh_.getParam("initial_velocities", velocities);
  options.positions.assign(positions.begin(), positions.end());
  options.velocities.assign(velocities.begin(), velocities.end());

  std::string model_file, description;
  try {
    if (pnh_.getParam("model_file", model_file) && !model_file.empty()) {
      model_ = loadModelFile(model_file, options);
    } else if (nh_.getParam("robot_description", description)) {
      model_ = loadModelString(description, "robot_description", options);
    } else {
      ROS_FATAL("mechanism_sim: no model: set ~model_file or robot_description");
      return false;
    }
    std::vector<double> gravity;
    if (pnh_.getParam("gravity", gravity)) {
      if (gravity.size() != 3 || !std::isfinite(gravity[0] + gravity[1] + gravity[2]))
        throw LoadError("~gravity must be three finite numbers");
      model_->mechanism().setGravity(Eigen::Vector3d(gravity[0], gravity[1], gravity[2]));
    }
  } catch (const std::exception& e) {
    ROS_FATAL("mechanism_sim: %s", e.what());
    return false;
  }
  const Mechanism& m = model_->mechanism();
  ROS_INFO("mechanism_sim: '%s': %d bodies, %zu joint dofs, %d constraint equations; %s; assembled to %.1e",
           model_->name().c_str(), m.numBodies() - 1, model_->dofs().size(), m.numEquations(),
           m.dependencies().describe().c_str(), model_->assembly().position_residual);

  joint_states_ = nh_.advertise<sensor_msgs::JointState>("joint_states", 10);
  violation_ = pnh_.advertise<geometry_msgs::Vector3Stamped>("constraint_violation", 10);
  markers_ = pnh_.advertise<visualization_msgs::MarkerArray>("constraint_markers", 2);
  if (publish_clock_) clock_ = nh_.advertise<rosgraph_msgs::Clock>("/clock", 10);
  std::set<std::string> tree;
  for (const TreeJoint& j : model_->treeJoints()) tree.insert(j.name);
  for (int j = 0; j < m.numJoints(); ++j)
    if (!tree.count(m.joint(j).name())) loop_joints_.push_back(j);
  effort_ = pnh_.subscribe("effort_command", 10, &SimNode::onEffort, this);
  reset_ = pnh_.advertiseService("reset", &SimNode::onReset, this);
  pause_ = pnh_.advertiseService("pause", &SimNode::onPause, this);
  unpause_ = pnh_.advertiseService("unpause", &SimNode::onUnpause, this);
  step_ = pnh_.advertiseService("advance", &SimNode::onStep, this);
  diagnostics_ = std::make_unique<diagnostic_updater::Updater>(nh_, pnh_);
  diagnostics_->setHardwareID("mechanism_sim/" + model_->name());
  diagnostics_->add("constraints", this, &SimNode::diagnose);

  if (!publish_clock_) anchorStampsToWall();
  restartPacing();
  publishStatic();
  return true;
}

ros::Time SimNode::stamp() const { return time_origin_ + ros::Duration(model_->mechanism().time()); }

// Without /clock: the current simulation time is stamped as the current wall time.
void SimNode::anchorStampsToWall() {
  time_origin_ = ros::Time(ros::WallTime::now().toSec()) - ros::Duration(model_->mechanism().time());
}

void SimNode::restartPacing() {
  pace_wall_ = ros::WallTime::now();
  pace_sim_ = model_->mechanism().time();
}

// tf of a URDF tree joint: the child link in the parent link, frames prefixed.
geometry_msgs::TransformStamped SimNode::treeTransform(const TreeJoint& j, const ros::Time& time) const {
  geometry_msgs::TransformStamped t;
  t.header.stamp = time;
  t.header.frame_id = prefix_ + j.parent;
  t.child_frame_id = prefix_ + j.child;
  t.transform = toTransform(model_->linkPose(model_->linkIndex(j.parent)).inverse() *
                            model_->linkPose(model_->linkIndex(j.child)));
  return t;
}

void SimNode::publishStatic() {
  std::vector<geometry_msgs::TransformStamped> fixed;
  for (const TreeJoint& j : model_->treeJoints())
    if (j.fixed) fixed.push_back(treeTransform(j, stamp()));
  if (!fixed.empty()) tf_static_.sendTransform(fixed);
}

// Without /clock, stamps follow wall time: a pause or a reset moves the origin so that
// they never repeat or run backwards. With /clock, a pause freezes time and tf is not
// republished (a repeated stamp is an error for tf2 listeners).
void SimNode::publish(bool paused) {
  if (!publish_clock_ && paused) anchorStampsToWall();
  const ros::Time now = stamp();
  const Mechanism& m = model_->mechanism();
  sensor_msgs::JointState js;
  js.header.stamp = now;
  for (size_t d = 0; d < model_->dofs().size(); ++d) {
    const int i = static_cast<int>(d);
    js.name.push_back(model_->dofs()[d].name);
    js.position.push_back(model_->position(i));
    js.velocity.push_back(model_->velocity(i));
    js.effort.push_back(model_->effort(i));
  }
  joint_states_.publish(js);

  std::vector<geometry_msgs::TransformStamped> moving;
  for (const TreeJoint& j : model_->treeJoints())
    if (!j.fixed) moving.push_back(treeTransform(j, now));
  if (!moving.empty() && !(paused && publish_clock_)) tf_.sendTransform(moving);

  geometry_msgs::Vector3Stamped v;
  v.header.stamp = now;
  v.header.frame_id = prefix_ + model_->rootLink();
  v.vector.x = m.positionViolation();
  v.vector.y = m.velocityViolation();
  violation_.publish(v);

  // Markers for rviz: the constraint state as text, and each loop closure's two joint
  // points (parent side, child side), which coincide while the loop holds.
  visualization_msgs::MarkerArray ma;
  visualization_msgs::Marker text;
  text.header = v.header;
  text.ns = "constraint_state";
  text.type = visualization_msgs::Marker::TEXT_VIEW_FACING;
  text.pose.position.z = 0.45;
  text.pose.orientation.w = 1.0;
  text.scale.z = 0.03;
  text.color.r = text.color.g = text.color.b = text.color.a = 1.0;
  char buf[160];
  std::snprintf(buf, sizeof buf, "t %.2f s  |Phi| %.1e  |Phi_q v| %.1e  dependent %d", m.time(), v.vector.x,
                v.vector.y, m.dependencies().dependent);
  text.text = buf;
  ma.markers.push_back(text);
  visualization_msgs::Marker points;
  points.header = v.header;
  points.ns = "loop_closures";
  points.type = visualization_msgs::Marker::SPHERE_LIST;
  points.pose.orientation.w = 1.0;
  points.scale.x = points.scale.y = points.scale.z = 0.02;
  points.color.r = 1.0, points.color.g = 0.85, points.color.a = 1.0;
  for (int j : loop_joints_) {
    const Joint& joint = m.joint(j);
    for (int side = 0; side < 2; ++side) {
      const int b = side ? joint.bodyJ() : joint.bodyI();
      const Eigen::Vector3d p = m.position(b) + m.rotation(b) * (side ? joint.frameJ() : joint.frameI()).sp_B;
      geometry_msgs::Point gp;
      gp.x = p.x(), gp.y = p.y(), gp.z = p.z();
      points.points.push_back(gp);
    }
  }
  if (!points.points.empty()) ma.markers.push_back(points);
  markers_.publish(ma);

  if (publish_clock_) {
    rosgraph_msgs::Clock c;
    c.clock = now;
    clock_.publish(c);
  }
}

void SimNode::run() {
  ros::AsyncSpinner spinner(1);
  spinner.start();
  const long per_publish = std::max(1L, std::lround(1.0 / (publish_rate_ * dt_)));
  {
    std::lock_guard<std::mutex> lock(mutex_);
    publish();
  }
  ros::WallTime last_warn(0), rtf_wall = ros::WallTime::now();
  double rtf_sim = model_->mechanism().time();
  while (ros::ok()) {
    double sim_now = 0;
    if (paused_) {
      {
        std::lock_guard<std::mutex> lock(mutex_);
        publish(true);
        restartPacing();
      }
      diagnostics_->update();
      ros::WallDuration(1.0 / publish_rate_).sleep();
      continue;
    }
    {
      std::lock_guard<std::mutex> lock(mutex_);
      const ros::WallTime t0 = ros::WallTime::now();
      try {
        for (long s = 0; s < per_publish; ++s) model_->step(dt_);
      } catch (const std::exception& e) {
        ROS_FATAL("mechanism_sim: %s", e.what());
        ros::shutdown();
        break;
      }
      step_time_ = (ros::WallTime::now() - t0).toSec() / per_publish;
      worst_position_ = std::max(worst_position_, model_->mechanism().positionViolation());
      worst_velocity_ = std::max(worst_velocity_, model_->mechanism().velocityViolation());
      publish();
      sim_now = model_->mechanism().time();
    }
    diagnostics_->update();
    const ros::WallTime now = ros::WallTime::now();
    if ((now - rtf_wall).toSec() >= 1.0) {
      rtf_achieved_ = (sim_now - rtf_sim) / (now - rtf_wall).toSec();
      rtf_wall = now;
      rtf_sim = sim_now;
    }
    if (rtf_target_ <= 0) continue;  // as fast as possible
    const double ahead = (sim_now - pace_sim_) / rtf_target_ - (now - pace_wall_).toSec();
    if (ahead > 0) {
      ros::WallDuration(std::min(ahead, 0.05)).sleep();
      behind_ = false;
    } else if (ahead < -0.1) {
      behind_ = true;
      if ((now - last_warn).toSec() > 5.0) {
        ROS_WARN("mechanism_sim: falling behind real time by %.2f s (real-time factor %.2f of %.2f)", -ahead,
                 rtf_achieved_, rtf_target_);
        last_warn = now;
      }
      std::lock_guard<std::mutex> lock(mutex_);
      restartPacing();  // do not try to catch up a lost second in a burst
    }
  }
  spinner.stop();
}

void SimNode::onEffort(const sensor_msgs::JointState::ConstPtr& msg) {
  const size_t n = msg->name.size();
  std::string problem;
  if (msg->effort.size() != n) problem = "name and effort arrays differ in length";
  if ((!msg->position.empty() && msg->position.size() != n) || (!msg->velocity.empty() && msg->velocity.size() != n))
    problem = "position or velocity array differs in length from name";
  std::vector<int> dofs;
  for (size_t i = 0; problem.empty() && i < n; ++i) {
    const int d = model_->dofIndex(msg->name[i]);  // dofs are fixed after init: no lock needed
    if (d < 0) problem = "unknown joint '" + msg->name[i] + "'";
    else if (!std::isfinite(msg->effort[i])) problem = "effort for '" + msg->name[i] + "' is not finite";
    dofs.push_back(d);
  }
  if (!problem.empty()) {
    ROS_WARN_THROTTLE(1.0, "mechanism_sim: effort command rejected: %s", problem.c_str());
    return;
  }
  std::lock_guard<std::mutex> lock(mutex_);
  for (size_t i = 0; i < n; ++i) model_->setEffort(dofs[i], msg->effort[i]);
}

bool SimNode::onReset(std_srvs::Empty::Request&, std_srvs::Empty::Response&) {
  std::lock_guard<std::mutex> lock(mutex_);
  model_->reset();
  worst_position_ = worst_velocity_ = 0.0;
  restartPacing();
  if (!publish_clock_) anchorStampsToWall();  // stamps go on, not back
  publish();
  return true;
}

bool SimNode::onPause(std_srvs::Empty::Request&, std_srvs::Empty::Response&) {
  paused_ = true;
  return true;
}

bool SimNode::onUnpause(std_srvs::Empty::Request&, std_srvs::Empty::Response&) {
  std::lock_guard<std::mutex> lock(mutex_);
  paused_ = false;
  restartPacing();
  return true;
}

bool SimNode::onStep(StepSimulation::Request& req, StepSimulation::Response& res) {
  if (!paused_ || req.steps > 1000000) {
    ROS_WARN("mechanism_sim: ~advance needs a paused simulation and at most 1000000 steps");
    return false;
  }
  std::lock_guard<std::mutex> lock(mutex_);
  try {
    for (uint32_t s = 0; s < req.steps; ++s) model_->step(dt_);
  } catch (const std::exception& e) {
    ROS_ERROR("mechanism_sim: %s", e.what());
    return false;
  }
  publish();
  res.time = model_->mechanism().time();
  return true;
}

void SimNode::diagnose(diagnostic_updater::DiagnosticStatusWrapper& status) {
  std::lock_guard<std::mutex> lock(mutex_);
  const Mechanism& m = model_->mechanism();
  const double p = m.positionViolation(), v = m.velocityViolation();
  if (p > 1e-8 || v > 1e-8) status.summary(diagnostic_msgs::DiagnosticStatus::ERROR, "constraints violated");
  else if (behind_) status.summary(diagnostic_msgs::DiagnosticStatus::WARN, "falling behind real time");
  else if (paused_) status.summary(diagnostic_msgs::DiagnosticStatus::OK, "paused");
  else status.summary(diagnostic_msgs::DiagnosticStatus::OK, "running");
  status.add("simulation time [s]", m.time());
  status.add("position violation (max |Phi|)", p);
  status.add("velocity violation (max |Phi_q v|)", v);
  status.add("largest position violation so far", worst_position_);
  status.add("largest velocity violation so far", worst_velocity_);
  status.add("constraint equations", m.numEquations());
  status.add("dependent equations", m.dependencies().dependent);
  status.add("energy [J]", m.kineticEnergy() + m.potentialEnergy());
  status.add("real-time factor", rtf_achieved_);
  status.add("real-time factor target", rtf_target_);
  status.add("step time [s]", step_time_);
}

}  // namespace mechanism_sim
