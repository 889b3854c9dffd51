// Drives (drive.h): prescribed motion as an exact rheonomic constraint. The driving
// effort of a pendulum turned at constant speed and harmonically against its inverse
// dynamics, a fully driven mechanism's accelerations against finite differences of its
// positions, the natural spline's interpolation and continuity, a velocity command's ramp,
// and the refusals.
#include <gtest/gtest.h>

#include <cmath>

#include "mechanism_sim/core/models.h"

namespace mechanism_sim {
namespace {

constexpr double kG = 9.81;

// A mass m at distance L from a revolute about y at the origin (central inertia Ic): q = 0
// horizontal, q > 0 below (position L (cos q, 0, -sin q)).
struct DrivenPendulum {
  double m = 2.0, L = 0.5, Ic = 0.01;
  Mechanism mech;
  int body = 0;
  explicit DrivenPendulum(const DriveProfile& profile, double q0 = 0.0) {
    Body b;
    b.name = "bob";
    b.m = m;
    b.Jp = Ic * Matrix3d::Identity();
    b.r = Vector3d(L, 0, 0);
    body = mech.addBody(b);
    mech.addJoint(makeJoint("revolute", "pivot", Mechanism::kGround, models::axisY(Vector3d::Zero()), body,
                            models::axisY(Vector3d(-L, 0, 0))));
    mech.addDrive(0, 0, profile, q0);
    mech.build();
    mech.assemble();
  }
  // Inverse dynamics: the effort along q that moves the pendulum as q(t):
  // (m L^2 + Ic) q'' = tau + m g L cos q.
  double effort(double q, double q_ddot) const { return (m * L * L + Ic) * q_ddot - m * kG * L * std::cos(q); }
};

TEST(Drive, ConstantSpeedPendulumNeedsTheGravityTorque) {
  const double w = 2.0 * M_PI;  // 60 rpm
  DrivenPendulum p(DriveProfile::velocity(w), 0.3);
  const double h = 1e-3;
  double worst = 0, worst_q = 0, worst_energy = 0;
  double E_prev = p.mech.kineticEnergy() + p.mech.potentialEnergy(), work = 0, tau_prev = p.mech.jointEffort(0, 0);
  for (int k = 1; k <= 2000; ++k) {
    p.mech.step(h);
    const double t = k * h, q = 0.3 + w * t;
    worst_q = std::max(worst_q, std::fabs(p.mech.jointPosition(0, 0) - q));
    const double tau = p.mech.jointEffort(0, 0);
    worst = std::max(worst, std::fabs(tau - p.effort(q, 0.0)));
    // energy balance: the drive's work (trapezoidal in tau w) is the change of T + V
    work += 0.5 * h * w * (tau + tau_prev);
    tau_prev = tau;
    const double E = p.mech.kineticEnergy() + p.mech.potentialEnergy();
    worst_energy = std::max(worst_energy, std::fabs(E - E_prev - work));
  }
  const double scale = p.m * kG * p.L;
  std::printf("constant-speed drive: |q - w t| %.2e rad, |tau - tau_exact| %.2e N m (of %.2f), energy balance %.2e J\n",
              worst_q, worst, scale, worst_energy);
  EXPECT_LT(worst_q, 1e-12);
  EXPECT_LT(worst, 1e-9 * scale);
  EXPECT_LT(worst_energy, 1e-5 * scale);  // the trapezoidal rule's own error: w^3 h^2 T / 12 scale
  EXPECT_EQ(p.mech.solverStats().shortfalls(), 0);
}

TEST(Drive, HarmonicPendulumEffortIsTheInverseDynamics) {
  const double a = 0.2, b = 0.7, f = 1.5, phase = 0.4, W = 2 * M_PI * f;
  DrivenPendulum p(DriveProfile::harmonic(a, b, f, phase));
  EXPECT_NEAR(p.mech.jointPosition(0, 0), a + b * std::sin(phase), 1e-12);
  EXPECT_NEAR(p.mech.jointVelocity(0, 0), b * W * std::cos(phase), 1e-12);
  double worst = 0;
  for (int k = 1; k <= 1500; ++k) {
    p.mech.step(1e-3);
    const double t = k * 1e-3, q = a + b * std::sin(W * t + phase), q_ddot = -b * W * W * std::sin(W * t + phase);
    worst = std::max(worst, std::fabs(p.mech.jointEffort(0, 0) - p.effort(q, q_ddot)));
    ASSERT_NEAR(p.mech.jointPosition(0, 0), q, 1e-11);
  }
  std::printf("harmonic drive: worst effort error %.2e N m\n", worst);
  EXPECT_LT(worst, 1e-9 * p.m * kG * p.L);
}

// A fully driven mechanism is a kinematic analysis: its accelerations are the second
// differences of the positions it passes through (five-point central differences: their
// truncation h^4 x^(6) / 90 is about 1e-10 here, the positions' round-off of ~1e-13 m
// amplified by 64 / (12 h^2) about 5e-7 m/s^2).
// A drive (and a limit) on a joint of a tree is a row of that joint's block in the KKT
// factorization: a stage solve of a driven chain is exact in one pass, as an undriven one
// is (weighted instead, its round-off took a second pass on every solve).
TEST(Drive, DrivenChainSolvesInOnePass) {
  Mechanism m;
  models::pendulumChain(m, 20, 0.5, 1.0, 0.3);
  m.addDrive(0, 0, DriveProfile::velocity(2.0), 0.0);
  m.build();
  m.assemble();
  for (int k = 0; k < 200; ++k) m.step(1e-3);
  const SolverStats& st = m.solverStats();
  EXPECT_EQ(st.shortfalls(), 0) << st.describe();
  const double per_solve = static_cast<double>(st.solve_passes) / st.solves;
  EXPECT_LE(per_solve, 1.2) << st.describe();
  EXPECT_NEAR(m.jointPosition(0, 0), 2.0 * 0.2, 1e-12);
}

TEST(Drive, FullyDrivenAccelerationsAreSecondDifferencesOfPositions) {
  DrivenPendulum p(DriveProfile::harmonic(0.0, 1.0, 1.0, 0.0));
  const double h = 1e-3;
  std::vector<Vector3d> r;
  std::vector<Eigen::VectorXd> acc;
  for (int k = 0; k < 800; ++k) {
    r.push_back(p.mech.position(p.body));
    acc.push_back(p.mech.state().acc);
    p.mech.step(h);
  }
  double worst = 0, scale = 0;
  for (size_t k = 2; k + 2 < r.size(); ++k) {
    const Vector3d fd = (-r[k + 2] + 16 * r[k + 1] - 30 * r[k] + 16 * r[k - 1] - r[k - 2]) / (12 * h * h);
    worst = std::max(worst, (fd - acc[k].head<3>()).norm());
    scale = std::max(scale, fd.norm());
  }
  std::printf("fully driven: |a - second difference| %.2e of %.2f m/s^2\n", worst, scale);
  EXPECT_LT(worst, 1e-7 * scale);
}

TEST(Drive, VelocityCommandRampsAtTheGivenAcceleration) {
  DrivenPendulum p(DriveProfile::velocity(1.0));
  for (int k = 0; k < 1000; ++k) p.mech.step(1e-3);
  const double q1 = p.mech.jointPosition(0, 0);
  EXPECT_NEAR(q1, 1.0, 1e-12);
  p.mech.commandDriveVelocity(0, 3.0, 2.0);  // 1 s of ramp
  const Mechanism::Snapshot snap = p.mech.snapshot();
  for (int k = 0; k < 500; ++k) p.mech.step(1e-3);
  EXPECT_NEAR(p.mech.jointVelocity(0, 0), 2.0, 1e-12);
  for (int k = 0; k < 1500; ++k) p.mech.step(1e-3);
  EXPECT_NEAR(p.mech.jointVelocity(0, 0), 3.0, 1e-12);
  EXPECT_NEAR(p.mech.jointPosition(0, 0), q1 + 1.0 + 0.5 * 2.0 + 3.0 * 1.0, 1e-10);
  const Eigen::VectorXd x = p.mech.state().x;
  p.mech.restore(snap);  // the ramp is in the State: a continuation is bit-identical
  for (int k = 0; k < 2000; ++k) p.mech.step(1e-3);
  EXPECT_EQ((p.mech.state().x - x).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_THROW(p.mech.commandDriveVelocity(0, NAN, 1.0), UsageError);
  EXPECT_THROW(p.mech.commandDriveVelocity(0, 1.0, 0.0), UsageError);
}

TEST(Drive, ProfileDrivesTakeNoVelocityCommand) {
  DrivenPendulum p(DriveProfile::harmonic(0, 1, 1, 0));
  EXPECT_THROW(p.mech.commandDriveVelocity(0, 1.0, 1.0), UsageError);
}

TEST(Drive, SplineInterpolatesAndIsTwiceContinuouslyDifferentiable) {
  const std::vector<double> t = {0.0, 0.4, 1.0, 1.7, 2.0}, q = {0.0, 1.0, -0.5, 0.3, 0.3};
  const DriveProfile s = DriveProfile::spline(t, q);
  const DriveRamp none;
  double f, fd, fdd, f2, fd2, fdd2;
  for (size_t i = 0; i < t.size(); ++i) {
    s.eval(t[i], none, &f, &fd, &fdd);
    EXPECT_NEAR(f, q[i], 1e-14);
    const double e = 1e-9;  // both sides of the knot
    s.eval(t[i] - e, none, &f, &fd, &fdd);
    s.eval(t[i] + e, none, &f2, &fd2, &fdd2);
    EXPECT_NEAR(f, f2, 1e-7);
    EXPECT_NEAR(fd, fd2, 1e-6);
    EXPECT_NEAR(fdd, fdd2, 1e-6);
  }
  s.eval(t.front(), none, &f, &fd, &fdd);
  EXPECT_NEAR(fdd, 0.0, 1e-12);  // natural ends
  s.eval(t.back(), none, &f, &fd, &fdd);
  EXPECT_NEAR(fdd, 0.0, 1e-12);
  // derivatives against central differences, inside and past the ends
  for (double x : {-0.5, 0.1, 0.7, 1.3, 1.9, 2.6}) {
    const double e = 1e-5;
    double fp, fm, dp, dm, unused;
    s.eval(x, none, &f, &fd, &fdd);
    s.eval(x + e, none, &fp, &dp, &unused);
    s.eval(x - e, none, &fm, &dm, &unused);
    EXPECT_NEAR(fd, (fp - fm) / (2 * e), 1e-8) << x;
    EXPECT_NEAR(fdd, (dp - dm) / (2 * e), 1e-7) << x;
  }
  EXPECT_THROW(DriveProfile::spline({0.0}, {1.0}), UsageError);
  EXPECT_THROW(DriveProfile::spline({0.0, 1.0, 1.0}, {1.0, 2.0, 3.0}), UsageError);
  EXPECT_THROW(DriveProfile::spline({0.0, NAN}, {1.0, 2.0}), UsageError);
  EXPECT_THROW(DriveProfile::velocity(INFINITY), UsageError);
}

TEST(Drive, DrivingACoordinateTwiceOrWithoutPositionIsRefused) {
  Mechanism m;
  Body b;
  b.name = "b";
  b.m = 1;
  b.Jp = Matrix3d::Identity();
  const int i = m.addBody(b);
  m.addJoint(makeJoint("revolute", "j", Mechanism::kGround, JointFrame(), i, JointFrame()));
  m.addDrive(0, 0, DriveProfile::velocity(1));
  EXPECT_THROW(m.addDrive(0, 0, DriveProfile::velocity(2)), ModelError);
  EXPECT_THROW(m.addDrive(0, 1, DriveProfile::velocity(2)), UsageError);
}

// A drive that moves its joint past the joint's limits stops the run naming the joint,
// instead of fighting the stop (two equations on one coordinate). The mechanism is left
// at the last accepted step, and its queries describe that state (they read the stepper's
// evaluation, which the failed step had moved): q = 2 t reaches the limit 1 at t = 0.5,
// the arm of length 0.5 then at 0.5 (cos 1, 0, -sin 1).
TEST(Drive, DrivingPastALimitIsAnErrorNamingTheJoint) {
  // in both formulations: a refused step leaves the last accepted state, bit for bit
  for (const char* formulation : {"absolute", "joint"}) {
    SCOPED_TRACE(formulation);
    Mechanism m;
    IntegratorOptions io;
    io.formulation = formulation;
    m.setIntegrator(io);
    Body b;
    b.name = "arm";
    b.m = 1;
    b.Jp = 0.01 * Matrix3d::Identity();
    b.r = Vector3d(0.5, 0, 0);
    const int i = m.addBody(b);
    m.addJoint(makeJoint("revolute", "elbow", Mechanism::kGround, models::axisY(Vector3d::Zero()), i,
                         models::axisY(Vector3d(-0.5, 0, 0))));
    m.setJointLimits(0, 0, -1.0, 1.0);
    m.addDrive(0, 0, DriveProfile::velocity(2.0));
    m.build();
    m.assemble();
    // the state and the queries before each step: after the failed one, those of the last accepted
    State before_error = m.state();
    double q = NAN, q_dot = NAN, effort = NAN;
    Vector3d r = Vector3d::Constant(NAN);
    try {
      for (int k = 0; k < 1000; ++k) {
        before_error = m.state();
        q = m.jointPosition(0, 0);
        q_dot = m.jointVelocity(0, 0);
        effort = m.jointEffort(0, 0);
        r = m.position(i);
        m.step(1e-3);
      }
      ADD_FAILURE() << "driven past the limit";
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find("the drive of joint 'elbow' moves it to"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("past its limits [-1, 1]"), std::string::npos) << e.what();
    }
    EXPECT_EQ(m.time(), before_error.t);
    EXPECT_EQ(m.state().steps, before_error.steps);
    EXPECT_EQ((m.state().x - before_error.x).cwiseAbs().maxCoeff(), 0.0);
    EXPECT_EQ((m.state().u - before_error.u).cwiseAbs().maxCoeff(), 0.0);
    EXPECT_EQ(m.jointPosition(0, 0), q);
    EXPECT_EQ(m.jointVelocity(0, 0), q_dot);
    EXPECT_EQ(m.jointEffort(0, 0), effort);
    EXPECT_EQ((m.position(i) - r).cwiseAbs().maxCoeff(), 0.0);
    EXPECT_NEAR(m.time(), 0.5, 1e-12);
    EXPECT_NEAR(m.jointPosition(0, 0), 1.0, 1e-12);
    EXPECT_NEAR(m.jointVelocity(0, 0), 2.0, 1e-12);
    EXPECT_LT((m.position(i) - 0.5 * Vector3d(std::cos(1.0), 0, -std::sin(1.0))).norm(), 1e-12);
  }
}

}  // namespace
}  // namespace mechanism_sim
