// simulate --bag: the bag holds what the node publishes (topics, types, frames, stamps), at
// the CSV's samples, readable with the rosbag C++ API and `rosbag info`.
#include <gtest/gtest.h>

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <geometry_msgs/Vector3Stamped.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <rosgraph_msgs/Clock.h>
#include <sensor_msgs/JointState.h>
#include <tf2_msgs/TFMessage.h>

#include "mechanism_sim/JointReactions.h"
#include "run_command.h"

namespace {

const std::string kSource = MECHANISM_SIM_SOURCE_DIR;

using Result = mechanism_sim::testing_util::CommandResult;  // out: stdout and stderr

Result run(const std::string& command) { return mechanism_sim::testing_util::runCommand(command + " 2>&1"); }

Result simulate(const std::string& args) { return run(std::string(SIMULATE_BIN) + " " + args); }

// A CSV with a header: rows of numbers by column name.
struct Csv {
  std::vector<std::string> columns;
  std::vector<std::vector<double>> rows;
  double at(size_t row, const std::string& column) const {
    const auto it = std::find(columns.begin(), columns.end(), column);
    if (it == columns.end()) throw std::runtime_error("no column " + column);
    return rows.at(row).at(it - columns.begin());
  }
};

Csv readCsv(const std::string& path) {
  std::ifstream in(path);
  Csv csv;
  std::string line;
  bool header = true;
  while (std::getline(in, line)) {
    std::stringstream ss(line);
    std::string cell;
    std::vector<double> row;
    while (std::getline(ss, cell, ',')) {
      if (header) csv.columns.push_back(cell);
      else row.push_back(std::stod(cell));
    }
    if (!header) csv.rows.push_back(row);
    header = false;
  }
  return csv;
}

// The CSV's 12 significant digits.
void expectClose(double bag, double csv, const std::string& what) {
  EXPECT_NEAR(bag, csv, 1e-10 * std::max(1.0, std::abs(csv))) << what;
}

// The messages of one topic, with their bag times.
template <class M>
std::vector<std::pair<ros::Time, typename M::ConstPtr>> read(const rosbag::Bag& bag, const std::string& topic) {
  std::vector<std::pair<ros::Time, typename M::ConstPtr>> out;
  rosbag::View view(bag, rosbag::TopicQuery(topic));
  for (const rosbag::MessageInstance& m : view) {
    typename M::ConstPtr msg = m.instantiate<M>();
    EXPECT_TRUE(msg) << topic << ": not a " << ros::message_traits::datatype<M>();
    EXPECT_EQ(m.getCallerId(), "/mechanism_sim") << topic;
    if (msg) out.emplace_back(m.getTime(), msg);
  }
  for (size_t i = 1; i < out.size(); ++i) EXPECT_LT(out[i - 1].first, out[i].first) << topic << " at " << i;
  return out;
}

std::map<std::string, std::string> topicTypes(const rosbag::Bag& bag) {
  rosbag::View view(bag);
  std::map<std::string, std::string> types;
  for (const rosbag::ConnectionInfo* c : view.getConnections()) types[c->topic] = c->datatype;
  return types;
}

// Stamp of a sample at simulation time t: t + 1 ns (a bag holds no message at 0).
ros::Time stampOf(double t) { return ros::Time(t) + ros::Duration(0, 1); }

// child frame -> parent frame of every transform in a message, all stamped `time`.
std::map<std::string, std::string> frames(const tf2_msgs::TFMessage& tf, const ros::Time& time) {
  std::map<std::string, std::string> out;
  for (const geometry_msgs::TransformStamped& t : tf.transforms) {
    EXPECT_EQ(t.header.stamp, time) << t.child_frame_id;
    out[t.child_frame_id] = t.header.frame_id;
  }
  return out;
}

const geometry_msgs::Transform& transformOf(const tf2_msgs::TFMessage& tf, const std::string& child) {
  for (const geometry_msgs::TransformStamped& t : tf.transforms)
    if (t.child_frame_id == child) return t.transform;
  throw std::runtime_error("no transform of " + child);
}

struct Expected {
  std::string urdf;
  double duration;
  long every;
  std::map<std::string, std::string> moving, fixed;  // child -> parent, as the URDF's tree joints
  std::vector<std::string> dofs, reaction_joints;
};

std::string bagPath(const std::string& name) { return ::testing::TempDir() + "/" + name + ".bag"; }

// Runs simulate with --bag and --csv --reactions, and checks the bag (bagPath(name))
// against the CSV.
void checkBag(const Expected& e, const std::string& name) {
  const std::string bag_path = bagPath(name), csv_path = ::testing::TempDir() + "/" + name + ".csv";
  std::remove(bag_path.c_str());
  const Result r = simulate(kSource + "/urdf/" + e.urdf + " --duration " + std::to_string(e.duration) +
                            " --dt 0.001 --output-every " + std::to_string(e.every) + " --reactions --csv " +
                            csv_path + " --bag " + bag_path + " --quiet");
  EXPECT_EQ(r.code, 0) << r.out;
  const Csv csv = readCsv(csv_path);
  const long steps = std::lround(e.duration / 0.001);
  const size_t samples = 1 + (steps + e.every - 1) / e.every;  // t = 0, every N steps, the end
  EXPECT_EQ(csv.rows.size(), samples);

  rosbag::Bag bag(bag_path, rosbag::bagmode::Read);
  std::map<std::string, std::string> types = {{"/clock", "rosgraph_msgs/Clock"},
                                              {"/joint_states", "sensor_msgs/JointState"},
                                              {"/tf", "tf2_msgs/TFMessage"},
                                              {"/mechanism_sim/constraint_violation", "geometry_msgs/Vector3Stamped"},
                                              {"/mechanism_sim/joint_reactions", "mechanism_sim/JointReactions"}};
  if (!e.fixed.empty()) types["/tf_static"] = "tf2_msgs/TFMessage";  // the node sends none without fixed joints
  EXPECT_EQ(topicTypes(bag), types);

  // /clock: a tick per sample, at the sample's time; it is the bag time.
  const auto clock = read<rosgraph_msgs::Clock>(bag, "/clock");
  EXPECT_EQ(clock.size(), samples);
  std::vector<ros::Time> times;
  for (size_t i = 0; i < clock.size() && i < csv.rows.size(); ++i) {
    EXPECT_EQ(clock[i].second->clock, clock[i].first);
    EXPECT_EQ(clock[i].first, stampOf(csv.at(i, "time"))) << "sample " << i;
    times.push_back(clock[i].first);
  }
  EXPECT_EQ(times.front(), ros::TIME_MIN);
  EXPECT_EQ(times.back(), stampOf(e.duration));

  const auto joint_states = read<sensor_msgs::JointState>(bag, "/joint_states");
  EXPECT_EQ(joint_states.size(), samples);
  for (size_t i = 0; i < joint_states.size() && i < samples; ++i) {
    const sensor_msgs::JointState& js = *joint_states[i].second;
    EXPECT_EQ(joint_states[i].first, times.at(i));
    EXPECT_EQ(js.header.stamp, times.at(i));
    EXPECT_EQ(js.name, e.dofs);
    ASSERT_EQ(js.position.size(), e.dofs.size());
    ASSERT_EQ(js.velocity.size(), e.dofs.size());
    ASSERT_EQ(js.effort.size(), e.dofs.size());
    for (size_t d = 0; d < e.dofs.size(); ++d) {
      expectClose(js.position[d], csv.at(i, e.dofs[d] + ".position"), e.dofs[d] + " position, sample " + std::to_string(i));
      expectClose(js.velocity[d], csv.at(i, e.dofs[d] + ".velocity"), e.dofs[d] + " velocity, sample " + std::to_string(i));
      expectClose(js.effort[d], csv.at(i, e.dofs[d] + ".effort"), e.dofs[d] + " effort, sample " + std::to_string(i));
    }
  }

  const auto tf = read<tf2_msgs::TFMessage>(bag, "/tf");
  EXPECT_EQ(tf.size(), samples);
  for (size_t i = 0; i < tf.size() && i < samples; ++i) {
    EXPECT_EQ(tf[i].first, times.at(i));
    EXPECT_EQ(frames(*tf[i].second, tf[i].first), e.moving) << "sample " << i;
  }
  const auto tf_static = read<tf2_msgs::TFMessage>(bag, "/tf_static");
  if (!e.fixed.empty()) {
    EXPECT_EQ(tf_static.size(), 1u);
    if (!tf_static.empty()) {
      EXPECT_EQ(tf_static[0].first, ros::TIME_MIN);
      EXPECT_EQ(frames(*tf_static[0].second, tf_static[0].first), e.fixed);
    }
    rosbag::View view(bag, rosbag::TopicQuery("/tf_static"));
    for (const rosbag::MessageInstance& m : view) EXPECT_TRUE(m.isLatching());  // played back latched
  }

  const auto violation = read<geometry_msgs::Vector3Stamped>(bag, "/mechanism_sim/constraint_violation");
  EXPECT_EQ(violation.size(), samples);
  for (size_t i = 0; i < violation.size() && i < samples; ++i) {
    const geometry_msgs::Vector3Stamped& v = *violation[i].second;
    EXPECT_EQ(violation[i].first, times.at(i));
    EXPECT_EQ(v.header.stamp, times.at(i));
    EXPECT_EQ(v.header.frame_id, "base");  // the root link, as the node
    expectClose(v.vector.x, csv.at(i, "constraint.position"), "position violation");
    expectClose(v.vector.y, csv.at(i, "constraint.velocity"), "velocity violation");
    EXPECT_EQ(v.vector.z, 0.0);
  }

  const auto reactions = read<mechanism_sim::JointReactions>(bag, "/mechanism_sim/joint_reactions");
  EXPECT_EQ(reactions.size(), samples);
  for (size_t i = 0; i < reactions.size() && i < samples; ++i) {
    const mechanism_sim::JointReactions& jr = *reactions[i].second;
    EXPECT_EQ(reactions[i].first, times.at(i));
    EXPECT_EQ(jr.header.stamp, times.at(i));
    EXPECT_EQ(jr.header.frame_id, "base");  // the node's header: the root link
    EXPECT_EQ(jr.name, e.reaction_joints);
    ASSERT_EQ(jr.wrench.size(), e.reaction_joints.size());
    for (size_t j = 0; j < jr.name.size(); ++j) {
      const geometry_msgs::Wrench& w = jr.wrench[j];
      const std::string& n = jr.name[j];
      expectClose(w.force.x, csv.at(i, n + ".fx"), n + ".fx");
      expectClose(w.force.y, csv.at(i, n + ".fy"), n + ".fy");
      expectClose(w.force.z, csv.at(i, n + ".fz"), n + ".fz");
      expectClose(w.torque.x, csv.at(i, n + ".tx"), n + ".tx");
      expectClose(w.torque.y, csv.at(i, n + ".ty"), n + ".ty");
      expectClose(w.torque.z, csv.at(i, n + ".tz"), n + ".tz");
    }
  }
}

TEST(SimulateBag, SliderCrankHasTheNodesTopicsAtTheCsvSamples) {
  Expected e;
  e.urdf = "slider_crank_driven.urdf";
  e.duration = 1.0;
  e.every = 10;
  e.moving = {{"crank", "base"}, {"rod", "crank"}, {"slider", "base"}};
  e.fixed = {{"flywheel", "crank"}};
  e.dofs = {"crank_joint", "rod_joint", "slider_joint", "wrist_pin"};
  e.reaction_joints = {"crank_joint", "rod_joint", "slider_joint", "wrist_pin"};
  checkBag(e, "slider_crank");
  const std::string path = bagPath("slider_crank");

  // The transforms are the joint positions: the slider slides along x from its origin, the
  // crank turns about -y; the reaction torque about the crank's axis is the drive's torque.
  rosbag::Bag bag(path, rosbag::bagmode::Read);
  const auto tf = read<tf2_msgs::TFMessage>(bag, "/tf");
  const auto js = read<sensor_msgs::JointState>(bag, "/joint_states");
  const auto reactions = read<mechanism_sim::JointReactions>(bag, "/mechanism_sim/joint_reactions");
  ASSERT_EQ(tf.size(), js.size());
  ASSERT_EQ(reactions.size(), js.size());
  double largest_torque = 0;
  for (size_t i = 0; i < tf.size(); ++i) {
    const auto& q = js[i].second->position;
    const geometry_msgs::Transform& slider = transformOf(*tf[i].second, "slider");
    EXPECT_NEAR(slider.translation.x, 0.449428104 + q[2], 1e-9);
    EXPECT_NEAR(slider.translation.z, 0.02, 1e-9);
    const geometry_msgs::Transform& crank = transformOf(*tf[i].second, "crank");
    // (cos q/2, 0, -sin q/2, 0) or its negative (one rotation)
    EXPECT_NEAR(std::abs(crank.rotation.w * std::cos(q[0] / 2) - crank.rotation.y * std::sin(q[0] / 2)), 1.0, 1e-9);
    EXPECT_NEAR(crank.rotation.x, 0, 1e-9);
    EXPECT_NEAR(crank.rotation.z, 0, 1e-9);
    const double about_axis = -reactions[i].second->wrench[0].torque.y;  // axis (0, -1, 0)
    EXPECT_NEAR(about_axis, js[i].second->effort[0], 1e-9 * std::max(1.0, std::abs(about_axis)));
    largest_torque = std::max(largest_torque, std::abs(about_axis));
  }
  EXPECT_GT(largest_torque, 0.1);  // the motor works: the flywheel and slider load it
  const auto tf_static = read<tf2_msgs::TFMessage>(bag, "/tf_static");
  ASSERT_EQ(tf_static.size(), 1u);
  EXPECT_NEAR(transformOf(*tf_static[0].second, "flywheel").translation.y, -0.02, 1e-12);
  EXPECT_EQ(transformOf(*tf_static[0].second, "flywheel").rotation.w, 1.0);
  // The clock covers the run: start 1 ns, end t = 1 s + 1 ns.
  rosbag::View all(bag);
  EXPECT_EQ(all.getBeginTime(), ros::TIME_MIN);
  EXPECT_EQ(all.getEndTime(), ros::Time(1, 1));
}

TEST(SimulateBag, FourBarWithoutFixedJointsHasNoTfStatic) {
  Expected e;
  e.urdf = "four_bar.urdf";
  e.duration = 1.0;
  e.every = 7;  // 1000 steps: a sample every 7, and a last one at the end
  e.moving = {{"crank", "base"}, {"coupler", "crank"}, {"rocker", "coupler"}};  // the loop closes rocker-base
  e.dofs = {"crank_joint", "coupler_joint", "rocker_joint", "loop"};
  e.reaction_joints = {"crank_joint", "coupler_joint", "rocker_joint", "loop"};
  checkBag(e, "four_bar");
}

TEST(SimulateBag, RosbagInfoListsTheTopics) {
  if (access("/usr/bin/rosbag", X_OK) != 0) GTEST_SKIP() << "no /usr/bin/rosbag";
  const std::string bag = ::testing::TempDir() + "/info.bag";
  ASSERT_EQ(simulate(kSource + "/urdf/slider_crank_driven.urdf --duration 0.5 --bag " + bag + " --csv /dev/null --quiet").code, 0);
  // The ROS Python tools need the system python3 and its modules only.
  const Result r = run("env -u PYTHONPATH PATH=/usr/bin:/bin PYTHONNOUSERSITE=1 /usr/bin/rosbag info " + bag);
  ASSERT_EQ(r.code, 0) << r.out;
  for (const char* line : {"/clock ", "/joint_states ", "/tf ", "/tf_static ", "/mechanism_sim/constraint_violation ",
                           "/mechanism_sim/joint_reactions "})
    EXPECT_NE(r.out.find(line), std::string::npos) << line << "\n" << r.out;
  EXPECT_NE(r.out.find("mechanism_sim/JointReactions"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("messages:    256"), std::string::npos) << r.out;  // 5 topics x 51 samples, 1 tf_static
}

TEST(SimulateBag, UnwritableFileIsOneLineAndExitCode1) {
  const Result r = simulate(kSource + "/urdf/four_bar.urdf --duration 0.1 --bag /nonexistent/dir/run.bag --csv /dev/null");
  EXPECT_EQ(r.code, 1);
  EXPECT_EQ(r.out, "simulate: cannot write '/nonexistent/dir/run.bag'\n");
}

TEST(SimulateBag, UsageNamesTheOption) {
  const Result r = simulate("--help");
  EXPECT_EQ(r.code, 0);
  EXPECT_NE(r.out.find("[--bag FILE.bag]"), std::string::npos) << r.out;
}

}  // namespace
