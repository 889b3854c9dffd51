#include "sim_node.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <sstream>

#include <geometry_msgs/Vector3Stamped.h>
#include <rosgraph_msgs/Clock.h>

#include "mechanism_sim/JointReactions.h"
#include "ros_conversions.h"

namespace mechanism_sim {
namespace {

// What is wrong with an effort command's arrays (~effort_command, ~actuator_effort_command):
// one effort per name, and position and velocity, when given, one per name; "" if nothing.
std::string effortArraysProblem(const sensor_msgs::JointState& msg) {
  const size_t n = msg.name.size();
  if ((!msg.position.empty() && msg.position.size() != n) || (!msg.velocity.empty() && msg.velocity.size() != n))
    return "position or velocity array differs in length from name";
  if (msg.effort.size() != n) return "name and effort arrays differ in length";
  return "";
}

}  // namespace

bool NodeParams::read(const ros::NodeHandle& pnh) {
  pnh.param("step", step, 1e-3);
  pnh.param("publish_rate", publish_rate, 100.0);
  pnh.param("real_time_factor", real_time_factor, 1.0);
  pnh.param("publish_clock", publish_clock, false);
  pnh.param<std::string>("frame_prefix", frame_prefix, "");
  pnh.param("start_paused", start_paused, false);
  pnh.param("drive_acceleration", drive_acceleration, 10.0);
  pnh.param("reaction_arrow_scale", reaction_arrow_scale, 0.01);
  pnh.param("trajectory_start_tolerance", trajectory_start_tolerance, kTrajectoryStartTolerance);
  if (!(trajectory_start_tolerance >= 0) || !std::isfinite(trajectory_start_tolerance)) {
    ROS_FATAL("mechanism_sim: ~trajectory_start_tolerance must be finite and >= 0");
    return false;
  }
  if (!(step > 0) || step > 0.1 || !(publish_rate > 0) || !(real_time_factor >= 0)) {
    ROS_FATAL("mechanism_sim: ~step must be in (0, 0.1] s, ~publish_rate > 0 and ~real_time_factor >= 0");
    return false;
  }
  if (!(drive_acceleration > 0) || !std::isfinite(drive_acceleration) || !(reaction_arrow_scale >= 0) ||
      !std::isfinite(reaction_arrow_scale)) {
    ROS_FATAL("mechanism_sim: ~drive_acceleration must be finite and > 0, ~reaction_arrow_scale finite and >= 0");
    return false;
  }
  pnh.param<std::string>("integrator", load.integrator, "");
  pnh.param<std::string>("formulation", load.formulation, "");
  pnh.param<std::string>("closures_file", load.closures_file, "");  // doc/loop_dialects.md
  pnh.param<std::string>("actuators_file", load.actuators_file, "");  // doc/actuators.md
  pnh.param<bool>("actuator_limits", load.actuator_limits, false);      // doc/actuators.md (saturating mode)
  pnh.param<bool>("strict_inertia", load.strict_inertia, false);     // doc/robots.md
  std::map<std::string, double> positions, velocities;
  pnh.getParam("initial_positions", positions);
  pnh.getParam("initial_velocities", velocities);
  load.positions.assign(positions.begin(), positions.end());
  load.velocities.assign(velocities.begin(), velocities.end());
  // ~xacro_args: "name:=value name:=value" (or name=value: roslaunch's command line takes
  // no ":=" inside a value) for a ~model_file ending in .xacro (doc/xacro.md)
  std::string xacro_args;
  if (pnh.getParam("xacro_args", xacro_args)) {
    std::istringstream words(xacro_args);
    std::string word;
    while (words >> word) {
      const size_t eq = word.find('='), op = eq != std::string::npos && eq > 0 && word[eq - 1] == ':' ? eq - 1 : eq;
      if (eq == std::string::npos || op == 0) {
        ROS_FATAL("mechanism_sim: ~xacro_args: '%s' is not name:=value", word.c_str());
        return false;
      }
      load.xacro_args.emplace_back(word.substr(0, op), word.substr(eq + 1));
    }
  }
  return true;
}

SimNode::SimNode() : pnh_("~") {}

bool SimNode::init() {
  if (!params_.read(pnh_) || !load()) return false;
  paused_ = params_.start_paused;
  ROS_INFO("mechanism_sim: '%s': %d bodies, %zu joint dofs, %d constraint equations; %s; assembled to %.1e; %s",
           model_->name().c_str(), model_->numMovingBodies(), model_->dofs().size(), model_->numEquations(),
           model_->dependencies().describe().c_str(), model_->assembly().position_residual,
           model_->formulationReason().c_str());

  // A sample per publish period.
  const long per_publish = std::max(1L, std::lround(1.0 / (params_.publish_rate * params_.step)));
  loop_ = std::make_unique<RunLoop>(*model_, params_.step, per_publish);
  loop_->setReactions(true);
  pacer_ = std::make_unique<Pacer>(params_.real_time_factor, model_->time());
  for (const TreeJoint& j : model_->treeJoints())
    tree_links_.emplace_back(model_->linkIndex(j.parent), model_->linkIndex(j.child));

  joint_states_ = nh_.advertise<sensor_msgs::JointState>("joint_states", 10);
  actuator_states_ = pnh_.advertise<sensor_msgs::JointState>("actuator_states", 10);
  actuator_command_.assign(model_->actuators().size(), 0.0);
  violation_ = pnh_.advertise<geometry_msgs::Vector3Stamped>("constraint_violation", 10);
  reactions_ = pnh_.advertise<JointReactions>("joint_reactions", 10);
  coupling_reactions_ = pnh_.advertise<sensor_msgs::JointState>("coupling_reactions", 10);
  markers_ = std::make_unique<ConstraintMarkers>(pnh_, *model_, params_.reaction_arrow_scale);
  if (params_.publish_clock) clock_ = nh_.advertise<rosgraph_msgs::Clock>("/clock", 10);
  effort_ = pnh_.subscribe("effort_command", 10, &SimNode::onEffort, this);
  actuator_effort_ = pnh_.subscribe("actuator_effort_command", 10, &SimNode::onActuatorEffort, this);
  drive_ = pnh_.subscribe("drive_command", 10, &SimNode::onDriveCommand, this);
  trajectory_ = pnh_.subscribe("joint_trajectory", 10, &SimNode::onTrajectory, this);
  reset_ = pnh_.advertiseService("reset", &SimNode::onReset, this);
  pause_ = pnh_.advertiseService("pause", &SimNode::onPause, this);
  unpause_ = pnh_.advertiseService("unpause", &SimNode::onUnpause, this);
  step_ = pnh_.advertiseService("advance", &SimNode::onStep, this);
  diagnostics_ = std::make_unique<diagnostic_updater::Updater>(nh_, pnh_);
  diagnostics_->setHardwareID("mechanism_sim/" + model_->name());
  diagnostics_->add("constraints", this, &SimNode::diagnose);

  if (!params_.publish_clock) anchorStampsToWall();
  publishStatic();
  return true;
}

// ~model_file, else robot_description; then ~gravity.
bool SimNode::load() {
  std::string model_file, description;
  try {
    if (pnh_.getParam("model_file", model_file) && !model_file.empty()) {
      model_ = loadModelFile(model_file, params_.load);
    } else if (nh_.getParam("robot_description", description)) {
      model_ = loadModelString(description, "robot_description", params_.load);
    } else {
      ROS_FATAL("mechanism_sim: no model: set ~model_file or robot_description");
      return false;
    }
    std::vector<double> gravity;
    if (pnh_.getParam("gravity", gravity)) {
      if (gravity.size() != 3 || !std::isfinite(gravity[0] + gravity[1] + gravity[2]))
        throw LoadError("~gravity must be three finite numbers");
      model_->setGravity(Eigen::Vector3d(gravity[0], gravity[1], gravity[2]));
    }
  } catch (const std::exception& e) {
    ROS_FATAL("mechanism_sim: %s", e.what());
    return false;
  }
  for (const std::string& note : model_->notes()) ROS_WARN("mechanism_sim: %s", note.c_str());
  return true;
}

ros::Time SimNode::stamp() const { return time_origin_ + ros::Duration(model_->time()); }

// Without /clock: the current simulation time is stamped as the current wall time, or
// 1 µs after the last stamp published when that is later: a running sample is published
// up to a sample period ahead of wall time, and ~advance moves simulation time on while
// wall time stands, so re-anchoring to the wall alone took stamps back. (1 µs, not 1 ns:
// tf2's Python binding reads stamps as double seconds, which cannot tell 1 ns apart.)
void SimNode::anchorStampsToWall() {
  ros::Time now(ros::WallTime::now().toSec());
  if (now <= last_stamp_ + ros::Duration(0, 1000)) now = last_stamp_ + ros::Duration(0, 1000);
  time_origin_ = now - ros::Duration(model_->time());
}

// tf of a URDF tree joint: the child link in the parent link, frames prefixed.
geometry_msgs::TransformStamped SimNode::treeTransform(size_t tree_joint, const ros::Time& time) const {
  const TreeJoint& j = model_->treeJoints()[tree_joint];
  const auto& poses = loop_->sample().link_poses;
  geometry_msgs::TransformStamped t;
  t.header.stamp = time;
  t.header.frame_id = params_.frame_prefix + j.parent;
  t.child_frame_id = params_.frame_prefix + j.child;
  t.transform = toTransform(poses[tree_links_[tree_joint].first].inverse() * poses[tree_links_[tree_joint].second]);
  return t;
}

void SimNode::publishStatic() {
  std::vector<geometry_msgs::TransformStamped> fixed;
  for (size_t j = 0; j < model_->treeJoints().size(); ++j)
    if (model_->treeJoints()[j].fixed) fixed.push_back(treeTransform(j, stamp()));
  if (!fixed.empty()) tf_static_.sendTransform(fixed);
}

// Publishes the run loop's sample. Without /clock, stamps follow wall time: a pause, a
// reset, or a sample whose stamp would not follow the last one (~advance of 0 steps) moves
// the origin so that they never repeat or run backwards. With /clock, a pause
// freezes time and tf is not republished (a repeated stamp is an error for tf2 listeners),
// nor is it when the stamp is that of the last tf sent (~advance of 0 steps while paused,
// a second reset in a row).
void SimNode::publish(bool paused) {
  if (!params_.publish_clock && (paused || stamp() < last_stamp_ + ros::Duration(0, 1000))) anchorStampsToWall();
  const ros::Time now = stamp();
  last_stamp_ = now;
  const Sample& s = loop_->sample();
  sensor_msgs::JointState js;
  js.header.stamp = now;
  for (const Dof& d : model_->dofs()) js.name.push_back(d.name);
  js.position = s.position;
  js.velocity = s.velocity;
  js.effort = s.effort;
  joint_states_.publish(js);
  if (!s.actuators.empty()) {
    // by actuator: motor position, speed and torque (doc/actuators.md)
    sensor_msgs::JointState as;
    as.header.stamp = now;
    for (size_t a = 0; a < s.actuators.size(); ++a) {
      as.name.push_back(model_->actuators()[a].name);
      as.position.push_back(s.actuators[a].position);
      as.velocity.push_back(s.actuators[a].velocity);
      as.effort.push_back(s.actuators[a].torque);
    }
    actuator_states_.publish(as);
  }

  std::vector<geometry_msgs::TransformStamped> moving;
  for (size_t j = 0; j < model_->treeJoints().size(); ++j)
    if (!model_->treeJoints()[j].fixed) moving.push_back(treeTransform(j, now));
  if (!moving.empty() && !(paused && params_.publish_clock) && now != last_tf_stamp_) {
    tf_.sendTransform(moving);
    last_tf_stamp_ = now;
  }

  geometry_msgs::Vector3Stamped v;
  v.header.stamp = now;
  v.header.frame_id = params_.frame_prefix + model_->rootLink();
  v.vector.x = s.position_violation;
  v.vector.y = s.velocity_violation;
  violation_.publish(v);
  JointReactions r;
  r.header = v.header;
  for (const JointReaction& jr : s.reactions) {
    r.name.push_back(jr.joint);
    geometry_msgs::Wrench w;
    w.force.x = jr.force.x(), w.force.y = jr.force.y(), w.force.z = jr.force.z();
    w.torque.x = jr.torque.x(), w.torque.y = jr.torque.y(), w.torque.z = jr.torque.z();
    r.wrench.push_back(w);
  }
  reactions_.publish(r);
  if (!model_->couplings().empty()) {
    // by coupling: its multiplier lambda as the effort (coordinate i carries -c_i lambda)
    sensor_msgs::JointState c;
    c.header = v.header;
    for (const CouplingInfo& ci : model_->couplings()) c.name.push_back(ci.name);
    c.effort = s.coupling_reactions;
    coupling_reactions_.publish(c);
  }
  markers_->publish(s, v.header);

  if (params_.publish_clock) {
    rosgraph_msgs::Clock c;
    c.clock = now;
    clock_.publish(c);
  }
}

void SimNode::run() {
  ros::AsyncSpinner spinner(1);
  spinner.start();
  {
    std::lock_guard<std::mutex> lock(mutex_);
    publish();
  }
  while (ros::ok()) {
    if (paused_) {
      {
        std::lock_guard<std::mutex> lock(mutex_);
        publish(true);
        pacer_->restart(model_->time());
      }
      diagnostics_->update();
      ros::WallDuration(1.0 / params_.publish_rate).sleep();
      continue;
    }
    double sim_now = 0;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      try {
        readActuatorLimits(true);
        advance(loop_->stepsPerSample());
      } catch (const std::exception& e) {
        ROS_FATAL("mechanism_sim: %s", e.what());
        ros::shutdown();
        break;
      }
      publish();
      sim_now = loop_->sample().time;
    }
    diagnostics_->update();
    pacer_->pace(sim_now);
  }
  spinner.stop();
}

