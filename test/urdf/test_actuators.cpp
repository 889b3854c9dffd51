// Transmissions and actuators as the loader reads them (doc/actuators.md): ros_control's and
// the PR2 form, the rotor inertia reflected into the dynamics, the motor's torque and speed
// from ros_control's maps, sizing against ratings, and one-line errors for bad input.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <string>

#include <Eigen/Dense>

#include "mechanism_sim/urdf/model.h"
#include "mechanism_sim/urdf/run_loop.h"

namespace mechanism_sim {
namespace {

const std::string kSource = MECHANISM_SIM_SOURCE_DIR;
constexpr double kG = 9.81;

// A pendulum (mass m at L along x from a hinge about y; gravity makes q grow from the
// horizontal) behind a transmission given as XML, with extra elements.
std::string pendulum(const std::string& extra, double m = 2.0, double L = 0.5, double Iyy = 1e-3) {
  char inertial[256];
  std::snprintf(inertial, sizeof inertial,
                "<inertial><origin xyz=\"%.17g 0 0\"/><mass value=\"%.17g\"/><inertia ixx=\"%.17g\" iyy=\"%.17g\" "
                "izz=\"%.17g\" ixy=\"0\" ixz=\"0\" iyz=\"0\"/></inertial>",
                L, m, Iyy, Iyy, Iyy);
  return std::string("<robot name=\"geared\" xmlns:mechanism_sim=\"https://mechanism-sim.github.io/urdf-extension\">"
                     "<link name=\"base\"/><link name=\"arm\">") +
         inertial +
         "</link><joint name=\"hinge\" type=\"continuous\"><parent link=\"base\"/><child link=\"arm\"/>"
         "<axis xyz=\"0 1 0\"/></joint>" +
         extra + "</robot>";
}

// Two discs about the vertical, a at the origin and b 0.3 m away, behind a differential
// (E = [20 40; 30 -60]), with extra elements (actuators, initial values).
std::string differentialDiscs(const std::string& extra) {
  return std::string(
           "<robot name=\"diff\" xmlns:mechanism_sim=\"https://mechanism-sim.github.io/urdf-extension\"><link name=\"base\"/>"
           "<link name=\"a\"><inertial><mass value=\"1\"/><inertia ixx=\"0.01\" iyy=\"0.01\" izz=\"0.02\" "
           "ixy=\"0\" ixz=\"0\" iyz=\"0\"/></inertial></link>"
           "<link name=\"b\"><inertial><mass value=\"1.2\"/><inertia ixx=\"0.015\" iyy=\"0.015\" izz=\"0.03\" "
           "ixy=\"0\" ixz=\"0\" iyz=\"0\"/></inertial></link>"
           "<joint name=\"ja\" type=\"continuous\"><parent link=\"base\"/><child link=\"a\"/><axis xyz=\"0 0 1\"/></joint>"
           "<joint name=\"jb\" type=\"continuous\"><parent link=\"base\"/><child link=\"b\"/><origin xyz=\"0.3 0 0\"/>"
           "<axis xyz=\"0 0 1\"/></joint>"
           "<transmission name=\"wrist\"><type>transmission_interface/DifferentialTransmission</type>"
           "<actuator name=\"m1\"><role>actuator1</role><mechanicalReduction>20</mechanicalReduction></actuator>"
           "<actuator name=\"m2\"><role>actuator2</role><mechanicalReduction>30</mechanicalReduction></actuator>"
           "<joint name=\"ja\"><role>joint1</role><mechanicalReduction>1</mechanicalReduction></joint>"
           "<joint name=\"jb\"><role>joint2</role><mechanicalReduction>2</mechanicalReduction></joint></transmission>") +
         extra + "</robot>";
}

const char* kSimple =
    "<transmission name=\"gearbox\"><type>transmission_interface/SimpleTransmission</type>"
    "<joint name=\"hinge\"><hardwareInterface>hardware_interface/EffortJointInterface</hardwareInterface></joint>"
    "<actuator name=\"motor\"><mechanicalReduction>100</mechanicalReduction></actuator></transmission>";

std::string loadError(const std::string& xml, const LoadOptions& options = {}) {
  try {
    loadModelString(xml, "t.urdf", options);
  } catch (const LoadError& e) {
    return e.what();
  }
  return "(loaded)";
}

// At rest at the horizontal: q_ddot = m g L / (m L^2 + Iyy + N^2 J), in both formulations.
TEST(Actuators, RotorInertiaReflectedThroughTheGearbox) {
  const double m = 2.0, L = 0.5, Iyy = 1e-3, N = 100, J = 4e-5;
  const std::string xml = pendulum(std::string(kSimple) + "<mechanism_sim:actuator name=\"motor\" rotor_inertia=\"4e-5\"/>");
  for (const char* f : {"absolute", "joint"}) {
    LoadOptions o;
    o.formulation = f;
    auto model = loadModelString(xml, "geared.urdf", o);
    ASSERT_EQ(model->actuators().size(), 1u);
    EXPECT_EQ(model->actuators()[0].name, "motor");
    EXPECT_DOUBLE_EQ(model->actuators()[0].ratings.rotor_inertia, J);
    const double expected = m * kG * L / (m * L * L + Iyy + N * N * J);
    EXPECT_NEAR(model->acceleration(0), expected, 1e-10 * expected) << f;
    for (const std::string& note : model->notes()) EXPECT_EQ(note.find("transmission"), std::string::npos) << note;
  }
}

// Driven q = A sin(w t): the drive's effort is (I + N^2 J) q_ddot - m g L cos q; the motor
// turns N times as fast with 1/N of the torque (ros_control's SimpleTransmission), the
// rotor's J theta_ddot included.
TEST(Actuators, MotorTorqueAndSpeedThroughTheGearbox) {
  const double m = 2.0, L = 0.5, Iyy = 1e-3, N = 100, J = 4e-5, A = 0.5, f = 0.8, w = 2 * M_PI * f;
  const std::string drive = "<mechanism_sim:drive joint=\"hinge\" profile=\"harmonic\" offset=\"0\" amplitude=\"0.5\" "
                            "frequency=\"0.8\" phase=\"0\"/>";
  const std::string xml = pendulum(std::string(kSimple) + "<mechanism_sim:actuator name=\"motor\" rotor_inertia=\"4e-5\"/>" + drive);
  for (const char* formulation : {"absolute", "joint"}) {
    LoadOptions o;
    o.formulation = formulation;
    auto model = loadModelString(xml, "geared.urdf", o);
    for (int k = 0; k < 300; ++k) {
      model->step(1e-3);
      if (k % 50 != 49) continue;
      const double t = model->time(), q = A * std::sin(w * t), qd = A * w * std::cos(w * t), qdd = -A * w * w * std::sin(w * t);
      const double effort = (m * L * L + Iyy + N * N * J) * qdd - m * kG * L * std::cos(q);
      const double scale = (m * L * L + Iyy + N * N * J) * A * w * w + m * kG * L;
      EXPECT_NEAR(model->effort(0), effort, 1e-8 * scale) << formulation << " t = " << t;
      const ActuatorState s = model->actuatorState(0);
      EXPECT_NEAR(s.velocity, N * qd, 1e-9 * N * A * w) << formulation;
      EXPECT_NEAR(s.position, N * q, 1e-9 * N * A) << formulation;
      EXPECT_NEAR(s.torque, effort / N, 1e-8 * scale / N) << formulation;
      EXPECT_NEAR(s.power, s.torque * s.velocity, 1e-12 * scale * A * w);
      // the hinge turns the arm alone: (m L^2 + Iyy) q_ddot - m g L cos q about its axis
      const std::vector<JointReaction> r = model->jointReactions();
      EXPECT_NEAR(r[0].torque.y(), (m * L * L + Iyy) * qdd - m * kG * L * std::cos(q), 1e-8 * scale) << formulation;
    }
  }
}

// The PR2 form: <mechanicalReduction> in the transmission, the type an attribute.
TEST(Actuators, Pr2FormAndIgnoredTypes) {
  const std::string xml = pendulum(
      "<transmission name=\"t\" type=\"pr2_mechanism_model/SimpleTransmission\"><actuator name=\"motor\"/>"
      "<joint name=\"hinge\"/><mechanicalReduction>25</mechanicalReduction></transmission>"
      "<transmission name=\"hand\"><type>sr_mechanism_model/SimpleTransmission</type>"
      "<actuator name=\"x\"/><joint name=\"hinge\"/></transmission>");
  auto model = loadModelString(xml, "pr2.urdf");
  ASSERT_EQ(model->transmissions().size(), 1u);
  EXPECT_EQ(model->transmissions()[0].map.actuator_reduction[0], 25.0);
  bool listed = false;
  for (const std::string& note : model->notes())
    listed = listed || note.find("1 <transmission> of type sr_mechanism_model/SimpleTransmission") != std::string::npos;
  EXPECT_TRUE(listed);
  // the same transmission once per hardware interface (franka_ros) is one transmission; a
  // different one on the same actuator contradicts it
  auto twice = [](const std::string& reduction) {
    return std::string(kSimple) + "<transmission name=\"gearbox\"><type>transmission_interface/SimpleTransmission</type>"
           "<joint name=\"hinge\"><hardwareInterface>hardware_interface/VelocityJointInterface</hardwareInterface></joint>"
           "<actuator name=\"motor\"><mechanicalReduction>" + reduction + "</mechanicalReduction></actuator></transmission>";
  };
  auto franka = loadModelString(pendulum(twice("100")), "franka.urdf");
  EXPECT_EQ(franka->transmissions().size(), 1u);
  EXPECT_EQ(loadError(pendulum(twice("50"))),
            "t.urdf:1: transmission 'gearbox': actuator 'motor' is in another transmission already");
}

// Two pendulums hinged on the ground behind one differential (ros_control's roles and
// reductions): the coupled reflected inertia E^T diag(J) E in the first accelerations; the
// motors' speeds from ros_control's jointToActuatorVelocity.
TEST(Actuators, DifferentialCouplesTheJoints) {
  const std::string xml =
      "<robot name=\"diff\" xmlns:mechanism_sim=\"https://mechanism-sim.github.io/urdf-extension\"><link name=\"base\"/>"
      "<link name=\"a\"><inertial><origin xyz=\"0.5 0 0\"/><mass value=\"1\"/><inertia ixx=\"1e-3\" iyy=\"1e-3\" izz=\"1e-3\" "
      "ixy=\"0\" ixz=\"0\" iyz=\"0\"/></inertial></link>"
      "<link name=\"b\"><inertial><origin xyz=\"0.3 0 0\"/><mass value=\"1.5\"/><inertia ixx=\"2e-3\" iyy=\"2e-3\" izz=\"2e-3\" "
      "ixy=\"0\" ixz=\"0\" iyz=\"0\"/></inertial></link>"
      "<joint name=\"ja\" type=\"continuous\"><parent link=\"base\"/><child link=\"a\"/><axis xyz=\"0 1 0\"/></joint>"
      "<joint name=\"jb\" type=\"continuous\"><parent link=\"base\"/><child link=\"b\"/><origin xyz=\"0 1 0\"/>"
      "<axis xyz=\"0 1 0\"/></joint>"
      "<transmission name=\"wrist\"><type>transmission_interface/DifferentialTransmission</type>"
      "<actuator name=\"m1\"><role>actuator1</role><mechanicalReduction>20</mechanicalReduction></actuator>"
      "<actuator name=\"m2\"><role>actuator2</role><mechanicalReduction>30</mechanicalReduction></actuator>"
      "<joint name=\"ja\"><role>joint1</role><offset>0.1</offset><mechanicalReduction>1</mechanicalReduction></joint>"
      "<joint name=\"jb\"><role>joint2</role><mechanicalReduction>2</mechanicalReduction></joint></transmission>"
      "<mechanism_sim:actuator name=\"m1\" rotor_inertia=\"1e-4\"/><mechanism_sim:actuator name=\"m2\" rotor_inertia=\"2e-4\"/>"
      "<mechanism_sim:initial joint=\"ja\" velocity=\"1.5\"/><mechanism_sim:initial joint=\"jb\" velocity=\"-2\"/>"
      "</robot>";
  EXPECT_STREQ(loadModelString(xml, "diff.urdf")->mechanism().formulation(), "joint");  // (auto: the coupled rotors too)
  for (const char* formulation : {"absolute", "joint"}) {
    SCOPED_TRACE(formulation);
    LoadOptions o;
    o.formulation = formulation;
    auto model = loadModelString(xml, "diff.urdf", o);
    Eigen::Matrix2d E;
    E << 20 * 1, 20 * 2, 30 * 1, -30 * 2;
    const Eigen::Matrix2d B = E.transpose() * Eigen::Vector2d(1e-4, 2e-4).asDiagonal() * E;
    Eigen::Matrix2d M = Eigen::Matrix2d::Zero();
    M(0, 0) = 1 * 0.25 + 1e-3, M(1, 1) = 1.5 * 0.09 + 2e-3;
    const Eigen::Vector2d qd(1.5, -2.0);
    EXPECT_NEAR(model->kineticEnergy(), 0.5 * qd.dot((M + B) * qd), 1e-10 * qd.dot((M + B) * qd));
    // gravity's torques m g x_c at the horizontal, through the coupled inertia
    const Eigen::Vector2d qdd = (M + B).ldlt().solve(Eigen::Vector2d(1 * kG * 0.5, 1.5 * kG * 0.3));
    for (int i = 0; i < 2; ++i) EXPECT_NEAR(model->acceleration(i), qdd[i], 1e-10 * qdd.norm()) << i;
    const ActuatorState s1 = model->actuatorState(0), s2 = model->actuatorState(1);
    EXPECT_NEAR(s1.velocity, (qd[0] * 1 + qd[1] * 2) * 20, 1e-9);
    EXPECT_NEAR(s2.velocity, (qd[0] * 1 - qd[1] * 2) * 30, 1e-9);
    EXPECT_NEAR(s1.position, ((0.0 - 0.1) * 1 + 0.0 * 2) * 20, 1e-9);  // joint1's offset
  }
}

// The example: within its ratings as written; driven twice as fast the motor's top speed,
// its continuous rating and its torque-speed line are exceeded (not its peak torque), and the
// summary says when and by how much.
TEST(Actuators, HarmonicDriveExampleSizing) {
  auto model = loadModelFile(kSource + "/urdf/harmonic_drive_joint.urdf");
  {
    RunLoop loop(*model, 1e-3, 100);
    const double E0 = model->kineticEnergy() + model->potentialEnergy();
    while (loop.steps() < 2300) loop.advance();
    const double E1 = model->kineticEnergy() + model->potentialEnergy();
    ASSERT_EQ(loop.actuatorSizing().size(), 1u);
    const ActuatorSizing& a = loop.actuatorSizing()[0];
    EXPECT_TRUE(a.withinRating()) << a.describe();
    EXPECT_NE(a.describe().find("within rating"), std::string::npos) << a.describe();
    EXPECT_NEAR(a.peakSpeed(), 100 * 0.8 * 2 * M_PI, 1e-6 * 500);
    // the motor's work is the change of energy, the rotor's included (no damping here);
    // the trapezoidal rule's error at 1 ms is O(h^2)
    ASSERT_GT(std::fabs(E1 - E0), 1.0);
    EXPECT_NEAR(a.positiveWork() + a.negativeWork(), E1 - E0, 1e-4 * a.positiveWork());
  }
  std::ifstream in(kSource + "/urdf/harmonic_drive_joint.urdf");
  std::string xml((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  xml.replace(xml.find("frequency=\"1\""), 13, "frequency=\"2\"");
  auto fast = loadModelString(xml, "fast.urdf");
  RunLoop loop(*fast, 1e-3, 100);
  while (loop.steps() < 1000) loop.advance();
  const ActuatorSizing& a = loop.actuatorSizing()[0];
  EXPECT_FALSE(a.withinRating());
  const std::string d = a.describe();
  EXPECT_EQ(d.find("peak_torque"), std::string::npos) << d;
  EXPECT_NE(d.find("EXCEEDS max_speed 600 rad/s from t = 0 s: worst 1005"), std::string::npos) << d;
  EXPECT_NE(d.find("EXCEEDS rated_torque 0.3 N m"), std::string::npos) << d;
  EXPECT_NE(d.find("EXCEEDS the torque-speed line"), std::string::npos) << d;
}

// The winch example (doc/actuators.md, "Saturating mode"): 10 kg on a drum of radius 0.05 m
// behind 20:1, the motor's line 0.5 N m / 400 rad/s. Saturating, the drum settles where the
// line meets the load: 0.5 (1 - 20 w / 400) = m g r / 20, in both formulations, the line
// never exceeded; sizing, the drive turns the drum at its 15 rad/s and the summary names the
// line.
TEST(Actuators, WinchSettlesWhereTheMotorsLineMeetsTheLoad) {
  const double m = 10.0, r = 0.05, N = 20.0, T_s = 0.5, w0 = 400.0;
  const double settled = w0 / N * (1.0 - m * kG * r / N / T_s);
  for (const char* f : {"absolute", "joint", "auto"}) {
    LoadOptions o;
    o.formulation = f;
    o.actuator_limits = true;
    auto model = loadModelFile(kSource + "/urdf/winch.urdf", o);
    EXPECT_TRUE(model->actuatorLimits());
    RunLoop loop(*model, 1e-3, 100);
    double worst = 0.0;
    while (loop.steps() < 3000) {
      loop.advance(1);
      const ActuatorState s = model->actuatorState(0);
      const double line = T_s * std::max(0.0, 1.0 - std::fabs(s.velocity) / w0);
      worst = std::max(worst, (s.torque - line) / T_s);
    }
    const int drum = model->dofIndex("drum_joint");
    EXPECT_NEAR(model->velocity(drum), settled, 1e-9 * settled) << f;
    EXPECT_NEAR(model->velocity(model->dofIndex("rope")), r * settled, 1e-9 * settled) << f;
    EXPECT_NEAR(model->actuatorState(0).torque, m * kG * r / N, 1e-9 * T_s) << f;
    EXPECT_LT(worst, 1e-10) << f;
    EXPECT_TRUE(model->actuatorState(0).saturated);
    const ActuatorSizing& a = loop.actuatorSizing()[0];
    EXPECT_TRUE(a.saturating());
    EXPECT_TRUE(a.withinRating()) << a.describe();
    EXPECT_EQ(a.boundIntervals(), 1) << a.describe();
    EXPECT_GT(a.largestLag(), 10.0);
    EXPECT_EQ(a.largestLagEnded(), -1.0);
    EXPECT_NE(a.describe().find("at its bounds 1 time, "), std::string::npos) << a.describe();
    EXPECT_NE(a.describe().find("still behind at the end"), std::string::npos) << a.describe();
  }
  auto sized = loadModelFile(kSource + "/urdf/winch.urdf");
  EXPECT_FALSE(sized->actuatorLimits());
  RunLoop loop(*sized, 1e-3, 100);
  while (loop.steps() < 1000) loop.advance();
  EXPECT_NEAR(sized->velocity(sized->dofIndex("drum_joint")), 15.0, 1e-9);
  const ActuatorSizing& a = loop.actuatorSizing()[0];
  EXPECT_FALSE(a.saturating());
  EXPECT_NE(a.describe().find("EXCEEDS the torque-speed line (stall 0.5 N m, no-load 400 rad/s)"), std::string::npos)
      << a.describe();
  EXPECT_EQ(a.describe().find("at its bounds"), std::string::npos) << a.describe();
}

// A differential's actuators are bounded like a simple transmission's (no note), each with its
// rows of E, E^-T and E^-1; a model whose actuators have no torque bound is told that
// nothing is bounded.
TEST(Actuators, SaturatingModeBoundsADifferentialsActuators) {
  const std::string xml =
      "<robot name=\"diff\" xmlns:mechanism_sim=\"https://mechanism-sim.github.io/urdf-extension\"><link name=\"base\"/>"
      "<link name=\"a\"><inertial><mass value=\"1\"/><inertia ixx=\"1e-3\" iyy=\"1e-3\" izz=\"1e-3\" "
      "ixy=\"0\" ixz=\"0\" iyz=\"0\"/></inertial></link>"
      "<link name=\"b\"><inertial><mass value=\"1\"/><inertia ixx=\"1e-3\" iyy=\"1e-3\" izz=\"1e-3\" "
      "ixy=\"0\" ixz=\"0\" iyz=\"0\"/></inertial></link>"
      "<joint name=\"ja\" type=\"continuous\"><parent link=\"base\"/><child link=\"a\"/><axis xyz=\"0 1 0\"/></joint>"
      "<joint name=\"jb\" type=\"continuous\"><parent link=\"base\"/><child link=\"b\"/><origin xyz=\"0 1 0\"/>"
      "<axis xyz=\"0 1 0\"/></joint>"
      "<transmission name=\"wrist\"><type>transmission_interface/DifferentialTransmission</type>"
      "<actuator name=\"m1\"><role>actuator1</role><mechanicalReduction>20</mechanicalReduction></actuator>"
      "<actuator name=\"m2\"><role>actuator2</role><mechanicalReduction>30</mechanicalReduction></actuator>"
      "<joint name=\"ja\"><role>joint1</role></joint><joint name=\"jb\"><role>joint2</role></joint></transmission>"
      "<mechanism_sim:actuator name=\"m1\" peak_torque=\"1\"/></robot>";
  LoadOptions o;
  o.actuator_limits = true;
  auto model = loadModelString(xml, "diff.urdf", o);
  for (const std::string& n : model->notes()) EXPECT_EQ(n.find("actuator limits"), std::string::npos) << n;
  ASSERT_EQ(model->mechanism().actuatorLimits().size(), 1u);
  const ActuatorLimit& L = model->mechanism().actuatorLimits()[0];
  EXPECT_EQ(L.name, "m1");
  ASSERT_EQ(L.coords.size(), 2u);
  // E = [20 20; 30 -30]: m1's row (20, 20), E^-T's row (1/40, 1/40), E^-1's column (1/40, 1/40)
  EXPECT_EQ(L.coords[0].speed, 20.0);
  EXPECT_EQ(L.coords[1].speed, 20.0);
  EXPECT_NEAR(L.coords[0].torque, 1.0 / 40, 1e-15);
  EXPECT_NEAR(L.coords[1].torque, 1.0 / 40, 1e-15);
  EXPECT_NEAR(L.coords[0].lag, 1.0 / 40, 1e-15);
  EXPECT_NEAR(L.coords[1].lag, 1.0 / 40, 1e-15);
  EXPECT_EQ(model->setActuatorLimits(false), "");
  EXPECT_FALSE(model->actuatorLimits());
  auto plain = loadModelString(pendulum(kSimple), "plain.urdf", o);
  EXPECT_EQ(plain->notes().back(), "actuator limits: no actuator has a peak_torque or a torque-speed line: nothing is bounded");
}

// A wheel about the vertical (gravity does no work) turned at a constant 2 rad/s by a
// velocity drive behind a 100:1 gearbox: the motor turns at 200 rad/s and gives only what its
// own friction and damping take from the motion (the drive's effort through the gearbox),
// 0.05 + 1e-4 * 200 = 0.07 N m. With k_t = 0.05 N m/A and R = 0.8 ohm:
// i = 0.07 / 0.05 = 1.4 A, V = 0.8 * 1.4 + 0.05 * 200 = 11.12 V, P_el = V i = 15.568 W, of
// which R i^2 = 1.568 W is copper loss and tau omega = 14 W mechanical.
std::string electricWheel() {
  return "<robot name=\"wheel\" xmlns:mechanism_sim=\"https://mechanism-sim.github.io/urdf-extension\">"
         "<link name=\"base\"/><link name=\"wheel\"><inertial><mass value=\"1\"/><inertia ixx=\"0.01\" iyy=\"0.01\" "
         "izz=\"0.02\" ixy=\"0\" ixz=\"0\" iyz=\"0\"/></inertial></link>"
         "<joint name=\"hinge\" type=\"continuous\"><parent link=\"base\"/><child link=\"wheel\"/><axis xyz=\"0 0 1\"/>"
         "</joint>" +
         std::string(kSimple) +
         "<mechanism_sim:actuator name=\"motor\" rotor_inertia=\"1e-5\" friction=\"0.05\" damping=\"1e-4\" "
         "torque_constant=\"0.05\" resistance=\"0.8\"/>"
         "<mechanism_sim:drive joint=\"hinge\" velocity=\"2\"/></robot>";
}

TEST(Actuators, ElectricalQuantitiesAtAKnownTorqueAndSpeed) {
  auto model = loadModelString(electricWheel(), "wheel.urdf");
  RunLoop loop(*model, 1e-3, 100);
  while (loop.steps() < 1000) loop.advance();
  const ActuatorState s = model->actuatorState(0);
  EXPECT_NEAR(s.velocity, 200.0, 1e-9 * 200);
  EXPECT_NEAR(s.torque, 0.07, 1e-9 * 0.07);
  EXPECT_NEAR(s.current, 1.4, 1e-9 * 1.4);
  EXPECT_NEAR(s.voltage, 11.12, 1e-9 * 11.12);
  EXPECT_NEAR(s.electrical_power, 15.568, 1e-9 * 15.568);
  const ActuatorSizing& a = loop.actuatorSizing()[0];
  ASSERT_TRUE(a.electricalGiven());
  EXPECT_NEAR(a.peakCurrent(), 1.4, 1e-9 * 1.4);
  EXPECT_NEAR(a.peakVoltage(), 11.12, 1e-9 * 11.12);
  EXPECT_NEAR(a.peakElectricalPower(), 15.568, 1e-9 * 15.568);
  // R i^2 over the run's 1 s, less over its first interval: at t = 0 no step has been taken
  // and the friction, which acts from the first step on, is not yet in the drive's effort
  // (the motor gives the damping's 0.02 N m there, i = 0.4 A)
  const double first = 0.5e-3 * (1.568 - 0.8 * 0.4 * 0.4);
  EXPECT_NEAR(a.copperEnergy(), 1.568 * 1.0 - first, 1e-9 * 1.568);
  EXPECT_NE(a.describe().find(", peak current 1.4 A, peak voltage 11.12 V, peak electrical power 15.57 W, copper energy "
                              "1.567 J"),
            std::string::npos)
      << a.describe();
  // without a torque_constant nothing electrical is reported; a resistance alone is refused
  auto plain = loadModelString(pendulum(kSimple), "t.urdf");
  EXPECT_FALSE(electricalGiven(plain->actuators()[0].ratings));
  EXPECT_EQ(plain->actuatorState(0).current, 0.0);
  RunLoop plain_loop(*plain, 1e-3, 10);
  EXPECT_EQ(plain_loop.actuatorSizing()[0].describe().find("current"), std::string::npos);
  EXPECT_EQ(loadError(pendulum(std::string(kSimple) + "<mechanism_sim:actuator name=\"motor\" resistance=\"0.8\"/>")),
            "t.urdf:1: mechanism_sim:actuator 'motor': resistance needs torque_constant (the current follows from it)");
}

// The harmonic-drive example with a motor's k_t and R: at every step the electrical power
// is the mechanical power plus the copper loss, P_el = tau omega + R i^2 (the back-EMF
// k_e = k_t in SI), while the torque and speed swing through motoring and braking.
TEST(Actuators, ElectricalPowerIsMechanicalPowerPlusCopperLoss) {
  std::ifstream in(kSource + "/urdf/harmonic_drive_joint.urdf");
  std::string xml((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  xml.replace(xml.find("max_speed=\"600\""), 15, "max_speed=\"600\" torque_constant=\"0.11\" resistance=\"1.3\"");
  auto model = loadModelString(xml, "electric.urdf");
  RunLoop loop(*model, 1e-3, 1);
  double copper = 0.0, last = -1.0;
  bool motoring = false, braking = false;
  while (loop.steps() < 1000) {
    const ActuatorState s = model->actuatorState(0);
    const double i = s.torque / 0.11;
    EXPECT_NEAR(s.current, i, 1e-12 * std::fabs(i) + 1e-15);
    EXPECT_NEAR(s.voltage, 1.3 * i + 0.11 * s.velocity, 1e-12 * (1.3 * std::fabs(i) + 0.11 * std::fabs(s.velocity)));
    const double scale = std::fabs(s.power) + 1.3 * i * i;
    EXPECT_NEAR(s.electrical_power, s.power + 1.3 * i * i, 1e-12 * scale + 1e-15) << "t = " << model->time();
    motoring = motoring || s.power > 1.0;
    braking = braking || s.power < -1.0;
    if (last >= 0) copper += 0.5 * 1e-3 * (last + 1.3 * i * i);
    last = 1.3 * i * i;
    loop.advance();
  }
  const ActuatorState s = model->actuatorState(0);
  const double i = s.torque / 0.11;
  copper += 0.5 * 1e-3 * (last + 1.3 * i * i);
  EXPECT_TRUE(motoring && braking);
  const ActuatorSizing& a = loop.actuatorSizing()[0];
  EXPECT_NEAR(a.copperEnergy(), copper, 1e-9 * copper);
  EXPECT_NEAR(a.peakCurrent(), a.peakTorque() / 0.11, 1e-12 * a.peakCurrent());
}

// The saturating mode's record: runs at the bounds, the time spent there (a step counts when
// it starts at the bound), the largest lag with when its drive fell behind and was back.
TEST(Actuators, SaturationRecordCountsTheRunsAtTheBoundsAndTheLargestLag) {
  ActuatorRatings r;
  r.peak_torque = 1.0;
  ActuatorSizing a("m", r);
  const double lag[] = {0, 0, 0.1, 0.3, 0.2, 0, 0, 0.05, 0, 0};
  const bool bound[] = {false, true, true, false, false, false, true, false, false, false};
  for (int k = 0; k < 10; ++k) {
    a.add(0.1 * k, 1.0, bound[k] ? 1.0 : 0.5);
    a.addLag(0.1 * k, lag[k], bound[k]);
  }
  EXPECT_EQ(a.boundIntervals(), 2);
  EXPECT_NEAR(a.boundTime(), 0.3, 1e-12);  // from 0.1 to 0.3, from 0.6 to 0.7
  EXPECT_DOUBLE_EQ(a.firstBound(), 0.1);
  EXPECT_DOUBLE_EQ(a.lastBound(), 0.6);
  EXPECT_DOUBLE_EQ(a.largestLag(), 0.3);
  EXPECT_DOUBLE_EQ(a.largestLagTime(), 0.30000000000000004);
  EXPECT_DOUBLE_EQ(a.largestLagBegan(), 0.2);
  EXPECT_DOUBLE_EQ(a.largestLagEnded(), 0.5);
  EXPECT_TRUE(a.withinRating());  // at the peak torque, not over it
  EXPECT_NE(a.describe().find("; at its bounds 2 times, 0.3 s in all (from t = 0.1 s, last at t = 0.6 s), largest lag "
                              "0.3 at t = 0.3 s (behind from t = 0.2 s, back on its profile at t = 0.5 s); within rating"),
            std::string::npos)
      << a.describe();
  ActuatorSizing calm("c", r);
  calm.add(0, 1, 0.5), calm.addLag(0, 0, false);
  EXPECT_NE(calm.describe().find("; never at its bounds; within rating"), std::string::npos) << calm.describe();
  ActuatorSizing sized("s", r);
  sized.add(0, 1, 0.5);
  EXPECT_EQ(sized.describe().find("bounds"), std::string::npos) << sized.describe();
}

// The points kept for --actuator-plot: all while fewer than the cap, then every second,
// every fourth, ...: evenly spaced in steps, the first one always kept.
TEST(Actuators, KeptOperatingPointsStayEvenlySpaced) {
  ActuatorSizing a("m", ActuatorRatings{});
  a.keepPoints(8);
  for (int k = 0; k < 7; ++k) a.add(k, 10.0 * k, -k);
  ASSERT_EQ(a.points().size(), 7u);  // below the cap: every one
  EXPECT_EQ(a.points()[6][0], 6.0);
  EXPECT_EQ(a.points()[6][1], 60.0);
  EXPECT_EQ(a.points()[6][2], -6.0);
  for (int k = 7; k < 100; ++k) a.add(k, 10.0 * k, -k);
  // 8 reached at k = 7 (-> 0 2 4 6, stride 2), at k = 14 (-> 0 4 8 12, stride 4), at k = 28
  // (stride 8), at k = 56 (stride 16): 0 16 32 48 64 80 96
  ASSERT_EQ(a.points().size(), 7u);
  for (size_t i = 0; i < a.points().size(); ++i) {
    EXPECT_EQ(a.points()[i][0], 16.0 * i);
    EXPECT_EQ(a.points()[i][1], 160.0 * i);
  }
  a.reset();  // the record restarts, still keeping points
  a.add(0.5, 1.0, 2.0);
  ASSERT_EQ(a.points().size(), 1u);
  EXPECT_EQ(a.points()[0][0], 0.5);
  ActuatorSizing none("n", ActuatorRatings{});
  none.add(0, 1, 1);
  EXPECT_TRUE(none.points().empty());  // not asked: nothing kept
}

TEST(Actuators, ActuatorsFile) {
  const std::string path = testing::TempDir() + "/actuators.yaml";
  {
    std::ofstream out(path);
    out << "actuators:\n  motor:\n    rotor_inertia: 2.0e-5\n    peak_torque: 3\n";
  }
  LoadOptions o;
  o.actuators_file = path;
  auto model = loadModelString(pendulum(std::string(kSimple) + "<mechanism_sim:actuator name=\"motor\" rotor_inertia=\"4e-5\"/>"),
                               "geared.urdf", o);
  EXPECT_DOUBLE_EQ(model->actuators()[0].ratings.rotor_inertia, 2e-5);
  EXPECT_DOUBLE_EQ(model->actuators()[0].ratings.peak_torque, 3.0);
  {
    std::ofstream out(path);
    out << "actuators:\n  motor:\n    rotor_inertai: 2.0e-5\n";
  }
  EXPECT_EQ(loadError(pendulum(kSimple), o), path + ":3: actuator 'motor': unknown property 'rotor_inertai'");
}

// A reduced model fixes joints, or leaves them out, and keeps their <transmission>s
// (example-robot-data's kinova fingers, talos_left_arm's shoulder): such a transmission
// drives nothing, is listed in one note, and the rest of the model runs with its rotors.
TEST(Actuators, ATransmissionOfAFixedOrMissingJointIsNotSimulated) {
  const std::string wrist =
      "<link name=\"hand\"><inertial><mass value=\"0.1\"/><inertia ixx=\"1e-4\" iyy=\"1e-4\" izz=\"1e-4\" "
      "ixy=\"0\" ixz=\"0\" iyz=\"0\"/></inertial></link><joint name=\"wrist\" type=\"fixed\"><parent "
      "link=\"arm\"/><child link=\"hand\"/><origin xyz=\"1 0 0\"/></joint>"
      "<transmission name=\"wrist_trans\"><type>transmission_interface/SimpleTransmission</type><joint "
      "name=\"wrist\"/><actuator name=\"wrist_motor\"><mechanicalReduction>50</mechanicalReduction></actuator>"
      "</transmission>";
  auto model = loadModelString(pendulum(std::string(kSimple) + wrist), "t.urdf", {});
  int listed = 0;
  for (const std::string& note : model->notes())
    if (note.find("transmissions of fixed joints drive nothing") != std::string::npos &&
        note.find("'wrist_trans'") != std::string::npos)
      ++listed;
  EXPECT_EQ(listed, 1);
  ASSERT_EQ(model->actuators().size(), 1u);  // the hinge's motor only
  EXPECT_EQ(model->actuators()[0].name, "motor");
  // and one of a joint the file does not have (a reduced model left it out), likewise
  const std::string elsewhere =
      "<transmission name=\"elbow_trans\"><type>transmission_interface/SimpleTransmission</type><joint "
      "name=\"elbow\"/><actuator name=\"elbow_motor\"><mechanicalReduction>50</mechanicalReduction></actuator>"
      "</transmission>";
  model = loadModelString(pendulum(std::string(kSimple) + elsewhere), "t.urdf", {});
  listed = 0;
  for (const std::string& note : model->notes())
    if (note.find("transmissions of joints the file does not have drive nothing") != std::string::npos &&
        note.find("'elbow_trans'") != std::string::npos)
      ++listed;
  EXPECT_EQ(listed, 1);
  EXPECT_EQ(model->actuators().size(), 1u);
}

TEST(Actuators, BadInputIsOneLine) {
  auto simple = [](const std::string& joint, const std::string& reduction) {
    return "<transmission name=\"gearbox\"><type>transmission_interface/SimpleTransmission</type><joint name=\"" + joint +
           "\"/><actuator name=\"motor\"><mechanicalReduction>" + reduction + "</mechanicalReduction></actuator></transmission>";
  };
  EXPECT_EQ(loadError(pendulum(simple("hinge", "0"))),
            "t.urdf:1: transmission 'gearbox': a mechanical reduction must be finite and not zero");
  EXPECT_EQ(loadError(pendulum(simple("hinge", "ten"))),
            "t.urdf:1: actuator 'motor': <mechanicalReduction> is not a finite number: 'ten'");
  EXPECT_EQ(loadError(pendulum(std::string(kSimple) + "<mechanism_sim:actuator name=\"motor\" rotor_inertia=\"-1e-5\"/>")),
            "t.urdf:1: mechanism_sim:actuator 'motor': rotor_inertia must be finite and not negative");
  EXPECT_EQ(loadError(pendulum(std::string(kSimple) + "<mechanism_sim:actuator name=\"servo\" rotor_inertia=\"1e-5\"/>")),
            "t.urdf:1: mechanism_sim:actuator 'servo': no transmission of a simulated type names actuator 'servo'");
}

// A wheel about the vertical (gravity does no work) behind 100:1, its motor's damping c_m
// and rotor J on the shaft, spun to w0 and let go: the damping reaches the joint as N^2 c_m,
// (I + N^2 J) w_dot = -N^2 c_m w, so w = w0 exp(-N^2 c_m t / (I + N^2 J)), in both
// formulations (to the integrator's accuracy at 1 ms: h k = 0.05).
TEST(Actuators, MotorDampingDecaysTheWheelAtNSquaredItsRate) {
  const double N = 100, c_m = 1e-5, J = 1e-6, I = 0.02, w0 = 3.0;
  const double k = N * N * c_m / (I + N * N * J);
  const std::string xml =
      "<robot name=\"wheel\" xmlns:mechanism_sim=\"https://mechanism-sim.github.io/urdf-extension\">"
      "<link name=\"base\"/><link name=\"wheel\"><inertial><mass value=\"1\"/><inertia ixx=\"0.01\" iyy=\"0.01\" "
      "izz=\"0.02\" ixy=\"0\" ixz=\"0\" iyz=\"0\"/></inertial></link>"
      "<joint name=\"hinge\" type=\"continuous\"><parent link=\"base\"/><child link=\"wheel\"/><axis xyz=\"0 0 1\"/>"
      "</joint>" +
      std::string(kSimple) +
      "<mechanism_sim:actuator name=\"motor\" rotor_inertia=\"1e-6\" damping=\"1e-5\"/>"
      "<mechanism_sim:initial joint=\"hinge\" velocity=\"3\"/></robot>";
  for (const char* f : {"absolute", "joint"}) {
    SCOPED_TRACE(f);
    LoadOptions o;
    o.formulation = f;
    auto model = loadModelString(xml, "wheel.urdf", o);
    for (const std::string& note : model->notes()) EXPECT_EQ(note.find("not applied"), std::string::npos) << note;
    EXPECT_NEAR(model->acceleration(0), -k * w0, 1e-12 * k * w0);
    for (int s = 0; s < 1000; ++s) model->step(1e-3);
    const double t = model->mechanism().time(), w = w0 * std::exp(-k * t);
    EXPECT_NEAR(model->velocity(0), w, 1e-9 * w0);
    // the motor turns N times as fast; its damping's torque c_m theta_dot is what it loses
    EXPECT_NEAR(model->actuatorState(0).velocity, N * w, 1e-9 * N * w0);
    std::printf("[motor damping, %s] w(1 s) = %.12f, w0 exp(-N^2 c_m t / (I + N^2 J)) = %.12f\n", f, model->velocity(0), w);
  }
}

// A pendulum behind 100:1 (m g L = 9.81 N m at the horizontal) with its motor's Coulomb
// friction f_m: the friction reaches the joint as a bound N f_m. Released at rest where
// gravity's torque m g L cos q is 0.9 N f_m it sticks; at 1.1 N f_m it accelerates at
// (m g L cos q - N f_m) / (I + N^2 J) from rest. Both formulations.
TEST(Actuators, MotorFrictionHoldsThePendulumWithinItsBound) {
  const double m = 2.0, L = 0.5, Iyy = 1e-3, N = 100, J = 4e-5, f_m = 0.05;
  const double mgL = m * kG * L, I = m * L * L + Iyy + N * N * J;
  const std::string xml = pendulum(std::string(kSimple) +
                                   "<mechanism_sim:actuator name=\"motor\" rotor_inertia=\"4e-5\" friction=\"0.05\"/>");
  for (const char* f : {"absolute", "joint"}) {
    for (double share : {0.9, 1.1}) {
      SCOPED_TRACE(std::string(f) + " share " + std::to_string(share));
      const double q0 = std::acos(share * N * f_m / mgL);
      LoadOptions o;
      o.formulation = f;
      o.positions = {{"hinge", q0}};
      auto model = loadModelString(xml, "geared.urdf", o);
      const int steps = share < 1 ? 1000 : 10;
      for (int s = 0; s < steps; ++s) model->step(1e-3);
      const double t = model->mechanism().time();
      const double free_fall = mgL * std::cos(q0) / I * t;  // what gravity alone would do
      if (share < 1) {  // stuck for 1 s (to the solves' round-off)
        EXPECT_NEAR(model->velocity(0), 0.0, 1e-6 * free_fall);
        EXPECT_NEAR(model->position(0), q0, 1e-6 * free_fall * t);
      } else {  // (gravity's torque falls with q by 2e-4 of the net torque over 10 ms)
        const double a = (mgL * std::cos(q0) - N * f_m) / I;
        EXPECT_NEAR(model->velocity(0), a * t, 1e-3 * a * t);
      }
      std::printf("[motor friction, %s] m g L cos q0 = %.2f N f_m: after %.2f s q_dot = %.3e rad/s\n", f, share, t,
                  model->velocity(0));
    }
  }
}

// Two discs about the vertical behind a differential (E = [20 40; 30 -60]), the first
// motor's damping c_m = 1e-5 N m s/rad, the rotors B = E^T diag(J) E: at the start,
// (M + B) q_ddot = -D q_dot with D = E^T diag(c_m, 0) E the full coupled matrix, and the
// power the motion loses is c_m theta_dot_1^2; over 1 s the kinetic energy falls by the
// integral of c_m theta_dot_1^2.
TEST(Actuators, DifferentialMotorDampingTakesItsMotorsPower) {
  const std::string xml = differentialDiscs(
      "<mechanism_sim:actuator name=\"m1\" rotor_inertia=\"1e-5\" damping=\"1e-5\"/>"
      "<mechanism_sim:actuator name=\"m2\" rotor_inertia=\"2e-5\"/>"
      "<mechanism_sim:initial joint=\"ja\" velocity=\"1.5\"/><mechanism_sim:initial joint=\"jb\" velocity=\"-2\"/>");
  Eigen::Matrix2d E;
  E << 20, 40, 30, -60;
  const double c_m = 1e-5;
  const Eigen::Matrix2d B = E.transpose() * Eigen::Vector2d(1e-5, 2e-5).asDiagonal() * E;
  const Eigen::Matrix2d D = E.transpose() * Eigen::Vector2d(c_m, 0.0).asDiagonal() * E;
  const Eigen::Matrix2d M = Eigen::Vector2d(0.02, 0.03).asDiagonal();
  const Eigen::Vector2d qd(1.5, -2.0);
  const Eigen::Vector2d qdd = -(M + B).ldlt().solve(D * qd);
  double T_end[2];
  for (const char* formulation : {"absolute", "joint"}) {
    SCOPED_TRACE(formulation);
    LoadOptions o;
    o.formulation = formulation;
    auto model = loadModelString(xml, "diff.urdf", o);
    EXPECT_STREQ(model->mechanism().formulation(), formulation);
    for (int i = 0; i < 2; ++i) EXPECT_NEAR(model->acceleration(i), qdd[i], 1e-10 * qdd.norm()) << i;
    const double theta_dot = E.row(0).dot(qd);
    EXPECT_NEAR(qd.dot((M + B) * qdd), -c_m * theta_dot * theta_dot, 1e-12 * c_m * theta_dot * theta_dot);
    const double T0 = model->kineticEnergy();
    double lost = 0.0, p_prev = c_m * std::pow(model->actuatorState(0).velocity, 2);
    const double h = 1e-3;
    for (int s = 0; s < 1000; ++s) {
      model->step(h);
      const double p = c_m * std::pow(model->actuatorState(0).velocity, 2);
      lost += 0.5 * h * (p + p_prev), p_prev = p;
  }
  // (the trapezoidal rule's error at 1 ms: the decay rate is 0.5/s, (h k)^2 / 12 of it)
  EXPECT_NEAR(T0 - model->kineticEnergy(), lost, 1e-6 * lost);
  std::printf("[differential motor damping, %s] kinetic energy lost over 1 s %.9f J, integral of c_m theta_dot^2 %.9f J\n",
              formulation, T0 - model->kineticEnergy(), lost);
  T_end[formulation[0] == 'j'] = model->kineticEnergy();
  }
  EXPECT_NEAR(T_end[0], T_end[1], 1e-10 * T_end[0]);  // the two formulations alike
}

// Energy: the geared pendulum driven q = 0.6 sin(2 pi t), its motor's damping and friction
// on the motion: the motor's work, the integral of tau_m theta_dot, equals the change of the
// energy (the arm's and the rotor's kinetic, gravity's) plus what the damping, c_m
// theta_dot^2, and the friction, f_m |theta_dot|, took. Both formulations.
TEST(Actuators, MotorWorkIsTheEnergyChangePlusWhatDampingAndFrictionTook) {
  const double c_m = 2e-6, f_m = 0.01, h = 1e-4;
  const std::string xml = pendulum(std::string(kSimple) +
                                   "<mechanism_sim:actuator name=\"motor\" rotor_inertia=\"4e-5\" friction=\"0.01\" "
                                   "damping=\"2e-6\"/><mechanism_sim:drive joint=\"hinge\" profile=\"harmonic\" "
                                   "offset=\"0\" amplitude=\"0.6\" frequency=\"1\" phase=\"0\"/>");
  for (const char* f : {"absolute", "joint"}) {
    SCOPED_TRACE(f);
    LoadOptions o;
    o.formulation = f;
    auto model = loadModelString(xml, "geared.urdf", o);
    model->step(h);  // (the balance starts after the first step, where the friction starts)
    const double E0 = model->kineticEnergy() + model->potentialEnergy();
    double work = 0.0, damped = 0.0, rubbed = 0.0;
    ActuatorState prev = model->actuatorState(0);
    for (int s = 0; s < 7500; ++s) {  // 0.75 s: through a reversal
      model->step(h);
      const ActuatorState a = model->actuatorState(0);
      work += 0.5 * h * (a.power + prev.power);
      damped += 0.5 * h * c_m * (a.velocity * a.velocity + prev.velocity * prev.velocity);
      rubbed += 0.5 * h * f_m * (std::fabs(a.velocity) + std::fabs(prev.velocity));
      prev = a;
    }
    const double dE = model->kineticEnergy() + model->potentialEnergy() - E0;
    const double balance = work - (dE + damped + rubbed);
    std::printf("[motor energy, %s] work %.6f J = energy change %.6f J + damping %.6f J + friction %.6f J "
                "(off by %.1e J)\n",
                f, work, dE, damped, rubbed, balance);
    EXPECT_GT(damped, 0.05 * std::fabs(work));
    EXPECT_GT(rubbed, 0.05 * std::fabs(work));
    EXPECT_NEAR(balance, 0.0, 1e-4 * (std::fabs(work) + damped + rubbed));
  }
}

// Two discs about the vertical behind a differential (E = [20 40; 30 -60]), the first
// motor's Coulomb friction f_m on its own shaft theta_1 = 20 q_a + 40 q_b, a row on both
// joints. In motor coordinates the inertia is M_theta = E^-T M E^-1. With
// motor torques tau_theta applied as joint efforts E^T tau_theta from rest: below the bound
// theta_1 sticks (its rate 0 to round-off) while theta_2 turns at tau_2 / M_theta(1, 1); above
// it the motor slides against f_m and theta_dot = M_theta^-1 (tau_theta - (f_m, 0)) t.
// Both formulations (the rotors left out: a differential's B couples the joints, which the
// joint formulation does not take).
TEST(Actuators, DifferentialMotorFrictionActsOnItsShaft) {
  const double f_m = 0.02;
  const std::string actuators = "<mechanism_sim:actuator name=\"m1\" friction=\"0.02\"/>";
  const std::string xml = differentialDiscs(actuators);
  Eigen::Matrix2d E;
  E << 20, 40, 30, -60;
  const Eigen::Matrix2d Einv = E.inverse();
  const Eigen::Matrix2d M_theta = Einv.transpose() * Eigen::Vector2d(0.02, 0.03).asDiagonal() * Einv;
  for (const char* f : {"absolute", "joint"}) {
    for (double share : {0.5, 1.5}) {
      SCOPED_TRACE(std::string(f) + " share " + std::to_string(share));
      LoadOptions o;
      o.formulation = f;
      auto model = loadModelString(xml, "diff.urdf", o);
      EXPECT_STREQ(model->mechanism().formulation(), f);
      for (const std::string& note : model->notes()) EXPECT_EQ(note.find("friction"), std::string::npos) << note;
      // tau_2 chosen so that, with theta_1 held, its reaction M_theta(0, 1) theta_ddot_2 is
      // within the bound: the friction holds tau_1 - M_theta(0, 1) tau_2 / M_theta(1, 1)
      const double tau2 = 0.01;
      const double held = M_theta(0, 1) * tau2 / M_theta(1, 1);
      const Eigen::Vector2d tau_theta(held + share * f_m, tau2);
      const Eigen::Vector2d tau_q = E.transpose() * tau_theta;
      model->setEffort(model->dofIndex("ja"), tau_q[0]);
      model->setEffort(model->dofIndex("jb"), tau_q[1]);
      for (int s = 0; s < 200; ++s) model->step(1e-3);
      const double t = model->mechanism().time();
      const Eigen::Vector2d qd(model->velocity(model->dofIndex("ja")), model->velocity(model->dofIndex("jb")));
      const Eigen::Vector2d theta_dot = E * qd;
      if (share < 1) {
        EXPECT_NEAR(theta_dot[0], 0.0, 1e-9 * std::fabs(theta_dot[1]));
        EXPECT_NEAR(theta_dot[1], tau2 / M_theta(1, 1) * t, 1e-9 * std::fabs(theta_dot[1]));
      } else {
        const Eigen::Vector2d expected = M_theta.ldlt().solve(tau_theta - Eigen::Vector2d(f_m, 0.0)) * t;
        for (int k = 0; k < 2; ++k) EXPECT_NEAR(theta_dot[k], expected[k], 1e-9 * expected.norm()) << k;
      }
      std::printf("[differential motor friction, %s, %.1f f_m] theta_dot = (%.3e, %.6f) rad/s after %.1f s\n", f, share,
                  theta_dot[0], theta_dot[1], t);
    }
  }
}

// Saturation behind a two-joint transmission: both discs velocity-driven, ja ramped to
// 10 rad/s at 1000 rad/s^2 with jb held still, m1's peak P = 0.25 N m below what the ramp
// asks of it, (E^-T (0.02 1000, 0))_1. While m1 is at its bound +-P, m2's coordinate
// theta_2 = E_2 q follows its profile, so (by hand)
//   M q_ddot = E^T (+-P, tau_2),   E_2 q_ddot = E_2 q_ddot_profile,
// three equations for q_ddot and tau_2 (behind the differential jb is dragged off its rest
// while ja falls behind). m1's coordinate lags at A1 = E_1 (q_ddot_profile - q_ddot) over
// the ramp's T = 0.01 s and catches up at A2 after it, its largest lag 1/2 A1 T^2 +
// (A1 T)^2 / (2 A2), A1 T / A2 after the ramp's end (at 0.1 ms steps). Then (at 1 ms steps,
// where the way back, critically damped at 0.5 / h, settles within the bounds) both drives
// follow their profiles exactly again. Both formulations, agreeing.
void saturationBehind(const std::string& type, const Eigen::Matrix2d& E) {
  SCOPED_TRACE(type);
  const double P = 0.25, V = 10.0, alpha = 1000.0, T = V / alpha, h = 1e-4;
  const Eigen::Matrix2d M = Eigen::Vector2d(0.02, 0.03).asDiagonal();
  // q_ddot at m1's torque tau_1 with theta_2 on its profile's acceleration
  auto atBound = [&](double tau_1, const Eigen::Vector2d& qdd_profile) {
    Eigen::Matrix3d K = Eigen::Matrix3d::Zero();
    K.topLeftCorner<2, 2>() = M;
    K.topRightCorner<2, 1>() = -E.transpose().col(1);
    K.bottomLeftCorner<1, 2>() = E.row(1);
    Eigen::Vector3d r;
    r.head<2>() = E.transpose().col(0) * tau_1;
    r[2] = E.row(1).dot(qdd_profile);
    return Eigen::Vector2d(K.partialPivLu().solve(r).head<2>());
  };
  const Eigen::Vector2d ramp(alpha, 0.0);
  ASSERT_GT((E.transpose().partialPivLu().solve(M * ramp))[0], 1.5 * P);
  const double A1 = E.row(0).dot(ramp - atBound(P, ramp));
  const double A2 = E.row(0).dot(atBound(P, Eigen::Vector2d::Zero()));
  const double lag_expected = 0.5 * A1 * T * T + A1 * T * A1 * T / (2 * A2);
  const double t_expected = 0.001 + T + A1 * T / A2;  // (the ramp starts at 0.001 s)
  std::string xml = differentialDiscs(
      "<mechanism_sim:actuator name=\"m1\" peak_torque=\"0.25\"/><mechanism_sim:actuator name=\"m2\" peak_torque=\"5\"/>"
      "<mechanism_sim:drive joint=\"ja\" velocity=\"0\"/><mechanism_sim:drive joint=\"jb\" velocity=\"0\"/>");
  xml.replace(xml.find("DifferentialTransmission"), std::strlen("DifferentialTransmission"), type);
  Eigen::Vector2d q_end[2];
  int f = 0;
  for (const char* formulation : {"absolute", "joint"}) {
    SCOPED_TRACE(formulation);
    LoadOptions o;
    o.formulation = formulation;
    o.actuator_limits = true;
    auto model = loadModelString(xml, "diff.urdf", o);
    EXPECT_STREQ(model->mechanism().formulation(), formulation);
    const int ja = model->dofIndex("ja"), jb = model->dofIndex("jb");
    for (int s = 0; s < 10; ++s) model->step(h);
    model->commandDriveVelocity(ja, V, alpha);
    double lag_max = 0.0, t_max = 0.0, worst = 0.0, worst_m2_lag = 0.0;
    int at_bound = 0;
    auto check = [&](int s) {
      const ActuatorState m1 = model->actuatorState(0), m2 = model->actuatorState(1);
      worst = std::max(worst, std::fabs(m1.torque) / P - 1.0);
      EXPECT_LE(std::fabs(m2.torque), 5.0 * (1 + 1e-12)) << s;
      if (m1.lag > lag_max) lag_max = m1.lag, t_max = model->mechanism().time();
      if (!m1.saturated) return;
      worst_m2_lag = std::max(worst_m2_lag, std::fabs(m2.lag));
      ++at_bound;
      // at the bound: the accelerations by hand from m1's torque and theta_2's profile
      Eigen::Vector2d qdd_profile;
      for (int i = 0; i < 2; ++i) {
        double q, qd;
        model->mechanism().driveTarget(i, &q, &qd, &qdd_profile[i]);
      }
      const Eigen::Vector2d qdd = atBound(m1.torque, qdd_profile);
      // (to the round-off of the drives' efforts, up to 60 times the motors' torques)
      EXPECT_NEAR(std::fabs(m1.torque), P, 1e-10 * P) << s;
      EXPECT_NEAR(model->acceleration(ja), qdd[0], 1e-8 * alpha) << s;
      EXPECT_NEAR(model->acceleration(jb), qdd[1], 1e-8 * alpha) << s;
    };
    // the ramp and the catching up, to 1 ms past the largest lag
    const int n1 = static_cast<int>(std::lround((t_expected - 0.001) / h)) + 10;
    for (int s = 0; s < n1; ++s) model->step(h), check(s);
    std::printf("[saturation behind a %s, %s] m1's largest lag %.9f rad at t = %.4f s (by hand %.9f at %.4f s), "
                "%d steps at its bound, m2's lag there at most %.2e\n",
                type.c_str(), formulation, lag_max, t_max, lag_expected, t_expected, at_bound, worst_m2_lag);
    EXPECT_EQ(at_bound, n1);
    EXPECT_NEAR(lag_max, lag_expected, 1e-6 * lag_expected);
    EXPECT_NEAR(t_max, t_expected, 1.5 * h);
    EXPECT_LT(worst_m2_lag, 1e-9 * lag_expected);  // m2's coordinate follows its profile
    for (int s = 0; s < 300; ++s) model->step(1e-3), check(n1 + s);
    EXPECT_LT(worst, 1e-10);  // never above its peak
    // back on both profiles exactly: ja at 10 rad/s, jb at rest where it started
    const ActuatorState m1 = model->actuatorState(0);
    EXPECT_EQ(m1.lag, 0.0);
    EXPECT_FALSE(m1.saturated);
    EXPECT_NEAR(model->velocity(ja), V, 1e-10);
    EXPECT_NEAR(model->velocity(jb), 0.0, 1e-10);
    EXPECT_NEAR(model->position(jb), 0.0, 1e-11);
    q_end[f++] = Eigen::Vector2d(model->position(ja), model->position(jb));
  }
  EXPECT_NEAR(q_end[0][0], q_end[1][0], 1e-9);
  EXPECT_NEAR(q_end[0][1], q_end[1][1], 1e-9);
}

TEST(Actuators, SaturationBehindADifferentialLagsByTheHandComputedAmount) {
  Eigen::Matrix2d E;
  E << 20, 40, 30, -60;  // (differentialDiscs: n_a = (20, 30), n_j = (1, 2))
  saturationBehind("DifferentialTransmission", E);
}

TEST(Actuators, SaturationBehindAFourBarLagsByTheHandComputedAmount) {
  Eigen::Matrix2d E;
  E << 20, 0, 30, 60;  // [n_a1 n_j1, 0; n_a2, n_a2 n_j2]
  saturationBehind("FourBarLinkageTransmission", E);
}

// The coupled rotor inertia B = E^T diag(J) E in both formulations: the discs (two sibling
// joints) under motor torques tau_theta accelerate at (M + B)^-1 E^T tau_theta, the dense
// formula; the joint formulation adds B's coupling to its articulated-body pass exactly
// (TreeModel::rotor_couplings) and `auto` picks it.
TEST(Actuators, CoupledRotorInertiaExactInBothFormulations) {
  const std::string xml = differentialDiscs(
      "<mechanism_sim:actuator name=\"m1\" rotor_inertia=\"1e-5\"/><mechanism_sim:actuator name=\"m2\" rotor_inertia=\"3e-5\"/>");
  Eigen::Matrix2d E;
  E << 20, 40, 30, -60;
  const Eigen::Matrix2d B = E.transpose() * Eigen::Vector2d(1e-5, 3e-5).asDiagonal() * E;
  const Eigen::Matrix2d M = Eigen::Vector2d(0.02, 0.03).asDiagonal();
  const Eigen::Vector2d tau_theta(0.01, -0.02), tau_q = E.transpose() * tau_theta;
  const Eigen::Vector2d qdd = (M + B).ldlt().solve(tau_q);
  EXPECT_GT(std::fabs(B(0, 1)), 0.1 * B(0, 0));  // (a coupling that matters: 1.56 of 2.56 g m^2)
  auto chosen = loadModelString(xml, "diff.urdf");
  EXPECT_STREQ(chosen->mechanism().formulation(), "joint") << chosen->formulationReason();
  for (const char* formulation : {"absolute", "joint"}) {
    SCOPED_TRACE(formulation);
    LoadOptions o;
    o.formulation = formulation;
    auto model = loadModelString(xml, "diff.urdf", o);
    EXPECT_STREQ(model->mechanism().formulation(), formulation);
    model->setEffort(model->dofIndex("ja"), tau_q[0]);
    model->setEffort(model->dofIndex("jb"), tau_q[1]);
    model->step(1e-3);
    // (constant accelerations: after a step the rates are h q_ddot)
    for (int i = 0; i < 2; ++i) {
      EXPECT_NEAR(model->acceleration(i), qdd[i], 1e-10 * qdd.norm()) << i;
      EXPECT_NEAR(model->velocity(i), 1e-3 * qdd[i], 1e-13 * qdd.norm()) << i;
    }
  }
}

// A serial wrist behind a differential with both rotors and a motor's damping, under gravity:
// pitch about z at the base, roll about x on the pitch link, the roll link's centre off its
// axis (so M(q) is full and changes). The two formulations agree on the motion over 0.5 s and
// on every joint's reaction, the rotors' coupled torque included; the energy falls by what
// the motor's damping took.
TEST(Actuators, CoupledRotorsOnASerialWristAgreeAcrossFormulations) {
  const std::string xml =
      "<robot name=\"wrist\" xmlns:mechanism_sim=\"https://mechanism-sim.github.io/urdf-extension\"><link name=\"base\"/>"
      "<link name=\"pitch\"><inertial><origin xyz=\"0.1 0 0\"/><mass value=\"0.8\"/><inertia ixx=\"1e-3\" iyy=\"2e-3\" "
      "izz=\"2.5e-3\" ixy=\"0\" ixz=\"0\" iyz=\"0\"/></inertial></link>"
      "<link name=\"roll\"><inertial><origin xyz=\"0.05 0.03 0.02\"/><mass value=\"0.5\"/><inertia ixx=\"6e-4\" "
      "iyy=\"8e-4\" izz=\"9e-4\" ixy=\"1e-5\" ixz=\"0\" iyz=\"0\"/></inertial></link>"
      "<joint name=\"wrist_pitch\" type=\"continuous\"><parent link=\"base\"/><child link=\"pitch\"/><axis xyz=\"0 1 0\"/>"
      "</joint><joint name=\"wrist_roll\" type=\"continuous\"><parent link=\"pitch\"/><child link=\"roll\"/>"
      "<origin xyz=\"0.2 0 0\"/><axis xyz=\"1 0 0\"/></joint>"
      "<transmission name=\"wrist\"><type>transmission_interface/DifferentialTransmission</type>"
      "<actuator name=\"m1\"><role>actuator1</role><mechanicalReduction>15</mechanicalReduction></actuator>"
      "<actuator name=\"m2\"><role>actuator2</role><mechanicalReduction>15</mechanicalReduction></actuator>"
      "<joint name=\"wrist_pitch\"><role>joint1</role></joint><joint name=\"wrist_roll\"><role>joint2</role>"
      "</joint></transmission>"
      "<mechanism_sim:actuator name=\"m1\" rotor_inertia=\"2e-5\" damping=\"2e-5\"/>"
      "<mechanism_sim:actuator name=\"m2\" rotor_inertia=\"1e-5\"/>"
      "<mechanism_sim:initial joint=\"wrist_pitch\" position=\"0.3\" velocity=\"1\"/>"
      "<mechanism_sim:initial joint=\"wrist_roll\" position=\"-0.4\" velocity=\"-2\"/></robot>";
  std::unique_ptr<MechanismModel> m[2];
  for (int f = 0; f < 2; ++f) {
    LoadOptions o;
    o.formulation = f == 0 ? "absolute" : "joint";
    m[f] = loadModelString(xml, "wrist.urdf", o);
    EXPECT_STREQ(m[f]->mechanism().formulation(), o.formulation.c_str());
  }
  for (int i = 0; i < 2; ++i) EXPECT_NEAR(m[0]->acceleration(i), m[1]->acceleration(i), 1e-10 * (1 + std::fabs(m[0]->acceleration(i))));
  const double E0 = m[1]->kineticEnergy() + m[1]->potentialEnergy();
  double damped = 0.0, p_prev = 2e-5 * std::pow(m[1]->actuatorState(0).velocity, 2);
  const double h = 1e-4;
  double worst_q = 0.0, worst_reaction = 0.0, largest_reaction = 0.0;
  for (int s = 0; s < 5000; ++s) {
    m[0]->step(h), m[1]->step(h);
    const double p = 2e-5 * std::pow(m[1]->actuatorState(0).velocity, 2);
    damped += 0.5 * h * (p + p_prev), p_prev = p;
    for (int i = 0; i < 2; ++i) worst_q = std::max(worst_q, std::fabs(m[0]->position(i) - m[1]->position(i)));
    if (s % 500 != 499) continue;
    const std::vector<JointReaction> r0 = m[0]->jointReactions(), r1 = m[1]->jointReactions();
    ASSERT_EQ(r0.size(), r1.size());
    for (size_t j = 0; j < r0.size(); ++j) {
      worst_reaction = std::max({worst_reaction, (r0[j].force - r1[j].force).norm(), (r0[j].torque - r1[j].torque).norm()});
      largest_reaction = std::max({largest_reaction, r0[j].force.norm(), r0[j].torque.norm()});
    }
  }
  const double dE = m[1]->kineticEnergy() + m[1]->potentialEnergy() - E0;
  std::printf("[coupled rotors, serial wrist] positions agree to %.2e rad, reactions to %.2e of %.3g; energy change %.9f J, "
              "damping took %.9f J\n",
              worst_q, worst_reaction, largest_reaction, dE, damped);
  EXPECT_LT(worst_q, 1e-9);
  EXPECT_LT(worst_reaction, 1e-8 * largest_reaction);
  EXPECT_NEAR(-dE, damped, 1e-6 * damped);
}

// What the joint formulation does not take with a coupled rotor, named in one line.
TEST(Actuators, CoupledRotorWithAClosureRunsInAbsoluteCoordinates) {
  const std::string xml = differentialDiscs(
      "<mechanism_sim:actuator name=\"m1\" rotor_inertia=\"1e-5\"/><mechanism_sim:drive joint=\"ja\" velocity=\"1\"/>");
  auto model = loadModelString(xml, "diff.urdf");
  EXPECT_STREQ(model->mechanism().formulation(), "absolute");
  EXPECT_NE(model->formulationReason().find("couples two joints (ja, jb) and constraint"), std::string::npos)
      << model->formulationReason();
}

// Damping that is stiff at the step with a coupled rotor stops the run with one line naming
// the joint, in both formulations: the joint formulation's implicit damping works on the
// articulated factors without the coupling, and the absolute one integrates the motors'
// coupled damping explicitly (stiff, it would diverge: the disc from 1 to thousands of
// rad/s in 10 ms). At a step the stages follow, both run.
TEST(Actuators, StiffDampingWithACoupledRotorStopsTheRun) {
  const std::string xml = differentialDiscs(
      "<mechanism_sim:actuator name=\"m1\" rotor_inertia=\"1e-5\" damping=\"1\"/>"
      "<mechanism_sim:initial joint=\"ja\" velocity=\"1\"/>");
  for (const char* formulation : {"joint", "absolute"}) {
    LoadOptions o;
    o.formulation = formulation;
    auto model = loadModelString(xml, "diff.urdf", o);
    std::string what = "(ran)";
    try {
      model->step(1e-3);  // (400 N m s on ja against 0.024 kg m^2: a rate 1.7e4 / s, h times it 17)
    } catch (const std::exception& e) {
      what = e.what();
    }
    EXPECT_NE(what.find("the damping of joint 'ja' is stiff at this step and "), std::string::npos)
        << formulation << ": " << what;
    // at a step the explicit stages follow, both run and the disc slows down
    auto slow = loadModelString(xml, "diff.urdf", o);
    const int ja = slow->dofIndex("ja");
    for (int k = 0; k < 100; ++k) slow->step(2e-5);
    EXPECT_GT(slow->velocity(ja), 0.0) << formulation;
    EXPECT_LT(slow->velocity(ja), 1.0) << formulation;
  }
}

}  // namespace
}  // namespace mechanism_sim
