#include "constraint_markers.h"

#include <cstdio>

#include <visualization_msgs/MarkerArray.h>

namespace mechanism_sim {

ConstraintMarkers::ConstraintMarkers(ros::NodeHandle& pnh, const MechanismModel& model)
    : model_(model), publisher_(pnh.advertise<visualization_msgs::MarkerArray>("constraint_markers", 2)) {}

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
  publisher_.publish(ma);
}

}  // namespace mechanism_sim
