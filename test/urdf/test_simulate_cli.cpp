// The simulate executable as a user runs it: CSV layout, options, exit codes, messages.
#include <gtest/gtest.h>

#include "run_command.h"

#include <sys/wait.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace {

const std::string kSource = MECHANISM_SIM_SOURCE_DIR;

using Result = mechanism_sim::testing_util::CommandResult;  // out: stdout and stderr

Result run(const std::string& args) {
  return mechanism_sim::testing_util::runCommand(std::string(SIMULATE_BIN) + " " + args + " 2>&1");
}

std::vector<std::vector<std::string>> readCsv(const std::string& path) {
  std::ifstream in(path);
  std::vector<std::vector<std::string>> rows;
  std::string line;
  while (std::getline(in, line)) {
    std::vector<std::string> cells;
    std::stringstream ss(line);
    std::string c;
    while (std::getline(ss, c, ',')) cells.push_back(c);
    rows.push_back(cells);
  }
  return rows;
}

TEST(SimulateCli, WritesTheDocumentedCsv) {
  const std::string csv = ::testing::TempDir() + "/cyl.csv";
  const Result r = run(kSource + "/urdf/cylindrical_pendulum.urdf --duration 1 --dt 0.001 --output-every 100 --csv " +
                       csv + " --set sleeve_joint.rotation=0.5 --poses --quiet");
  ASSERT_EQ(r.code, 0) << r.out;
  const auto rows = readCsv(csv);
  ASSERT_EQ(rows.size(), 12u);  // header, t = 0, then every 0.1 s
  const auto& h = rows[0];
  const std::vector<std::string> head = {"time", "sleeve_joint.rotation.position", "sleeve_joint.rotation.velocity",
                                         "sleeve_joint.rotation.effort", "sleeve_joint.translation.position"};
  for (size_t i = 0; i < head.size(); ++i) EXPECT_EQ(h[i], head[i]);
  EXPECT_EQ(h[7], "constraint.position");
  EXPECT_EQ(h[8], "constraint.velocity");
  EXPECT_EQ(h[9], "base.x");  // --poses: links in the world frame
  EXPECT_EQ(h.size(), 9u + 7u * 3u);
  EXPECT_NEAR(std::stod(rows[1][1]), 0.5, 1e-12);  // --set holds at assembly
  EXPECT_NEAR(std::stod(rows.back()[0]), 1.0, 1e-12);
  EXPECT_LE(std::stod(rows.back()[7]), 1e-10);
}

// Every number is written as printf's %.12g writes it (the documented 12 significant
// digits): reading a cell and writing it again with %.12g gives the same text.
TEST(SimulateCli, NumbersHaveTwelveSignificantDigits) {
  const std::string csv = ::testing::TempDir() + "/digits.csv";
  const Result r = run(kSource + "/urdf/cylindrical_pendulum.urdf --duration 0.3 --csv " + csv +
                       " --set sleeve_joint.rotation=0.5 --poses --reactions --quiet");
  ASSERT_EQ(r.code, 0) << r.out;
  const auto rows = readCsv(csv);
  ASSERT_GT(rows.size(), 2u);
  int long_ones = 0;
  for (size_t i = 1; i < rows.size(); ++i) {
    ASSERT_EQ(rows[i].size(), rows[0].size());
    for (const std::string& c : rows[i]) {
      char buf[40];
      std::snprintf(buf, sizeof buf, "%.12g", std::stod(c));
      EXPECT_EQ(c, buf);
      long_ones += c.size() >= 13;
    }
  }
  EXPECT_GT(long_ones, 100);  // (cells with all twelve digits, not only round numbers)
}

TEST(SimulateCli, SummaryReportsStepsViolationAndDependentEquations) {
  const Result r = run(kSource + "/urdf/four_bar.urdf --duration 0.5 --csv " + ::testing::TempDir() + "/fb.csv");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("500 steps"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("real-time factor"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("3 of 20 constraint equations are dependent ('loop' 3)"), std::string::npos) << r.out;
}

TEST(SimulateCli, BadModelIsOneLineAndExitCode1) {
  const Result r = run(kSource + "/test/invalid/negative_mass.urdf");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("negative_mass.urdf:"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("mass is negative"), std::string::npos) << r.out;
  EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1) << r.out;
}