void SimNode::onEffort(const sensor_msgs::JointState::ConstPtr& msg) {
  const size_t n = msg->name.size();
  std::string problem = effortArraysProblem(*msg);
  std::vector<int> dofs;
  for (size_t i = 0; problem.empty() && i < n; ++i) {
    const int d = model_->dofIndex(msg->name[i]);  // dofs are fixed after init: no lock needed
    if (d < 0) problem = "unknown joint '" + msg->name[i] + "'";
    else if (!std::isfinite(msg->effort[i])) problem = "effort for '" + msg->name[i] + "' is not finite";
    else if (!model_->dofs()[d].actuated) problem = model_->whyPassive(d);
    dofs.push_back(d);
  }
  if (!problem.empty()) {
    ROS_WARN_THROTTLE(1.0, "mechanism_sim: effort command rejected: %s", problem.c_str());
    return;
  }
  std::lock_guard<std::mutex> lock(mutex_);
  for (size_t i = 0; i < n; ++i) model_->setEffort(dofs[i], msg->effort[i]);
}

// ~actuator_effort_command: torques of actuators by name, mapped to their transmissions'
// joint efforts by virtual work, tau_q = E^T tau_theta (transmission.h). An actuator not
// named keeps its last torque (a differential's joint efforts take both of its actuators'
// torques); the joint efforts replace what ~effort_command last set on those joints. A
// message with an unknown actuator, a non-finite torque, arrays of different lengths or an
// actuator of a passive joint is rejected whole, as ~effort_command's.
void SimNode::onActuatorEffort(const sensor_msgs::JointState::ConstPtr& msg) {
  const size_t n = msg->name.size();
  std::string problem = effortArraysProblem(*msg);
  const std::vector<Actuator>& actuators = model_->actuators();  // fixed after init: no lock needed
  std::vector<int> which;
  for (size_t i = 0; problem.empty() && i < n; ++i) {
    int a = 0;
    while (a < static_cast<int>(actuators.size()) && actuators[a].name != msg->name[i]) ++a;
    if (a == static_cast<int>(actuators.size())) problem = "unknown actuator '" + msg->name[i] + "'";
    else if (!std::isfinite(msg->effort[i])) problem = "effort for '" + msg->name[i] + "' is not finite";
    else
      for (int d : model_->transmissions()[actuators[a].transmission].dofs)
        if (!model_->dofs()[d].actuated) problem = "actuator '" + msg->name[i] + "' drives " + model_->whyPassive(d);
    which.push_back(a);
  }
  if (!problem.empty()) {
    ROS_WARN_THROTTLE(1.0, "mechanism_sim: actuator effort command rejected: %s", problem.c_str());
    return;
  }
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<bool> touched(model_->transmissions().size(), false);
  for (size_t i = 0; i < n; ++i) {
    actuator_command_[which[i]] = msg->effort[i];
    touched[actuators[which[i]].transmission] = true;
  }
  for (size_t t = 0; t < touched.size(); ++t) {
    if (!touched[t]) continue;
    const TransmissionInfo& info = model_->transmissions()[t];
    const int m = static_cast<int>(info.dofs.size());
    Eigen::Vector2d tau_theta = Eigen::Vector2d::Zero();
    for (int k = 0; k < m; ++k) tau_theta[k] = actuator_command_[info.actuators[k]];
    const Eigen::Vector2d tau_q = info.E.transpose() * tau_theta;
    for (int k = 0; k < m; ++k) model_->setEffort(info.dofs[k], tau_q[k]);
  }
}

