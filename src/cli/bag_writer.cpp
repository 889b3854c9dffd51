#include "bag_writer.h"

#include <boost/make_shared.hpp>
#include <geometry_msgs/TransformStamped.h>
#include <geometry_msgs/Vector3Stamped.h>
#include <rosgraph_msgs/Clock.h>
#include <sensor_msgs/JointState.h>
#include <tf2_msgs/TFMessage.h>

#include "../node/ros_conversions.h"
#include "mechanism_sim/JointReactions.h"

namespace mechanism_sim {

namespace {

// The connection header rosbag record would store for the node's publisher: the player
// advertises from it (latched for /tf_static, as tf2_ros::StaticTransformBroadcaster).
template <class M>
boost::shared_ptr<ros::M_string> connection(const std::string& topic, bool latched = false) {
  auto h = boost::make_shared<ros::M_string>();
  (*h)["topic"] = topic;
  (*h)["type"] = ros::message_traits::datatype<M>();
  (*h)["md5sum"] = ros::message_traits::md5sum<M>();
  (*h)["message_definition"] = ros::message_traits::definition<M>();
  (*h)["callerid"] = kBagNode;
  (*h)["latching"] = latched ? "1" : "0";
  return h;
}

}  // namespace

template <class M>
void BagWriter::put(const char* topic, const ros::Time& t, const M& msg, bool latched) {
  auto& header = connections_[topic];
  if (!header) header = connection<M>(topic, latched);
  bag_.write(topic, t, msg, header);
}

ros::Time BagWriter::stamp(double t) { return ros::Time(t) + ros::Duration(0, 1); }

BagWriter::BagWriter(const std::string& path, const MechanismModel& model) : model_(model) {
  bag_.open(path, rosbag::bagmode::Write);
  for (const TreeJoint& j : model_.treeJoints())
    tree_links_.emplace_back(model_.linkIndex(j.parent), model_.linkIndex(j.child));
}

void BagWriter::write(const Sample& s) {
  const ros::Time now = stamp(s.time);
  // tf of the URDF tree joints (fixed or moving), as SimNode::treeTransform.
  auto transforms = [&](bool fixed) {
    tf2_msgs::TFMessage tf;
    for (size_t j = 0; j < tree_links_.size(); ++j) {
      const TreeJoint& joint = model_.treeJoints()[j];
      if (joint.fixed != fixed) continue;
      geometry_msgs::TransformStamped t;
      t.header.stamp = now;
      t.header.frame_id = joint.parent;
      t.child_frame_id = joint.child;
      t.transform = toTransform(s.link_poses[tree_links_[j].first].inverse() * s.link_poses[tree_links_[j].second]);
      tf.transforms.push_back(t);
    }
    return tf;
  };

  // /clock first, so that a player's time has reached the stamps of what follows.
  rosgraph_msgs::Clock clock;
  clock.clock = now;
  put(kBagClock, now, clock);

  if (!wrote_static_) {
    wrote_static_ = true;
    const tf2_msgs::TFMessage fixed = transforms(true);
    if (!fixed.transforms.empty()) put(kBagTfStatic, now, fixed, true);
  }

  sensor_msgs::JointState js;
  js.header.stamp = now;
  for (const Dof& d : model_.dofs()) js.name.push_back(d.name);
  js.position = s.position;
  js.velocity = s.velocity;
  js.effort = s.effort;
  put(kBagJointStates, now, js);

  const tf2_msgs::TFMessage moving = transforms(false);
  if (!moving.transforms.empty()) put(kBagTf, now, moving);

  geometry_msgs::Vector3Stamped v;
  v.header.stamp = now;
  v.header.frame_id = model_.rootLink();
  v.vector.x = s.position_violation;
  v.vector.y = s.velocity_violation;
  put(kBagViolation, now, v);

  // Each wrench in its own joint frame on the child link (doc/simulate.md "Joint
  // reactions"); the header is the violation's (the root link), as the node's.
  JointReactions r;
  r.header = v.header;
  for (const JointReaction& jr : s.reactions) {
    geometry_msgs::Wrench w;
    w.force.x = jr.force.x(), w.force.y = jr.force.y(), w.force.z = jr.force.z();
    w.torque.x = jr.torque.x(), w.torque.y = jr.torque.y(), w.torque.z = jr.torque.z();
    r.name.push_back(jr.joint);
    r.wrench.push_back(w);
  }
  put(kBagReactions, now, r);
}

}  // namespace mechanism_sim
