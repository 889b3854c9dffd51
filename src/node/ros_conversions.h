// The one place where a pose becomes a ROS transform.
#pragma once
#include <geometry_msgs/Transform.h>

#include <Eigen/Geometry>

namespace mechanism_sim {

inline geometry_msgs::Transform toTransform(const Eigen::Isometry3d& T) {
  geometry_msgs::Transform t;
  const Eigen::Quaterniond q(T.linear());
  t.translation.x = T.translation().x();
  t.translation.y = T.translation().y();
  t.translation.z = T.translation().z();
  t.rotation.w = q.w();
  t.rotation.x = q.x();
  t.rotation.y = q.y();
  t.rotation.z = q.z();
  return t;
}

}  // namespace mechanism_sim