// ~drive_command: velocities of velocity-driven dofs, by name; each drive ramps to its new
// velocity at ~drive_acceleration. A command naming an undriven dof, a profile drive, or a
// non-finite value is rejected whole.
void SimNode::onDriveCommand(const sensor_msgs::JointState::ConstPtr& msg) {
  const size_t n = msg->name.size();
  std::string problem;
  if (msg->velocity.size() != n) problem = "name and velocity arrays differ in length";
  std::vector<int> dofs;
  std::lock_guard<std::mutex> lock(mutex_);  // a trajectory may drive a dof that was free
  for (size_t i = 0; problem.empty() && i < n; ++i) {
    const int d = model_->dofIndex(msg->name[i]);
    if (d < 0) problem = "unknown joint '" + msg->name[i] + "'";
    else if (model_->dofs()[d].drive < 0) problem = "'" + msg->name[i] + "' is not driven";
    else if (!std::isfinite(msg->velocity[i])) problem = "velocity for '" + msg->name[i] + "' is not finite";
    dofs.push_back(d);
  }
  if (problem.empty()) {
    // all or nothing: a profile drive refuses before any drive has changed
    for (size_t i = 0; problem.empty() && i < n; ++i) {
      const int k = model_->mechanism().driveOf(model_->dofs()[dofs[i]].joint_index, model_->dofs()[dofs[i]].k);
      if (model_->mechanism().system().drives[k].profile.kind() != DriveProfile::Kind::kVelocity)
        problem = "'" + msg->name[i] + "' follows a profile and takes no velocity command";
    }
    for (size_t i = 0; problem.empty() && i < n; ++i)
      model_->commandDriveVelocity(dofs[i], msg->velocity[i], params_.drive_acceleration);
  }
  if (!problem.empty()) ROS_WARN_THROTTLE(1.0, "mechanism_sim: drive command rejected: %s", problem.c_str());
}

