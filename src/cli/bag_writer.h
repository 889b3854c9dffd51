// simulate --bag: the run's samples as a ROS bag of what the node publishes (doc/simulate.md
// "Bags"), so that `rosbag play --clock FILE.bag` replays the run as if the node had
// run with ~publish_clock: /joint_states, /tf, /tf_static (once, latched),
// /clock, /mechanism_sim/constraint_violation and /mechanism_sim/joint_reactions.
// Needs librosbag_storage and the message headers, not roscpp.
#pragma once
#include <map>
#include <string>
#include <utility>
#include <vector>

#include <ros/time.h>
#include <rosbag/bag.h>

#include "mechanism_sim/urdf/model.h"
#include "mechanism_sim/urdf/run_loop.h"

namespace mechanism_sim {

// Topics as the node, started as `mechanism_sim` (launch/simulate.launch), names them.
constexpr const char* kBagNode = "/mechanism_sim";
constexpr const char* kBagJointStates = "/joint_states";
constexpr const char* kBagTf = "/tf";
constexpr const char* kBagTfStatic = "/tf_static";
constexpr const char* kBagClock = "/clock";
constexpr const char* kBagViolation = "/mechanism_sim/constraint_violation";
constexpr const char* kBagReactions = "/mechanism_sim/joint_reactions";

class BagWriter {
 public:
  // Creates (truncates) the file. Throws rosbag::BagException when it cannot.
  BagWriter(const std::string& path, const MechanismModel& model);
  // A sample's messages, stamped (and recorded) at stamp(sample.time); the first call
  // also writes /tf_static (when the model has fixed tree joints). The sample must have
  // its reactions (RunLoop::setReactions(true)). Throws rosbag::BagException.
  void write(const Sample& sample);
  // Writes the index; the destructor does it too (a run that fails keeps its samples).
  void close() { bag_.close(); }

  // Simulation time t as a stamp: t + 1 ns. A bag cannot hold a message before
  // ros::TIME_MIN (1 ns), and a zero time means "no time yet" to ROS clients, so every
  // stamp is offset by that nanosecond (the node with ~publish_clock stamps t itself).
  static ros::Time stamp(double t);

 private:
  template <class M>
  void put(const char* topic, const ros::Time& t, const M& msg, bool latched = false);

  const MechanismModel& model_;
  rosbag::Bag bag_;
  std::map<std::string, boost::shared_ptr<ros::M_string>> connections_;  // by topic
  std::vector<std::pair<int, int>> tree_links_;  // (parent, child) link of each tree joint
  bool wrote_static_ = false;
};

}  // namespace mechanism_sim
