// simulate --trajectory (doc/trajectories.md): a pendulum run with a constant effort of
// 0.5 N m is recorded with --csv and fed back to the same pendulum, free, with
// --trajectory: it must move as recorded, and its drive must supply what the record's
// effort did, 0.5 N m, which is also the inverse dynamics I q'' + m g l sin q of the
// replayed motion (q'' by central differences of its velocities). Bad files: exit code 2
// and the reason, never a crash.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "run_command.h"

namespace {

const std::string kModel = std::string(MECHANISM_SIM_SOURCE_DIR) + "/test/urdf/pendulum_trajectory.urdf";
constexpr double kI = 0.52, kMgl = 2 * 9.81 * 0.5;  // the file's inertia about the pivot, m g l

mechanism_sim::testing_util::CommandResult simulate(const std::string& args) {
  return mechanism_sim::testing_util::runCommand(std::string(SIMULATE_BIN) + " " + args + " 2>&1");
}

std::string tmp(const std::string& name) { return ::testing::TempDir() + "trajectory_cli_" + name; }

// CSV columns by name.
std::map<std::string, std::vector<double>> readCsv(const std::string& path) {
  std::ifstream in(path);
  std::string line, cell;
  std::getline(in, line);
  std::vector<std::string> names;
  std::istringstream h(line);
  while (std::getline(h, cell, ',')) names.push_back(cell);
  std::map<std::string, std::vector<double>> cols;
  while (std::getline(in, line)) {
    std::istringstream r(line);
    for (size_t c = 0; std::getline(r, cell, ','); ++c) cols[names.at(c)].push_back(std::stod(cell));
  }
  return cols;
}

void write(const std::string& path, const std::string& text) { std::ofstream(path) << text; }

TEST(TrajectoryCli, ARecordedRunDrivesTheFreePendulumWithTheEffortOfItsInverseDynamics) {
  const std::string rec = tmp("record.csv"), rep = tmp("replay.csv");
  const std::string run = kModel + " --set pivot=1.0 --duration 2 --output-every 1 --quiet";
  ASSERT_EQ(simulate(run + " --effort pivot=0.5 --csv " + rec).code, 0);
  const auto r = simulate(run + " --trajectory " + rec + " --csv " + rep);
  ASSERT_EQ(r.code, 0) << r.out;
  const auto a = readCsv(rec), b = readCsv(rep);
  const std::vector<double> &t = b.at("time"), &q = b.at("pivot.position"), &v = b.at("pivot.velocity"),
                            &tau = b.at("pivot.effort");
  ASSERT_EQ(t.size(), 2001u);
  double worst_q = 0, worst_known = 0, worst_id = 0;
  for (size_t i = 0; i < t.size(); ++i) worst_q = std::max(worst_q, std::fabs(q[i] - a.at("pivot.position")[i]));
  // away from the first and last 10 ms: the path leaves the free pendulum's acceleration at
  // t = 0 and comes to acceleration 0 at the last point (doc/trajectories.md)
  for (size_t i = 10; i + 10 < t.size(); ++i) {
    const double q_ddot = (v[i + 1] - v[i - 1]) / (t[i + 1] - t[i - 1]);
    worst_known = std::max(worst_known, std::fabs(tau[i] - 0.5));
    worst_id = std::max(worst_id, std::fabs(tau[i] - (kI * q_ddot + kMgl * std::sin(q[i]))));
  }
  std::printf("replayed record: |q - q_record| %.2e rad, |tau - 0.5| %.2e N m, |tau - inverse dynamics| %.2e N m\n",
              worst_q, worst_known, worst_id);
  EXPECT_LT(worst_q, 1e-9);
  EXPECT_LT(worst_known, 1e-4);
  EXPECT_LT(worst_id, 1e-4);
}

TEST(TrajectoryCli, BadFilesAreRejectedWithTheReasonAndExitCode2) {
  const std::string good = "time,pivot.position,pivot.velocity\n0,0,0\n0.1,0.1,0\n0.2,0.2,0\n";
  struct Case {
    std::string name, text, args, reason;
  };
  const std::vector<Case> cases = {
      {"repeat.csv", "time,pivot.position\n0,0\n0.1,0.1\n0.1,0.2\n", "", "times must increase"},
      {"back.csv", "time,pivot.position\n0,0\n0.2,0.1\n0.1,0.2\n", "", "times must increase"},
      {"nan.csv", "time,pivot.position\n0,0\n0.1,nan\n", "", "'pivot.position' is not finite"},
      {"word.csv", "time,pivot.position\n0,0\n0.1,abc\n", "", "'abc' is not a number"},
      {"short.csv", "time,pivot.position\n0,0\n0.1\n", "", "1 values for 2 columns"},
      {"unknown.csv", "time,pivot.position,elbow.position\n0,0,0\n0.1,0.1,0\n", "", "unknown joint 'elbow'"},
      {"notime.csv", "t,pivot.position\n0,0\n", "", "no 'time' column"},
      {"header.csv", "time,pivot.position\n", "", "no point"},
      {"empty.csv", "", "", "empty file"},
      {"past.csv", "time,pivot.position\n0,0\n", "", "not after the current time"},
      {"far.csv", good, "--set pivot=0.5", "is 0.5 from its position 0.5"},
      {"far_tolerance.csv", good, "--set pivot=0.05 --trajectory-start-tolerance 0.01", "start tolerance 0.01"},
  };
  for (const Case& c : cases) {
    write(tmp(c.name), c.text);
    const auto r = simulate(kModel + " --duration 0.3 --quiet --trajectory " + tmp(c.name) + " " + c.args);
    EXPECT_EQ(r.code, 2) << c.name << ": " << r.out;
    EXPECT_NE(r.out.find("trajectory rejected"), std::string::npos) << c.name << ": " << r.out;
    EXPECT_NE(r.out.find(c.reason), std::string::npos) << c.name << ": " << r.out;
  }
  // the follower of a <mimic> is moved by its leader
  write(tmp("mimic.csv"), "time,right_joint.position\n0,0.1\n0.5,0.2\n");
  auto r = simulate(std::string(MECHANISM_SIM_SOURCE_DIR) + "/test/urdf/mimic.urdf --duration 0.1 --quiet --trajectory " +
                    tmp("mimic.csv"));
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_NE(r.out.find("'right_joint' is coupled"), std::string::npos) << r.out;
  r = simulate(kModel + " --quiet --trajectory " + tmp("does_not_exist.csv"));
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_NE(r.out.find("cannot be read"), std::string::npos) << r.out;
  // and a good one runs: the pendulum lifted to 0.2 rad, held there by m g l sin 0.2
  write(tmp("good.csv"), good);
  r = simulate(kModel + " --duration 0.5 --output-every 500 --trajectory " + tmp("good.csv") + " --csv " + tmp("good_out.csv"));
  ASSERT_EQ(r.code, 0) << r.out;
  const auto out = readCsv(tmp("good_out.csv"));
  EXPECT_NEAR(out.at("pivot.position").back(), 0.2, 1e-9);
  EXPECT_NEAR(out.at("pivot.effort").back(), kMgl * std::sin(0.2), 1e-6);
}

}  // namespace