// ~joint_trajectory (doc/trajectories.md): the named dofs follow a C2 path through the
// points from header.stamp (zero: on receipt), replacing the rest of what they followed;
// a message that cannot be followed is rejected whole with ROS_ERROR. One stamped in the
// future waits (a newer message replaces a waiting one).
void SimNode::onTrajectory(const trajectory_msgs::JointTrajectory::ConstPtr& msg) {
  Trajectory traj;
  traj.dofs = msg->joint_names;
  bool velocities = false, accelerations = false;
  for (const auto& p : msg->points) velocities |= !p.velocities.empty(), accelerations |= !p.accelerations.empty();
  for (const auto& p : msg->points) {
    traj.times.push_back(p.time_from_start.toSec());
    traj.positions.push_back(p.positions);
    if (velocities) traj.velocities.push_back(p.velocities);
    if (accelerations) traj.accelerations.push_back(p.accelerations);
  }
  std::lock_guard<std::mutex> lock(mutex_);
  const double start = msg->header.stamp.isZero() ? model_->time() : (msg->header.stamp - time_origin_).toSec();
  if (start <= model_->time() + 1e-9) {
    pending_.reset();
    followOrReject(traj, start);
    return;
  }
  try {
    checkTrajectory(*model_, traj);  // what can be judged now is judged now
  } catch (const TrajectoryError& e) {
    ROS_ERROR("mechanism_sim: trajectory rejected: %s", e.what());
    return;
  }
  pending_ = std::make_unique<Trajectory>(std::move(traj));
  pending_start_ = start;
}

