// Transmissions and reflected rotor inertia (transmission.h) against known answers: the
// maps of ros_control's three transmissions, a pendulum behind a gearbox swinging with
// I + N^2 J in both formulations, and a differential's coupled inertia E^T diag(J) E in the
// accelerations and the kinetic energy.
#include <gtest/gtest.h>

#include <cmath>

#include "bodies.h"
#include "mechanism_sim/core/models.h"
#include "mechanism_sim/core/model/transmission.h"
#include "pendulum.h"

namespace mechanism_sim {
namespace {

Transmission make(TransmissionType type, std::vector<double> a, std::vector<double> j, std::vector<double> o) {
  Transmission t;
  t.name = "t";
  t.type = type;
  t.actuator_reduction = a, t.joint_reduction = j, t.joint_offset = o;
  t.validate();
  return t;
}

// ros_control's transmission_interface formulas, written out (its jointToActuator* and
// actuatorToJoint* of the differential, and the four-bar's positions and velocities).
TEST(Transmission, DifferentialIsRosControls) {
  const double ar[2] = {50, -30}, jr[2] = {2, 1.5}, jo[2] = {0.1, -0.2};
  const Transmission t = make(TransmissionType::kDifferential, {ar[0], ar[1]}, {jr[0], jr[1]}, {jo[0], jo[1]});
  const Eigen::Vector2d q(0.3, -0.7), v(1.1, 2.3), e(4.0, -5.0);
  const Eigen::VectorXd p = t.actuatorPosition(q), w = t.actuatorVelocity(v), f = t.actuatorEffort(e);
  EXPECT_NEAR(p[0], ((q[0] - jo[0]) * jr[0] + (q[1] - jo[1]) * jr[1]) * ar[0], 1e-12);
  EXPECT_NEAR(p[1], ((q[0] - jo[0]) * jr[0] - (q[1] - jo[1]) * jr[1]) * ar[1], 1e-12);
  EXPECT_NEAR(w[0], (v[0] * jr[0] + v[1] * jr[1]) * ar[0], 1e-12);
  EXPECT_NEAR(w[1], (v[0] * jr[0] - v[1] * jr[1]) * ar[1], 1e-12);
  EXPECT_NEAR(f[0], (e[0] / jr[0] + e[1] / jr[1]) / (2 * ar[0]), 1e-15);
  EXPECT_NEAR(f[1], (e[0] / jr[0] - e[1] / jr[1]) / (2 * ar[1]), 1e-15);
  // actuator -> joint, and power in = power out
  const Eigen::VectorXd je = t.jointEffort(f);
  EXPECT_NEAR(je[0], jr[0] * (f[0] * ar[0] + f[1] * ar[1]), 1e-12);
  EXPECT_NEAR(je[1], jr[1] * (f[0] * ar[0] - f[1] * ar[1]), 1e-12);
  EXPECT_NEAR((t.jointPosition(p) - q).norm(), 0.0, 1e-14);
  EXPECT_NEAR((t.jointVelocity(w) - v).norm(), 0.0, 1e-14);
  EXPECT_NEAR(f.dot(w), e.dot(v), 1e-12);
}

TEST(Transmission, FourBarPositionsAreRosControlsEffortsConservePower) {
  const double ar[2] = {20, 40}, jr[2] = {1.5, 3}, jo[2] = {0.5, 0.0};
  const Transmission t = make(TransmissionType::kFourBar, {ar[0], ar[1]}, {jr[0], jr[1]}, {jo[0], jo[1]});
  const Eigen::Vector2d q(0.3, -0.7), v(1.1, 2.3), e(4.0, -5.0);
  const Eigen::VectorXd p = t.actuatorPosition(q), w = t.actuatorVelocity(v), f = t.actuatorEffort(e);
  EXPECT_NEAR(p[0], (q[0] - jo[0]) * jr[0] * ar[0], 1e-12);
  EXPECT_NEAR(p[1], ((q[0] - jo[0]) + (q[1] - jo[1]) * jr[1]) * ar[1], 1e-12);
  EXPECT_NEAR(w[1], (v[0] + v[1] * jr[1]) * ar[1], 1e-12);
  // ros2_control's corrected effort map (its PR 1837): tau_a2 = tau_j2 / (n_j2 n_a2),
  // tau_a1 = (tau_j1 - tau_j2 / n_j2) / (n_j1 n_a1)
  EXPECT_NEAR(f[1], e[1] / (jr[1] * ar[1]), 1e-15);
  EXPECT_NEAR(f[0], (e[0] - e[1] / jr[1]) / (jr[0] * ar[0]), 1e-15);
  EXPECT_NEAR(f.dot(w), e.dot(v), 1e-12);
}

TEST(Transmission, SimpleAndBadInput) {
  const Transmission t = make(TransmissionType::kSimple, {100}, {1}, {0.25});
  EXPECT_DOUBLE_EQ(t.actuatorPosition(Eigen::VectorXd::Constant(1, 1.25))[0], 100.0);
  EXPECT_DOUBLE_EQ(t.actuatorVelocity(Eigen::VectorXd::Constant(1, 2.0))[0], 200.0);
  EXPECT_DOUBLE_EQ(t.actuatorEffort(Eigen::VectorXd::Constant(1, 50.0))[0], 0.5);
  EXPECT_DOUBLE_EQ(t.reflectedInertia(Eigen::VectorXd::Constant(1, 2e-5))(0, 0), 0.2);
  try {
    make(TransmissionType::kSimple, {0}, {1}, {0});
    FAIL();
  } catch (const ModelError& e) {
    EXPECT_STREQ(e.what(), "transmission 't': a mechanical reduction must be finite and not zero");
  }
  ActuatorRatings r;
  r.rotor_inertia = -1;
  EXPECT_THROW(r.validate("m"), ModelError);
  r.rotor_inertia = 1e-5, r.stall_torque = 1;
  EXPECT_THROW(r.validate("m"), ModelError);  // a torque-speed line without its no-load speed
}

// A pendulum behind a gearbox of ratio N with a rotor J: (m L^2 + Ic + N^2 J) q'' = m g L
// cos q (Pendulum::exactAngle with N^2 J reflected). Built, not yet assembled.
void buildGeared(Mechanism& m, const Pendulum& p, double N, double J, const char* formulation) {
  p.add(m);
  RotorInertia r;
  r.name = "gearbox";
  r.coords = {{0, 0}};
  r.B(0, 0) = N * N * J;
  m.addRotorInertia(r);
  IntegratorOptions io;
  io.formulation = formulation;
  m.setIntegrator(io);
  m.build();
}

TEST(RotorInertia, GearedPendulumSwingsWithReflectedInertia) {
  Pendulum p;
  p.m = 2.0, p.L = 0.5, p.Ic = 1e-3;
  const double N = 100, J = 5e-5;  // N^2 J = 0.5 kg m^2, next to m L^2 = 0.5
  const double q_exact = p.exactAngle(1.0, N * N * J);
  const double q_free = p.exactAngle(1.0);
  ASSERT_GT(std::fabs(q_exact - q_free), 0.05);  // the rotor matters (0.09 rad)
  double q_by[2];
  int i = 0;
  for (const char* f : {"absolute", "joint"}) {
    Mechanism m;
    buildGeared(m, p, N, J, f);
    m.assemble();
    EXPECT_STREQ(m.formulation(), f);
    const double E0 = m.kineticEnergy() + m.potentialEnergy();
    for (int k = 0; k < 1000; ++k) m.step(1e-3);
    q_by[i] = m.jointPosition(0, 0);
    EXPECT_NEAR(q_by[i], q_exact, 1e-9) << f;
    // the rotor's kinetic energy 1/2 N^2 J q_dot^2 is in the total, which is conserved
    EXPECT_NEAR(m.kineticEnergy() + m.potentialEnergy(), E0, 1e-8 * p.m * kG * p.L) << f;
    ++i;
  }
  EXPECT_NEAR(q_by[0], q_by[1], 1e-10);
}

// Hanging, a small swing: the period 2 pi sqrt((I + N^2 J) / (m g L)).
TEST(RotorInertia, SmallOscillationPeriod) {
  Pendulum p;
  p.m = 1.0, p.L = 0.4, p.Ic = 2e-3;
  const double N = 50, J = 1e-4;
  const double I = p.m * p.L * p.L + p.Ic + N * N * J;
  const double period = 2 * M_PI * std::sqrt(I / (p.m * kG * p.L));
  for (const char* f : {"absolute", "joint"}) {
    Mechanism m;
    buildGeared(m, p, N, J, f);
    // hanging (q = pi/2) plus 1e-3 rad, at rest
    m.assemble({{0, 0, M_PI / 2 + 1e-3}}, {{0, 0, 0.0}});
    // time of the first return to rest on the far side and back (velocity sign changes)
    const double h = 1e-3;
    double prev = 0, t_cross[2] = {0, 0};
    int crossings = 0;
    for (int k = 0; k < 20000 && crossings < 2; ++k) {
      m.step(h);
      const double v = m.jointVelocity(0, 0);
      if (k > 0 && ((prev < 0 && v >= 0) || (prev > 0 && v <= 0))) {
        // linear interpolation of the zero of v
        t_cross[crossings++] = m.time() - h * v / (v - prev);
      }
      prev = v;
    }
    ASSERT_EQ(crossings, 2) << f;
    // from rest at t = 0: rest again at T/2 and T (amplitude 1e-3: T(1 + theta^2/16) = T + 6e-8 T)
    EXPECT_NEAR(t_cross[1], period, 2e-6 * period) << f;
  }
}

// Two pendulums, each hinged on the ground, coupled only by a differential's rotors: at the
// horizontal, at rest, (M + E^T diag(J) E) q_ddot = (m g L, m g L), M = diag(m L^2 + Ic);
// with velocities, the kinetic energy 1/2 q_dot^T (M + E^T J E) q_dot. Both formulations
// (auto picks the joint one: its articulated-body pass takes the coupling exactly).
TEST(RotorInertia, DifferentialCoupledInertia) {
  Pendulum p1, p2;
  p1.m = 1.0, p1.L = 0.5, p1.Ic = 1e-3;
  p2.m = 1.5, p2.L = 0.3, p2.Ic = 2e-3, p2.pivot = Vector3d(0, 1, 0);
  Transmission t;
  t.type = TransmissionType::kDifferential;
  t.actuator_reduction = {20, 30}, t.joint_reduction = {1, 2}, t.joint_offset = {0, 0};
  const Eigen::Vector2d J(1e-4, 2e-4);
  const Eigen::Matrix2d B = t.reflectedInertia(J);
  ASSERT_GT(std::fabs(B(0, 1)), 0.01);
  auto build = [&](Mechanism& m, const char* f) {
    p1.add(m, "a");
    p2.add(m, "b");
    RotorInertia r;
    r.name = "wrist";
    r.coords = {{0, 0}, {1, 0}};
    r.B = B;
    m.addRotorInertia(r);
    IntegratorOptions io;
    io.formulation = f;
    m.setIntegrator(io);
    m.build();
  };
  Eigen::Matrix2d M = Eigen::Matrix2d::Zero();
  M(0, 0) = p1.m * p1.L * p1.L + p1.Ic;
  M(1, 1) = p2.m * p2.L * p2.L + p2.Ic;
  const Eigen::Vector2d qdd = (M + B).ldlt().solve(Eigen::Vector2d(p1.m * kG * p1.L, p2.m * kG * p2.L));
  for (const char* f : {"auto", "absolute"}) {
    Mechanism m;
    build(m, f);
    m.assemble();
    EXPECT_STREQ(m.formulation(), f[0] == 'a' && f[1] == 'u' ? "joint" : f) << m.formulationReason();
    EXPECT_NEAR(m.jointAcceleration(0, 0), qdd[0], 1e-10 * qdd.norm()) << f;
    EXPECT_NEAR(m.jointAcceleration(1, 0), qdd[1], 1e-10 * qdd.norm()) << f;

    Mechanism v;
    build(v, f);
    const Eigen::Vector2d q_dot(1.5, -2.0);
    v.assemble({}, {{0, 0, q_dot[0]}, {1, 0, q_dot[1]}});
    EXPECT_NEAR(v.kineticEnergy(), 0.5 * q_dot.dot((M + B) * q_dot), 1e-12 * q_dot.dot((M + B) * q_dot));
    const double E0 = v.kineticEnergy() + v.potentialEnergy();
    for (int k = 0; k < 500; ++k) v.step(1e-3);
    EXPECT_NEAR(v.kineticEnergy() + v.potentialEnergy(), E0, 1e-8 * E0) << f;
  }
}

// A serial two-link arm (shoulder on the ground, elbow on the upper arm, both about y)
// behind a four-bar transmission with both rotors: B couples the two joints across three
// bodies. Released from the horizontal with velocities, the energy with the rotors'
// 1/2 q_dot^T B q_dot stays constant; without the rotors it is not the same motion.
TEST(RotorInertia, FourBarRotorsOnASerialArmConserveEnergy) {
  Transmission t;
  t.type = TransmissionType::kFourBar;
  t.actuator_reduction = {30, 20}, t.joint_reduction = {1.5, 2}, t.joint_offset = {0, 0};
  const Eigen::Matrix2d B = t.reflectedInertia(Eigen::Vector2d(1e-4, 5e-5));
  ASSERT_GT(std::fabs(B(0, 1)), 1e-3);
  auto build = [&](Mechanism& m, bool rotors) {
    const int upper = m.addBody(body("upper", 2.0, 0.02 * Matrix3d::Identity(), Vector3d(0.2, 0, 0)));
    const int fore = m.addBody(body("fore", 1.0, 0.01 * Matrix3d::Identity(), Vector3d(0.6, 0, 0)));
    m.addJoint(makeJoint("revolute", "shoulder", Mechanism::kGround, models::axisY(Vector3d::Zero()), upper,
                         models::axisY(Vector3d(-0.2, 0, 0))));
    m.addJoint(makeJoint("revolute", "elbow", upper, models::axisY(Vector3d(0.2, 0, 0)), fore,
                         models::axisY(Vector3d(-0.2, 0, 0))));
    if (rotors) {
      RotorInertia r;
      r.name = "four_bar";
      r.coords = {{0, 0}, {1, 0}};
      r.B = B;
      m.addRotorInertia(r);
    }
    IntegratorOptions io;
    io.formulation = "auto";
    m.setIntegrator(io);
    m.build();
    m.assemble({}, {{0, 0, 1.0}, {1, 0, -2.0}});
  };
  Mechanism m, plain;
  build(m, true);
  build(plain, false);
  EXPECT_STREQ(m.formulation(), "joint") << m.formulationReason();  // (auto: the coupling taken exactly)
  const Eigen::Vector2d q_dot(1.0, -2.0);
  EXPECT_NEAR(m.kineticEnergy() - plain.kineticEnergy(), 0.5 * q_dot.dot(B * q_dot), 1e-12 * m.kineticEnergy());
  const double E0 = m.kineticEnergy() + m.potentialEnergy();
  for (int k = 0; k < 1000; ++k) m.step(1e-3), plain.step(1e-3);
  EXPECT_NEAR(m.kineticEnergy() + m.potentialEnergy(), E0, 1e-8 * std::fabs(E0) + 1e-8);
  EXPECT_GT(std::fabs(m.jointPosition(1, 0) - plain.jointPosition(1, 0)), 0.01);
  EXPECT_LT(m.relativePositionViolation(), 1e-10);
}

TEST(RotorInertia, BadRotorIsRefused) {
  Mechanism m;
  Pendulum().add(m);
  RotorInertia r;
  r.name = "gearbox";
  r.coords = {{0, 0}};
  r.B(0, 0) = -1.0;
  m.addRotorInertia(r);
  try {
    m.build();
    FAIL();
  } catch (const ModelError& e) {
    EXPECT_STREQ(e.what(), "rotor inertia 'gearbox': negative (a kinetic energy below zero)");
  }
}

}  // namespace
}  // namespace mechanism_sim