TEST(SimulateCli, BadArgumentsExitCode2) {
  EXPECT_EQ(run("").code, 2);
  EXPECT_EQ(run(kSource + "/urdf/four_bar.urdf --dt -1").code, 2);
  EXPECT_EQ(run(kSource + "/urdf/four_bar.urdf --frobnicate").code, 2);
  EXPECT_EQ(run(kSource + "/urdf/four_bar.urdf --set crank_joint").code, 2);
  const Result r = run(kSource + "/urdf/four_bar.urdf --effort nope=1 --quiet");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("'nope'"), std::string::npos) << r.out;
}

TEST(SimulateCli, EffortDrivesTheJoint) {
  const std::string csv = ::testing::TempDir() + "/jack.csv";
  // A torque of 2 N m on the screw against the 5 kg load (lead 5 mm) raises it faster than
  // the free run does.
  ASSERT_EQ(run(kSource + "/urdf/screw_jack.urdf --duration 0.5 --output-every 500 --quiet --csv " + csv).code, 0);
  ASSERT_EQ(readCsv(csv)[0][1], "screw_joint.position");  // file order
  const double free_run = std::stod(readCsv(csv).back()[1]);
  ASSERT_EQ(run(kSource + "/urdf/screw_jack.urdf --duration 0.5 --output-every 500 --quiet --effort screw_joint=2 --csv " + csv).code, 0);
  const double driven = std::stod(readCsv(csv).back()[1]);
  EXPECT_GT(driven, free_run + 1.0);
}

// --reactions writes each <mechanism_sim:coupling>'s multiplier as <name>.reaction: the
// planetary example's Willis coupling carries the carrier's load 0.05 N m s/rad x 2.5 rad/s
// over Z_sun + Z_ring = 96 teeth.
TEST(SimulateCli, ReactionsIncludeEachCouplingsMultiplier) {
  const std::string csv = ::testing::TempDir() + "/planetary.csv";
  ASSERT_EQ(run(kSource + "/urdf/planetary_gear.urdf --duration 0.2 --output-every 100 --quiet --reactions --csv " + csv).code, 0);
  const auto rows = readCsv(csv);
  const auto& header = rows[0];
  const auto at = std::find(header.begin(), header.end(), "willis.reaction");
  ASSERT_NE(at, header.end());
  EXPECT_EQ(header.back(), "sun_planet2.reaction") << "the couplings in file order, after the joints' reactions";
  EXPECT_NEAR(std::stod(rows.back()[at - header.begin()]), 0.05 * 2.5 / 96, 1e-12);
}

// --formulation: a tree runs in joint coordinates (and moves as in absolute ones), the
// summary says which ran and why; a loop asked in joint coordinates is a one-line error.
TEST(SimulateCli, FormulationIsChosenAndReported) {
  const std::string pendulum = kSource + "/test/urdf/pendulum_point_mass.urdf --duration 1 --output-every 1000 --csv ";
  const std::string a = ::testing::TempDir() + "/pa.csv", j = ::testing::TempDir() + "/pj.csv";
  const Result ra = run(pendulum + a + " --formulation absolute"), rj = run(pendulum + j + " --formulation joint");
  ASSERT_EQ(ra.code, 0) << ra.out;
  ASSERT_EQ(rj.code, 0) << rj.out;
  EXPECT_NE(ra.out.find("formulation: absolute coordinates, as asked"), std::string::npos) << ra.out;
  EXPECT_NE(rj.out.find("formulation: joint coordinates, as asked"), std::string::npos) << rj.out;
  // the default is auto: a tree in joint coordinates
  const Result rd = run(pendulum + j);
  ASSERT_EQ(rd.code, 0) << rd.out;
  EXPECT_NE(rd.out.find("formulation: joint coordinates (auto: a tree"), std::string::npos) << rd.out;
  const auto rows_a = readCsv(a), rows_j = readCsv(j);
  ASSERT_EQ(rows_a.back().size(), rows_j.back().size());
  EXPECT_NEAR(std::stod(rows_a.back()[1]), std::stod(rows_j.back()[1]), 1e-9);  // the angle after 1 s
  const Result auto_loop = run(kSource + "/urdf/four_bar.urdf --duration 0.01 --formulation auto");
  ASSERT_EQ(auto_loop.code, 0) << auto_loop.out;
  EXPECT_NE(auto_loop.out.find("formulation: joint coordinates (auto: joint"), std::string::npos) << auto_loop.out;
  EXPECT_NE(auto_loop.out.find("closes a loop"), std::string::npos) << auto_loop.out;
  const Result joint_loop = run(kSource + "/urdf/four_bar.urdf --duration 0.01 --formulation joint");
  EXPECT_EQ(joint_loop.code, 0) << joint_loop.out;
  EXPECT_NE(joint_loop.out.find("formulation: joint coordinates, as asked"), std::string::npos) << joint_loop.out;
  EXPECT_EQ(run(kSource + "/urdf/four_bar.urdf --formulation sideways").code, 1);
  // massless links between revolutes (a gimbal): auto runs absolute coordinates, joint
  // coordinates asked are refused in one line
  const std::string gimbal = kSource + "/test/urdf/massless_gimbal.urdf";
  const Result auto_gimbal = run(gimbal + " --duration 0.01 --csv /dev/null");
  ASSERT_EQ(auto_gimbal.code, 0) << auto_gimbal.out;
  EXPECT_NE(auto_gimbal.out.find("formulation: absolute coordinates (auto: body 'int1' has neither mass nor inertia"),
            std::string::npos)
      << auto_gimbal.out;
  const Result joint_gimbal = run(gimbal + " --formulation joint");
  EXPECT_EQ(joint_gimbal.code, 1) << joint_gimbal.out;
  EXPECT_NE(joint_gimbal.out.find(gimbal + ": the joint formulation cannot run this mechanism: body 'int1' has neither "
                                           "mass nor inertia between joint 'rx' and joint 'ry'"),
            std::string::npos)
      << joint_gimbal.out;
  EXPECT_NE(joint_gimbal.out.find("(a gimbal lock); use formulation 'absolute'\n"), std::string::npos) << joint_gimbal.out;
}