void SimNode::followOrReject(const Trajectory& traj, double start) {
  try {
    followTrajectory(*model_, traj, start, params_.trajectory_start_tolerance);
    ROS_INFO("mechanism_sim: following a trajectory of %zu points from t = %.6f s", traj.times.size(), start);
  } catch (const TrajectoryError& e) {
    ROS_ERROR("mechanism_sim: trajectory rejected: %s", e.what());
  }
}

void SimNode::advance(long steps) {
  if (pending_) {
    // the steps before the start (to round-off: a start on the step grid is met exactly)
    const double ahead = (pending_start_ - model_->time()) / loop_->h();
    const long before = std::max(0L, static_cast<long>(std::ceil(ahead - 1e-6)));
    if (before < steps) {
      loop_->advance(before);
      const std::unique_ptr<Trajectory> traj = std::move(pending_);
      followOrReject(*traj, pending_start_);
      loop_->advance(steps - before);
      return;
    }
  }
  loop_->advance(steps);
}

void SimNode::readActuatorLimits(bool cached) {
  bool on = model_->actuatorLimits();
  // (absent, or not a bool: the mode stays as it is)
  if (!(cached ? pnh_.getParamCached("actuator_limits", on) : pnh_.getParam("actuator_limits", on))) return;
  if (on == model_->actuatorLimits()) return;
  const std::string note = model_->setActuatorLimits(on);
  ROS_INFO("mechanism_sim: actuator limits %s at t = %.6f s%s%s", on ? "on" : "off", model_->time(),
           note.empty() ? "" : ": ", note.c_str());
}

