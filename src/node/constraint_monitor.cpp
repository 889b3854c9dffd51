// constraint_monitor: a rostest test node for users' own mechanisms (doc/node.md "Verifying
// a mechanism with rostest"). Fails when the simulator's largest constraint violation
// exceeds ~bound over ~duration, when no violation messages arrive, or when pairs of points
// that a loop ties together (each a point in a tf frame) drift apart by more than
// ~frame_tolerance.
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <tf2_ros/transform_listener.h>

#include <geometry_msgs/Vector3Stamped.h>

#include <cmath>
#include <string>
#include <vector>

namespace {

struct PointPair {
  std::string frame_a, frame_b;
  double a[3] = {0, 0, 0}, b[3] = {0, 0, 0};
};

std::vector<PointPair> readPairs(ros::NodeHandle& pnh) {
  std::vector<PointPair> pairs;
  XmlRpc::XmlRpcValue list;
  if (!pnh.getParam("coincident", list)) return pairs;
  if (list.getType() != XmlRpc::XmlRpcValue::TypeArray) throw std::runtime_error("~coincident must be a list");
  for (int i = 0; i < list.size(); ++i) {
    XmlRpc::XmlRpcValue& e = list[i];
    PointPair p;
    p.frame_a = static_cast<std::string>(e["frame_a"]);
    p.frame_b = static_cast<std::string>(e["frame_b"]);
    for (const char* key : {"point_a", "point_b"}) {
      if (!e.hasMember(key)) continue;
      XmlRpc::XmlRpcValue& v = e[key];
      for (int k = 0; k < 3; ++k)
        (key[6] == 'a' ? p.a : p.b)[k] = v[k].getType() == XmlRpc::XmlRpcValue::TypeInt ? static_cast<int>(v[k])
                                                                                         : static_cast<double>(v[k]);
    }
    pairs.push_back(p);
  }
  return pairs;
}

TEST(ConstraintMonitor, ViolationStaysWithinTheBound) {
  ros::NodeHandle nh, pnh("~");
  std::string topic;
  double bound, duration, timeout, tolerance;
  int min_messages;
  pnh.param<std::string>("violation_topic", topic, "mechanism_sim/constraint_violation");
  pnh.param("bound", bound, 1e-10);
  pnh.param("duration", duration, 5.0);
  pnh.param("timeout", timeout, 20.0);
  pnh.param("min_messages", min_messages, 10);
  pnh.param("frame_tolerance", tolerance, 1e-6);
  const std::vector<PointPair> pairs = readPairs(pnh);

  int count = 0;
  double worst_p = 0, worst_v = 0;
  auto sub = nh.subscribe<geometry_msgs::Vector3Stamped>(topic, 100, [&](const geometry_msgs::Vector3Stamped::ConstPtr& m) {
    ++count;
    worst_p = std::max(worst_p, std::fabs(m->vector.x));
    worst_v = std::max(worst_v, std::fabs(m->vector.y));
  });
  tf2_ros::Buffer buffer;
  tf2_ros::TransformListener listener(buffer);

  const ros::WallTime start = ros::WallTime::now();
  while (ros::ok() && count == 0 && (ros::WallTime::now() - start).toSec() < timeout) {
    ros::spinOnce();
    ros::WallDuration(0.01).sleep();
  }
  ASSERT_GT(count, 0) << "no message on " << sub.getTopic() << " within " << timeout << " s";
  const ros::WallTime begin = ros::WallTime::now();
  double worst_gap = 0;
  int gap_checks = 0;
  while (ros::ok() && (ros::WallTime::now() - begin).toSec() < duration) {
    ros::spinOnce();
    for (const PointPair& p : pairs) {
      geometry_msgs::TransformStamped t;
      try {
        t = buffer.lookupTransform(p.frame_a, p.frame_b, ros::Time(0));
      } catch (const tf2::TransformException&) {
        continue;  // not yet available
      }
      const auto& q = t.transform.rotation;
      const auto& tr = t.transform.translation;
      // point_b in frame_a: R(q) b + t
      const double x = p.b[0], y = p.b[1], z = p.b[2];
      const double ix = q.w * x + q.y * z - q.z * y, iy = q.w * y + q.z * x - q.x * z,
                   iz = q.w * z + q.x * y - q.y * x, iw = -q.x * x - q.y * y - q.z * z;
      const double bx = ix * q.w + iw * -q.x + iy * -q.z - iz * -q.y + tr.x;
      const double by = iy * q.w + iw * -q.y + iz * -q.x - ix * -q.z + tr.y;
      const double bz = iz * q.w + iw * -q.z + ix * -q.y - iy * -q.x + tr.z;
      worst_gap = std::max(worst_gap, std::sqrt(std::pow(bx - p.a[0], 2) + std::pow(by - p.a[1], 2) + std::pow(bz - p.a[2], 2)));
      ++gap_checks;
    }
    ros::WallDuration(0.02).sleep();
  }
  EXPECT_GE(count, min_messages) << "too few messages on " << sub.getTopic();
  EXPECT_LE(worst_p, bound) << "position-level violation on " << sub.getTopic();
  EXPECT_LE(worst_v, bound) << "velocity-level violation on " << sub.getTopic();
  if (!pairs.empty()) {
    EXPECT_GT(gap_checks, 0) << "the ~coincident frames were never available on tf";
    EXPECT_LE(worst_gap, tolerance) << "points tied by a loop drifted apart";
  }
  ROS_INFO("constraint_monitor: %d messages, worst violation %.2e / %.2e, worst gap %.2e (%d checks)", count,
           worst_p, worst_v, worst_gap, gap_checks);
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "constraint_monitor");
  ros::NodeHandle nh;  // keep the node alive across the test
  return RUN_ALL_TESTS();
}