// A model without mass runs kinematically and says so: the note and the summary's
// formulation; --strict-inertia refuses a non-physical inertia that otherwise runs.
TEST(SimulateCli, KinematicModeAndStrictInertia) {
  const Result r = run(kSource + "/test/urdf/kinematic_four_bar.urdf --duration 0.1 --drive crank_joint=2 --csv /dev/null");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("kinematic_four_bar.urdf: kinematic: no moving body has mass; 0 dofs held, 1 driven, 2 solved "
                       "from the loops and couplers\n"),
            std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("formulation: kinematic, in absolute coordinates"), std::string::npos) << r.out;
  const std::string finger = kSource + "/test/urdf/finger_zero_moments.urdf --duration 0.01 --csv /dev/null";
  const Result loose = run(finger);
  ASSERT_EQ(loose.code, 0) << loose.out;
  EXPECT_NE(loose.out.find("body 'left_finger': its inertia violates the triangle inequality"), std::string::npos) << loose.out;
  const Result strict = run(finger + " --strict-inertia");
  EXPECT_EQ(strict.code, 1) << strict.out;
  EXPECT_NE(strict.out.find("finger_zero_moments.urdf:8: inertia: the rigid body of link 'left_finger'"), std::string::npos)
      << strict.out;
}

// In the saturating mode each actuator's CSV has its drive's lag and whether it is at its
// bound: the winch (urdf/winch.urdf) asked 15 rad/s settles at 10.19, so its lag grows at
// the difference from the start and it stays at its bound; the last row's lag is the
// summary's.
TEST(SimulateCli, SaturatingModeWritesEachActuatorsLag) {
  const std::string csv = ::testing::TempDir() + "/winch.csv";
  const Result r = run(kSource + "/urdf/winch.urdf --duration 3 --dt 0.001 --output-every 500 --actuator-limits --csv " + csv);
  ASSERT_EQ(r.code, 0) << r.out;
  const auto rows = readCsv(csv);
  const auto& head = rows[0];
  ASSERT_GE(head.size(), 2u);
  EXPECT_EQ(head[head.size() - 2], "winch_motor.lag");
  EXPECT_EQ(head.back(), "winch_motor.saturated");
  const double lag = std::stod(rows.back()[head.size() - 2]);
  EXPECT_EQ(rows.back().back(), "1");
  // 15 rad/s asked, 10.19 reached after a short run-up: the lag after 3 s is about 4.8 x 3
  EXPECT_GT(lag, 13.0);
  EXPECT_LT(lag, 14.5);
  std::ostringstream summary;
  summary.precision(4);
  summary << "still behind at the end: " << lag << ")";
  EXPECT_NE(r.out.find(summary.str()), std::string::npos) << r.out;
  // without the mode, no such columns
  const std::string sized = ::testing::TempDir() + "/winch_sized.csv";
  ASSERT_EQ(run(kSource + "/urdf/winch.urdf --duration 0.01 --quiet --csv " + sized).code, 0);
  EXPECT_EQ(readCsv(sized)[0].back(), "winch_motor.motor_power");
}

}  // namespace