bool SimNode::onReset(std_srvs::Empty::Request&, std_srvs::Empty::Response&) {
  std::lock_guard<std::mutex> lock(mutex_);
  pending_.reset();
  loop_->reset();  // dofs that trajectories drove are free again
  std::fill(actuator_command_.begin(), actuator_command_.end(), 0.0);  // as the joints' commands
  pacer_->restart(model_->time());
  if (!params_.publish_clock) anchorStampsToWall();  // stamps go on, not back
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
  pacer_->restart(model_->time());
  return true;
}

bool SimNode::onStep(StepSimulation::Request& req, StepSimulation::Response& res) {
  if (!paused_ || req.steps > 1000000) {
    ROS_WARN("mechanism_sim: ~advance needs a paused simulation and at most 1000000 steps");
    return false;
  }
  std::lock_guard<std::mutex> lock(mutex_);
  try {
    readActuatorLimits(false);
    advance(req.steps);
  } catch (const std::exception& e) {
    ROS_ERROR("mechanism_sim: %s", e.what());
    return false;
  }
  publish();
  res.time = loop_->sample().time;
  return true;
}

void SimNode::diagnose(diagnostic_updater::DiagnosticStatusWrapper& status) {
  std::lock_guard<std::mutex> lock(mutex_);
  const double p = model_->positionViolation(), v = model_->velocityViolation();
  const SolverStats& solver = model_->solverStats();
  if (model_->relativePositionViolation() > 1e-8 || model_->relativeVelocityViolation() > 1e-8)
    status.summary(diagnostic_msgs::DiagnosticStatus::ERROR, "constraints violated");
  else if (solver.shortfalls() > 0)
    status.summary(diagnostic_msgs::DiagnosticStatus::WARN, "solver iterations short of tolerance");
  else if (pacer_->behind()) status.summary(diagnostic_msgs::DiagnosticStatus::WARN, "falling behind real time");
  else if (paused_) status.summary(diagnostic_msgs::DiagnosticStatus::OK, "paused");
  else status.summary(diagnostic_msgs::DiagnosticStatus::OK, "running");
  status.add("simulation time [s]", model_->time());
  status.add("position violation (max |Phi|)", p);
  status.add("velocity violation (max |Phi_q v|)", v);
  status.add("largest position violation so far", loop_->worstPositionViolation());
  status.add("largest velocity violation so far", loop_->worstVelocityViolation());
  status.add("constraint equations", model_->numEquations());
  status.add("dependent equations", model_->dependencies().dependent);
  status.add("energy [J]", model_->kineticEnergy() + model_->potentialEnergy());
  status.add("real-time factor", pacer_->achieved());
  status.add("real-time factor target", pacer_->target());
  status.add("step time [s]", loop_->stepWallTime());
  status.add("solver", solver.describe());
  status.add("formulation", model_->formulationReason());
  status.add("iterations short of tolerance", solver.shortfalls());
}

}  // namespace mechanism_sim
