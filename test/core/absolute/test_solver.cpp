// The solver reaches RK4's truncation error, whatever the units and wherever the
// mechanism is: h^4 convergence on a pendulum and a four-bar, 1e-10 m on the pendulum at
// 1 ms, the same motion in metres and in millimetres, a 1 g pendulum beside a 10 t body,
// a pendulum 1e5 m from the origin, and a bit-identical continuation from a snapshot.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "bodies.h"
#include "compare.h"
#include "mechanism_sim/core/models.h"
#include "pendulum.h"

namespace mechanism_sim {
namespace {



double pendulumError(const Pendulum& p, double h, double T, SolverStats* stats = nullptr,
                     const std::string& method = "rk4") {
  Mechanism m;
  const int b = p.add(m);
  IntegratorOptions io;
  io.method = method;
  m.setIntegrator(io);
  m.build();
  m.assemble();
  for (long k = 0, n = std::lround(T / h); k < n; ++k) m.step(h);
  if (stats) *stats = m.solverStats();
  return (m.position(b) - p.exact(T)).norm();
}

TEST(Solver, PendulumAtOneMillisecondIsWithin1e10MetresAfter10Seconds) {
  SolverStats stats;
  const double err = pendulumError(Pendulum(), 1e-3, 10.0, &stats);
  std::printf("pendulum error after 10 s at 1 ms: %.3e m (%s)\n", err, stats.describe().c_str());
  EXPECT_LT(err, 1e-10);
  EXPECT_EQ(stats.shortfalls(), 0);
}

// Errors fall as h^4 (ratio 16 per halving) down to about 1e-12 m. The smaller the step,
// the fewer steps drift past position_tol (at 0.5 ms almost none), and the position
// projection's own O(h^5) share of the error goes with them, so the last halving gains
// more than 16: there it must gain at least 12 and end below 1e-12 m.
TEST(Solver, PendulumErrorFallsAsHToTheFourth) {
  const double T = 2.0;
  double previous = 0;
  for (double h : {8e-3, 4e-3, 2e-3, 1e-3, 5e-4}) {
    const double err = pendulumError(Pendulum(), h, T);
    std::printf("pendulum h = %g: error %.3e\n", h, err);
    if (previous > 0) {
      EXPECT_GT(previous / err, 12.0) << "h = " << h;
      if (h >= 1e-3) {
        EXPECT_LT(previous / err, 20.0) << "h = " << h;
      }
    }
    previous = err;
  }
  EXPECT_LT(previous, 1e-12);
}

// rk3 (Kutta's third-order method): errors fall as h^3 (ratio 8 per halving), and an
// undamped oscillation does not gain energy (its stability region holds the imaginary
// axis up to sqrt(3), Heun's none of it); it loses a little (|R(i y)| < 1 there).
TEST(Solver, Rk3ErrorFallsAsHCubedAndKeepsTheEnergy) {
  const double T = 2.0;
  double previous = 0;
  for (double h : {4e-3, 2e-3, 1e-3, 5e-4}) {
    const double err = pendulumError(Pendulum(), h, T, nullptr, "rk3");
    std::printf("pendulum rk3 h = %g: error %.3e\n", h, err);
    if (previous > 0) {
      EXPECT_GT(previous / err, 6.0) << "h = " << h;
      EXPECT_LT(previous / err, 10.0) << "h = " << h;
    }
    previous = err;
  }
  Mechanism m;
  models::fourBarChain(m, 1, 0.4, 1.0, 1.2);
  IntegratorOptions io;
  io.method = "rk3";
  m.setIntegrator(io);
  m.build();
  m.assemble();
  const double E0 = m.kineticEnergy() + m.potentialEnergy();
  double gain = 0, loss = 0;
  for (int k = 0; k < 20000; ++k) {
    m.step(1e-3);
    const double dE = m.kineticEnergy() + m.potentialEnergy() - E0;
    gain = std::max(gain, dE), loss = std::max(loss, -dE);
  }
  std::printf("four-bar rk3, 20 s at 1 ms: energy gain %.2e J, loss %.2e J of %.2f\n", gain, loss, std::fabs(E0));
  EXPECT_LT(gain, 1e-8 * std::fabs(E0));  // round-off of the projections
  EXPECT_LT(loss, 1e-5 * std::fabs(E0));
}

// The four-bar (dependent equations, a closed loop): self-convergence of the crank angle
// (largest error over 8 sample times in 1 s) against a run at 1/64 ms; ratio 16 per halving.
TEST(Solver, FourBarErrorFallsAsHToTheFourth) {
  auto run = [](double h) {
    Mechanism m;
    models::fourBarChain(m, 1, 0.4, 1.0, 1.2);
    m.build();
    m.assemble();
    std::vector<double> samples;
    const long n = std::lround(1.024 / h);  // a whole number of steps at every h
    for (long k = 1; k <= n; ++k) {
      m.step(h);
      if (k % (n / 8) == 0) samples.push_back(m.jointPosition(0, 0));
    }
    return samples;
  };
  const std::vector<double> ref = run(1e-3 / 64);
  double previous = 0;
  for (double h : {4e-3, 2e-3, 1e-3}) {
    const std::vector<double> q = run(h);
    double err = 0;
    for (size_t k = 0; k < ref.size(); ++k) err = std::max(err, std::fabs(q[k] - ref[k]));
    std::printf("four-bar h = %g: error %.3e rad\n", h, err);
    if (previous > 0) {
      EXPECT_GT(previous / err, 12.0) << "h = " << h;
      EXPECT_LT(previous / err, 20.0) << "h = " << h;
    }
    previous = err;
  }
}

// Velocities left off the constraints let the constraint forces do work, and the error
// stops falling as h^4. With the velocities projected to 1e-13 (relative) the pendulum at
// 0.5 ms ended 1.0e-11 m off after 10 s, ten times what 1 ms (2.2e-11) and h^4 give; at
// 1e-14 it ends 1e-12 m off (the exact solution itself is good to 2.4e-13 m).
TEST(Solver, PendulumAtHalfAMillisecondKeepsFallingAsHToTheFourth) {
  SolverStats stats;
  const double err = pendulumError(Pendulum(), 5e-4, 10.0, &stats);
  std::printf("pendulum error after 10 s at 0.5 ms: %.3e m (%s)\n", err, stats.describe().c_str());
  EXPECT_LT(err, 2.2e-11 / 16.0 + 5e-13);
  EXPECT_EQ(stats.shortfalls(), 0);
}

// Energy of the pendulum over 10 s at 0.5 ms: conserved to the level of round-off.
TEST(Solver, PendulumEnergyIsConservedToTruncationLevel) {
  Mechanism m;
  Pendulum().add(m);
  m.build();
  m.assemble();
  const double E0 = m.kineticEnergy() + m.potentialEnergy();
  double worst = 0;
  for (int k = 0; k < 20000; ++k) {
    m.step(5e-4);
    worst = std::max(worst, std::fabs(m.kineticEnergy() + m.potentialEnergy() - E0));
  }
  EXPECT_LT(worst, 1e-11 * m.body(1).m * kG * 1.0);
}

// A four-bar with parameters in metres and the same one in millimetres (lengths x 1000,
// inertias x 1e6, g x 1000): the same angles, and the same accuracy, after 2 s.
TEST(Solver, MetresAndMillimetresGiveTheSameMotion) {
  auto run = [](double s) {
    Mechanism m;
    const double r = 0.3 * s, d = 1.0 * s, c = 0.9 * s;  // crank, ground, coupler, rocker 0.8
    const double rocker = 0.8 * s;
    // crank pivot at 0, rocker pivot at (d, 0, 0); start with the crank at 60 degrees
    const Vector3d A(0, 0, 0), D(d, 0, 0);
    const Vector3d B = A + r * Vector3d(std::cos(1.0), 0, std::sin(1.0));
    // C: intersection of circles |C - B| = c, |C - D| = rocker (upper branch)
    const Vector3d BD = D - B;
    const double L = BD.norm(), a = (c * c - rocker * rocker + L * L) / (2 * L);
    const double hgt = std::sqrt(c * c - a * a);
    const Vector3d e = BD / L, n(-e.z(), 0, e.x());
    const Vector3d C = B + a * e + hgt * n;
    auto rod = [&](const std::string& name, const Vector3d& p, const Vector3d& q, double mass) {
      Body b = body(name, mass, Matrix3d::Zero(), 0.5 * (p + q));
      const double len = (q - p).norm();
      const Vector3d x = (q - p) / len;
      b.p = Quaterniond::FromTwoVectors(Vector3d::UnitX(), x);
      b.Jp = Vector3d(1e-4 * mass * s * s, mass * len * len / 12, mass * len * len / 12).asDiagonal();
      return m.addBody(b);
    };
    const int crank = rod("crank", A, B, 1.0), coupler = rod("coupler", B, C, 2.0),
              rock = rod("rocker", D, C, 1.5);
    auto at = [&](int b, const Vector3d& P) {
      const Body& bb = m.body(b);
      JointFrame f = models::axisY(bb.p.conjugate() * (P - bb.r));
      f.Rp = bb.p.conjugate().toRotationMatrix() * f.Rp;
      return f;
    };
    m.addJoint(makeJoint("revolute", "a", Mechanism::kGround, models::axisY(A), crank, at(crank, A)));
    m.addJoint(makeJoint("revolute", "b", crank, at(crank, B), coupler, at(coupler, B)));
    m.addJoint(makeJoint("revolute", "c", coupler, at(coupler, C), rock, at(rock, C)));
    m.addJoint(makeJoint("revolute", "d", Mechanism::kGround, models::axisY(D), rock, at(rock, D)));
    m.setGravity(Vector3d(0, 0, -kG * s));
    m.build();
    m.assemble({}, {CoordinateTarget{0, 0, 2.0}});
    for (int k = 0; k < 2000; ++k) m.step(1e-3);
    EXPECT_EQ(m.solverStats().shortfalls(), 0) << m.solverStats().describe();
    return std::array<double, 3>{m.jointPosition(0, 0), m.jointPosition(1, 0), m.positionViolation() / s};
  };
  const auto metres = run(1.0), millimetres = run(1000.0), micro = run(1e-3);
  for (int k = 0; k < 2; ++k) {
    EXPECT_NEAR(metres[k], millimetres[k], 1e-9) << k;
    EXPECT_NEAR(metres[k], micro[k], 1e-9) << k;
  }
  EXPECT_LT(millimetres[2], 1e-12);
  EXPECT_LT(micro[2], 1e-12);
}

// A 1 g pendulum beside an unconnected 10 t body keeps its own motion: each body's
// equations are weighted by the masses they couple, not by one global number.
TEST(Solver, LightPendulumBesideHeavyBodyKeepsItsPeriod) {
  Pendulum light;
  light.m = 1e-3;
  light.Ic = 1e-9;
  Mechanism alone, beside;
  const int b1 = light.add(alone);
  const int b2 = light.add(beside);
  beside.addBody(body("block", 1e4, 1e3 * Matrix3d::Identity(), Vector3d(5, 0, 0)));
  for (Mechanism* m : {&alone, &beside}) {
    m->build();
    m->assemble();
    for (int k = 0; k < 2000; ++k) m->step(1e-3);
  }
  EXPECT_LT((alone.position(b1) - beside.position(b2)).norm(), 1e-12);
  EXPECT_LT((beside.position(b2) - light.exact(2.0)).norm(), 1e-9);
  EXPECT_EQ(beside.solverStats().shortfalls(), 0) << beside.solverStats().describe();
}

// A pendulum 1e5 m from the origin: tolerances follow the coordinates' own size, so every
// iteration still converges (no 40 Newton iterations a step) and the motion is right to
// what the coordinates can hold (1e5 m carries ~1e-11 m of round-off).
TEST(Solver, PendulumFarFromTheOriginConvergesEveryStep) {
  Pendulum far;
  far.pivot = Vector3d(1e5, -2e4, 3e4);
  SolverStats stats;
  const double err = pendulumError(far, 1e-3, 2.0, &stats);
  EXPECT_LT(err, 1e-7);
  EXPECT_EQ(stats.shortfalls(), 0) << stats.describe();
  EXPECT_LE(stats.factorizations, 4 * 2000 + 10);
}

// The joints of a tree are block rows of the factored KKT matrix: a stage solve is exact
// up to round-off whatever the chain's length, so the refinement passes a solve takes do
// not grow along a chain (in penalty form they did, the contraction per pass falling like
// 1 / N^2: 2.7 passes a stage solve at N = 50, 3.6 at N = 400) and the cost of a step stays
// linear in the bodies.
TEST(Solver, RefinementPassesDoNotGrowAlongAChain) {
  double per_solve[2] = {0, 0};
  const int sizes[2] = {5, 120};
  for (int k = 0; k < 2; ++k) {
    Mechanism m;
    models::pendulumChain(m, sizes[k], 0.5, 1.0, 0.3);
    m.build();
    m.assemble();
    for (int i = 0; i < 100; ++i) m.step(1e-3);
    const SolverStats& st = m.solverStats();
    EXPECT_EQ(st.shortfalls(), 0) << st.describe();
    per_solve[k] = static_cast<double>(st.solve_passes) / st.solves;
  }
  EXPECT_LE(per_solve[0], 1.2);
  EXPECT_LE(per_solve[1], per_solve[0] + 0.2) << "N = 5: " << per_solve[0] << ", N = 120: " << per_solve[1];
}

// A snapshot is the State: restoring it and stepping again repeats the run bit for bit,
// inputs changing between steps included.
TEST(Solver, SnapshotRestoreContinuesBitIdentically) {
  Mechanism m;
  models::fourBarChain(m, 2, 0.4, 1.0, 1.2);
  m.setJointDamping(0, 0, 0.01);
  m.build();
  m.assemble();
  for (int k = 0; k < 100; ++k) m.step(1e-3);
  const auto [a, b] = test_util::runTwiceFromSnapshot(m, 300);
  EXPECT_EQ(a.t, b.t);
  for (int i = 0; i < a.x.size(); ++i) ASSERT_EQ(a.x[i], b.x[i]) << i;
  for (int i = 0; i < a.u.size(); ++i) ASSERT_EQ(a.u[i], b.u[i]) << i;
  EXPECT_EQ(a.tracked, b.tracked);
}


// A wheel at 4000 rad/s with 1 ms steps turns 4 rad a step (more than pi, and beyond
// what RK4 follows): the steps are taken in halves down to 0.25 rad and the tracked angle
// follows its rate, so after 1 s it reads 4000 rad (to RK4's phase error, 5e-7 rad a
// substep), and a nut on a screw spun as fast rises by lead x turns instead of running
// backwards. Ten times faster is refused with
// the body named.
TEST(Solver, AngleTrackedThroughMoreThanPiPerStep) {
  for (const char* type : {"revolute", "screw"}) {
    Mechanism m;
    const int w = m.addBody(body("wheel", 1.0, Vector3d(0.1, 0.1, 0.2).asDiagonal(), Vector3d::Zero()));
    JointParams params;
    params.alpha = 1e-3 / (2 * M_PI);  // 1 mm per turn
    m.addJoint(makeJoint(type, "axle", Mechanism::kGround, JointFrame(), w, JointFrame(), params));
    m.setGravity(Vector3d::Zero());
    m.build();
    m.assemble({}, {CoordinateTarget{0, 0, 4000.0}});
    for (int k = 0; k < 1000; ++k) m.step(1e-3);
    EXPECT_NEAR(m.jointPosition(0, 0), 4000.0, 1e-2) << type;
    if (std::string(type) == "screw") {
      EXPECT_NEAR(m.position(w).z(), params.alpha * 4000.0, 1e-2 * params.alpha);
    }
    EXPECT_EQ(m.solverStats().shortfalls(), 0) << type << ": " << m.solverStats().describe();
    EXPECT_EQ(m.solverStats().halved_steps, 1000 * 15) << type;  // 16 substeps a step
  }
  Mechanism m;
  const int w = m.addBody(body("turbine", 1.0, Matrix3d::Identity(), Vector3d::Zero()));
  m.addJoint(makeJoint("revolute", "axle", Mechanism::kGround, JointFrame(), w, JointFrame()));
  m.build();
  m.assemble({}, {CoordinateTarget{0, 0, 4e4}});
  try {
    m.step(1e-3);
    ADD_FAILURE() << "40 rad in a step taken";
  } catch (const SimulationError& e) {
    EXPECT_NE(std::string(e.what()).find("body 'turbine' turns 40 rad in one step"), std::string::npos) << e.what();
  }
}

// A step that fails part way (here a turbine spun up past what 64 substeps follow during
// the step, not at its start) leaves the State at the last accepted step, not after the
// substeps it had taken.
TEST(Solver, AFailedStepLeavesTheStateWhereItWas) {
  Mechanism m;
  const int w = m.addBody(body("turbine", 1.0, Matrix3d::Identity(), Vector3d::Zero()));
  m.addJoint(makeJoint("revolute", "axle", Mechanism::kGround, JointFrame(), w, JointFrame()));
  m.setGravity(Vector3d::Zero());
  m.build();
  m.assemble({}, {CoordinateTarget{0, 0, 15900.0}});  // 15.9 rad a step: 64 substeps of 0.248
  m.setJointEffort(0, 0, 1e6);                          // +1000 rad/s within the step
  const Mechanism::Snapshot before = m.snapshot();
  EXPECT_THROW(m.step(1e-3), SimulationError);
  EXPECT_EQ(m.time(), before.t);
  EXPECT_EQ(m.stepsTaken(), before.steps);
  EXPECT_EQ((m.state().x - before.x).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ((m.state().u - before.u).cwiseAbs().maxCoeff(), 0.0);
}


// A heavy turntable spinning at 20 rad/s carries a 1 kg slider on a radial prismatic
// joint at 0.5 m with Coulomb friction 2000 N: m W^2 q = 200 N, so it must stick. The
// sticking effort includes the coordinate's own velocity term (gamma of q).
TEST(Friction, SliderOnSpinningTurntableSticks) {
  Mechanism m;
  const int t = m.addBody(body("table", 1000.0, Vector3d(1e6, 1e6, 2e6).asDiagonal(), Vector3d::Zero()));
  const int s = m.addBody(body("slider", 1.0, 1e-3 * Matrix3d::Identity(), Vector3d(0.5, 0, 0)));
  m.addJoint(makeJoint("revolute", "spindle", Mechanism::kGround, JointFrame(), t, JointFrame()));
  JointFrame radial;  // z along x of the table
  radial.Rp = Eigen::AngleAxisd(M_PI / 2, Vector3d::UnitY()).toRotationMatrix();
  JointFrame on_slider = radial;
  m.addJoint(makeJoint("prismatic", "rail", t, radial, s, on_slider));
  m.setJointFriction(1, 0, 2000.0);
  m.setGravity(Vector3d::Zero());
  m.build();
  m.assemble({CoordinateTarget{1, 0, 0.5}}, {CoordinateTarget{0, 0, 20.0}});
  for (int k = 0; k < 2000; ++k) m.step(1e-3);
  EXPECT_NEAR(m.jointPosition(1, 0), 0.5, 1e-9);
  EXPECT_NEAR(m.jointVelocity(0, 0), 20.0, 1e-3);
}

// Friction sized with the step being taken: a 1 kg slider at 5 mm/s against 10 N, run
// with 10 ms steps, stops and stays (no reversal, no energy gained).
// A 1 kg block on a prismatic joint to ground along z.
void addSlider(Mechanism& m, const std::string& name) {
  const int id = m.addBody(body(name, 1.0, 1e-3 * Matrix3d::Identity(), Vector3d::Zero()));
  m.addJoint(makeJoint("prismatic", "slide", Mechanism::kGround, JointFrame(), id, JointFrame()));
}

TEST(Friction, LargeStepStopsWithoutReversal) {
  Mechanism m;
  addSlider(m, "block");
  m.setJointFriction(0, 0, 10.0);
  m.setGravity(Vector3d::Zero());
  m.build();
  m.assemble({}, {CoordinateTarget{0, 0, 0.005}});
  const double E0 = m.kineticEnergy();
  for (int k = 0; k < 20; ++k) {
    const double q = m.jointPosition(0, 0);
    m.step(1e-2);
    EXPECT_GE(m.jointPosition(0, 0), q - 1e-15) << k;  // never moves back
    EXPECT_LE(m.kineticEnergy(), E0 * (1 + 1e-12)) << k;
  }
  EXPECT_NEAR(m.jointVelocity(0, 0), 0.0, 1e-12);
}

// A 1 kg puck on a planar joint slides at (3, 1) m/s against Coulomb friction 2 N: the
// friction force has magnitude 2 N opposite the velocity (a disc, not a box), so the puck
// decelerates at 2 m/s^2 along a straight line and stops after |v|^2 / (2 a) = 2.5 m at
// (3, 1) / sqrt(10) * 2.5. A box (2 N per axis) would stop y first and bend the path.
TEST(Friction, PlanarFrictionIsADiscNotABox) {
  Mechanism m;
  const int id = m.addBody(body("puck", 1.0, 1e-3 * Matrix3d::Identity(), Vector3d::Zero()));
  m.addJoint(makeJoint("planar", "table", Mechanism::kGround, JointFrame(), id, JointFrame()));
  for (int k = 0; k < 3; ++k) m.setJointFriction(0, k, 2.0);
  m.setGravity(Vector3d::Zero());
  m.build();
  m.assemble({}, {CoordinateTarget{0, 0, 3.0}, CoordinateTarget{0, 1, 1.0}});
  const Vector3d direction = Vector3d(3, 1, 0).normalized();
  double off_line = 0;
  for (int k = 0; k < 2000; ++k) {
    m.step(1e-3);
    const Vector3d p(m.jointPosition(0, 0), m.jointPosition(0, 1), 0);
    off_line = std::max(off_line, p.cross(direction).norm());
  }
  const Vector3d end(m.jointPosition(0, 0), m.jointPosition(0, 1), 0);
  std::printf("planar friction: end (%.9f, %.9f), off the line %.2e m\n", end.x(), end.y(), off_line);
  EXPECT_LT((end - 2.5 * direction).norm(), 1e-6);
  EXPECT_LT(off_line, 1e-9);
  EXPECT_NEAR(m.jointVelocity(0, 0), 0.0, 1e-12);
  EXPECT_NEAR(m.jointVelocity(0, 1), 0.0, 1e-12);
}

// Starting outside a limit is an error naming the joint, not a jump.
TEST(Limits, InitialPositionOutsideTheLimitsIsAnError) {
  Mechanism m;
  addSlider(m, "carriage");
  m.setJointLimits(0, 0, -0.5, 0.5);
  m.build();
  try {
    m.assemble({CoordinateTarget{0, 0, -5.0}});
    ADD_FAILURE() << "assembled outside the limits";
  } catch (const ModelError& e) {
    EXPECT_EQ(std::string(e.what()), "joint 'slide': initial position -5 is outside its limits [-0.5, 0.5]");
  }
}


}  // namespace
}  // namespace mechanism_sim
