#include "constraint_markers.h"

#include <cstdio>

#include <visualization_msgs/MarkerArray.h>

namespace mechanism_sim {

ConstraintMarkers::ConstraintMarkers(ros::NodeHandle& pnh, const MechanismModel& model, double arrow_scale)
    : model_(model), arrow_scale_(arrow_scale), publisher_(pnh.advertise<visualization_msgs::MarkerArray>("constraint_markers", 2)) {}

void ConstraintMarkers::publish(const Sample& sample, const std_msgs::Header& header) {
  visualization_msgs::MarkerArray ma;
  visualization_msgs::Marker text;
  text.header = header;
  text.ns = "constraint_state";
  text.type = visualization_msgs::Marker::TEXT_VIEW_FACING;
  text.pose.position.z = 0.45;
  text.pose.orientation.w = 1.0;
  text.scale.z = 0.03;
  text.color.r = text.color.g = text.color.b = text.color.a = 1.0;
  char buf[160];
  std::snprintf(buf, sizeof buf, "t %.2f s  |Phi| %.1e  |Phi_q v| %.1e  dependent %d", sample.time,
                sample.position_violation, sample.velocity_violation, model_.dependencies().dependent);
  text.text = buf;
  ma.markers.push_back(text);

  visualization_msgs::Marker points;
  points.header = header;
  points.ns = "loop_closures";
  points.type = visualization_msgs::Marker::SPHERE_LIST;
  points.pose.orientation.w = 1.0;
  points.scale.x = points.scale.y = points.scale.z = 0.02;
  points.color.r = 1.0, points.color.g = 0.85, points.color.a = 1.0;
  auto add = [&](int link, const Eigen::Vector3d& point) {
    const Eigen::Vector3d p = sample.link_poses.at(link) * point;
    geometry_msgs::Point gp;
    gp.x = p.x(), gp.y = p.y(), gp.z = p.z();
    points.points.push_back(gp);
  };
  for (const LoopJoint& j : model_.loopJoints()) {
    add(j.parent_link, j.parent_point);
    add(j.child_link, j.child_point);
  }
  if (!points.points.empty()) ma.markers.push_back(points);

  // reaction forces: an arrow per joint from its origin along the force on the child
  // (the sample's reactions are in the joint frame on the child; reactionFrame() is that
  // frame now, and the sample is taken now)
  for (size_t j = 0; j < sample.reactions.size() && arrow_scale_ > 0; ++j) {
    visualization_msgs::Marker arrow;
    arrow.header = header;
    arrow.ns = "reactions";
    arrow.id = static_cast<int>(j);
    arrow.type = visualization_msgs::Marker::ARROW;
    arrow.pose.orientation.w = 1.0;
    arrow.scale.x = 0.006, arrow.scale.y = 0.012, arrow.scale.z = 0.015;  // shaft, head width, head length
    arrow.color.r = 0.95, arrow.color.g = 0.3, arrow.color.b = 0.9, arrow.color.a = 1.0;
    const Eigen::Isometry3d F = model_.reactionFrame(static_cast<int>(j));
    const Eigen::Vector3d from = F.translation(), to = from + arrow_scale_ * (F.linear() * sample.reactions[j].force);
    geometry_msgs::Point a, b;
    a.x = from.x(), a.y = from.y(), a.z = from.z();
    b.x = to.x(), b.y = to.y(), b.z = to.z();
    arrow.points = {a, b};
    ma.markers.push_back(arrow);
  }
  publisher_.publish(ma);
}

}  // namespace mechanism_sim