// Actuators in the CSV (doc/actuators.md): the motor's columns after constraint.velocity,
// its electrical ones only with a torque_constant. A wheel about the vertical turned at
// 2 rad/s behind 100:1 (no gravity work): the motor at 200 rad/s gives its friction and
// damping, 0.05 + 1e-4 * 200 = 0.07 N m; k_t = 0.05 N m/A, R = 0.8 ohm make i = 1.4 A,
// V = 0.8 * 1.4 + 0.05 * 200 = 11.12 V, P_el = 15.568 W.
TEST(SimulateCli, ActuatorColumnsAndElectricalQuantities) {
  const std::string urdf = ::testing::TempDir() + "/wheel.urdf";
  {
    std::ofstream out(urdf);
    out << "<robot name=\"wheel\" xmlns:mechanism_sim=\"https://mechanism-sim.github.io/urdf-extension\">"
           "<link name=\"base\"/><link name=\"wheel\"><inertial><mass value=\"1\"/><inertia ixx=\"0.01\" iyy=\"0.01\" "
           "izz=\"0.02\" ixy=\"0\" ixz=\"0\" iyz=\"0\"/></inertial></link>"
           "<joint name=\"hinge\" type=\"continuous\"><parent link=\"base\"/><child link=\"wheel\"/><axis xyz=\"0 0 1\"/>"
           "</joint><transmission name=\"gearbox\"><type>transmission_interface/SimpleTransmission</type>"
           "<joint name=\"hinge\"/><actuator name=\"motor\"><mechanicalReduction>100</mechanicalReduction></actuator>"
           "</transmission><mechanism_sim:actuator name=\"motor\" rotor_inertia=\"1e-5\" friction=\"0.05\" "
           "damping=\"1e-4\" torque_constant=\"0.05\" resistance=\"0.8\" peak_torque=\"0.1\"/>"
           "<mechanism_sim:drive joint=\"hinge\" velocity=\"2\"/></robot>";
  }
  const std::string csv = ::testing::TempDir() + "/wheel.csv";
  const Result r = run(urdf + " --duration 0.5 --dt 0.001 --output-every 100 --csv " + csv);
  ASSERT_EQ(r.code, 0) << r.out;
  const auto rows = readCsv(csv);
  const std::vector<std::string> motor = {"motor.motor_position", "motor.motor_velocity", "motor.motor_torque",
                                          "motor.motor_power",    "motor.motor_current",  "motor.motor_voltage",
                                          "motor.electrical_power"};
  ASSERT_EQ(rows[0].size(), 6u + motor.size());
  for (size_t i = 0; i < motor.size(); ++i) EXPECT_EQ(rows[0][6 + i], motor[i]);
  const std::vector<double> expected = {100 * 2 * 0.5, 200, 0.07, 14, 1.4, 11.12, 15.568};
  for (size_t i = 0; i < expected.size(); ++i)
    EXPECT_NEAR(std::stod(rows.back()[6 + i]), expected[i], 1e-9 * expected[i]) << motor[i];
  EXPECT_NE(r.out.find("actuator 'motor': peak torque 0.07 N m"), std::string::npos) << r.out;
  // (copper energy: 0.784 J less the first interval's, where the motor gives the damping's
  // 0.02 N m alone, the friction acting from the first step on: 0.7833 J)
  EXPECT_NE(r.out.find("peak current 1.4 A, peak voltage 11.12 V, peak electrical power 15.57 W, copper energy 0.7833 J; "
                       "within rating (peak_torque 0.1 N m)"),
            std::string::npos)
      << r.out;
  // the example has no torque_constant: its motor has the mechanical columns only
  const std::string plain = ::testing::TempDir() + "/harmonic.csv";
  ASSERT_EQ(run(kSource + "/urdf/harmonic_drive_joint.urdf --duration 0.01 --quiet --csv " + plain).code, 0);
  const auto head = readCsv(plain)[0];
  EXPECT_EQ(head.back(), "shoulder_motor.motor_power");
}
