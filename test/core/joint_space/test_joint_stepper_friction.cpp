// Damping on spherical joints and Coulomb friction in the joint formulation
// (joint_stepper.cpp), against known answers and against the absolute formulation, which
// defines both: a spherical joint's damping acts per coordinate of its relative angular
// velocity in frame i (Joint::coordinates, appliedForces), and friction is sized for each
// step to stop the coordinate within it, at most f (Stepper::frictionFor, coulombFriction).
//   - a sphere spinning on a damped ball joint (no gravity): each frame-i component of its
//     angular velocity decays as exp(-c_k t / I), its rotation angle as w0 I / c (1 -
//     exp(-c t / I)); stiff components (h c / I = 1000) by implicit Euler, 1 / (1 + h c / I)
//     a step, the others by RK4's amplification, in the same joint;
//   - a damped spherical double pendulum on a spinning arm (frame i moving, one joint
//     written child-first): both formulations agree on the positions after 1 s;
//   - a block under a constant effort below the breakaway friction stays put, above it
//     slides at (tau - f) / m; a block sliding freely stops after m v0^2 / 2f; a wheel the
//     same in rotation; a puck on a planar joint slides along a straight line (a disc);
//     a slider on a turntable sticks against its centripetal load; in both formulations;
//   - a chain with friction and damping on a moving base, and a ball joint with friction on
//     a spinning arm: both formulations agree.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <functional>
#include <string>

#include "bodies.h"
#include "compare.h"
#include "mechanism_sim/core/mechanism.h"
#include "mechanism_sim/core/models.h"

namespace mechanism_sim {
namespace {

using test_util::body;
using test_util::frame;

const char* const kFormulations[] = {"absolute", "joint"};

IntegratorOptions formulation(const char* f) {
  IntegratorOptions io;
  io.formulation = f;
  io.method = "rk4";
  return io;
}

// `model` adds the mechanism; built in formulation f and assembled (with the velocity
// targets).
void buildIn(Mechanism& m, const char* f, const std::function<void(Mechanism&)>& model,
             const std::vector<CoordinateTarget>& velocities = {}) {
  model(m);
  m.setIntegrator(formulation(f));
  m.build();
  m.assemble({}, velocities);
  ASSERT_STREQ(m.formulation(), f) << m.formulationReason();
}

using test_util::difference;  // (compare.h)

// ---- damping on spherical joints

// A sphere (isotropic inertia I) on a ball joint to ground at its centre, no gravity, frame
// i turned by R; damping c_k per coordinate. Euler's equations with I isotropic have no
// gyroscopic term, and frame i is fixed: I d/dt w_k = -c_k w_k for the frame-i components,
// w_k = w0_k exp(-c_k t / I), each on its own.
void dampedSphere(Mechanism& m, double I, const Vector3d& c, const Vector3d& w0_global, const Matrix3d& R) {
  Body ball = body("ball", 1.0, Vector3d(I, I, I), Vector3d::Zero());
  ball.w = w0_global;  // (the body starts unrotated: body components are global)
  const int b = m.addBody(ball);
  m.addJoint(makeJoint("spherical", "socket", Mechanism::kGround, frame(Vector3d::Zero(), R), b,
                       frame(Vector3d::Zero(), R)));
  m.setGravity(Vector3d::Zero());
  for (int k = 0; k < 3; ++k) m.setJointDamping(0, k, c(k));
}

const Matrix3d kTurned = Eigen::AngleAxisd(0.7, Vector3d(1, -2, 0.5).normalized()).toRotationMatrix();

TEST(SphericalDamping, EachFrameIComponentDecaysExponentially) {
  const double I = 0.02, h = 1e-3, T = 1.0;
  const Vector3d c(0.01, 0.04, 0.002), w0(3.0, -1.0, 2.0);  // c / I = 0.5, 2, 0.1 per second
  const Vector3d w0_i = kTurned.transpose() * w0;
  Mechanism runs[2];
  for (int f = 0; f < 2; ++f) {
    SCOPED_TRACE(kFormulations[f]);
    Mechanism& m = runs[f];
    buildIn(m, kFormulations[f], [&](Mechanism& mm) { dampedSphere(mm, I, c, w0, kTurned); });
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(m.jointVelocity(0, k), w0_i(k), 1e-14);
    const int n = static_cast<int>(std::lround(T / h));
    for (int s = 0; s < n; ++s) m.step(h);
    double worst = 0;
    for (int k = 0; k < 3; ++k) {
      const double exact = w0_i(k) * std::exp(-c(k) * T / I);
      worst = std::max(worst, std::fabs(m.jointVelocity(0, k) - exact) / std::fabs(w0_i(k)));
      // the damping effort the joint reports, per coordinate
      EXPECT_NEAR(m.jointEffort(0, k), -c(k) * m.jointVelocity(0, k), 1e-15 * c(k) * w0.norm()) << k;
    }
    std::printf("[damped sphere, %s] frame-i rates against exp(-c_k t / I) after %g s: %.2e relative\n",
                kFormulations[f], T, worst);
    // RK4's global error: n (h c / I)^5 / 120 at the fastest rate (2 / s): 3e-14 (the
    // absolute formulation adds its projections' and solves' tolerances: 1.0e-12 measured)
    EXPECT_LT(worst, 3e-12);
  }
  const double d = difference(runs[0], runs[1]);
  std::printf("[damped sphere] joint against absolute after %g s: %.2e\n", T, d);
  EXPECT_LT(d, 1e-12);
}

// Isotropic damping: the spin keeps its axis, and the body turns by w0 I / c (1 - exp(-c t
// / I)) about it: the positions against the known answer (rotation vector of frame j in i).
TEST(SphericalDamping, IsotropicDampingTurnsTheSphereByTheIntegratedRate) {
  const double I = 0.02, cc = 0.03, h = 1e-3, T = 1.0;
  const Vector3d w0(1.0, 0.5, -1.5);
  for (const char* f : kFormulations) {
    SCOPED_TRACE(f);
    Mechanism m;
    buildIn(m, f, [&](Mechanism& mm) { dampedSphere(mm, I, Vector3d::Constant(cc), w0, kTurned); });
    for (int s = 0; s < std::lround(T / h); ++s) m.step(h);
    const Vector3d exact = kTurned.transpose() * w0 * (I / cc) * (1 - std::exp(-cc * T / I));  // 1.2 rad
    const Vector3d got(m.jointPosition(0, 0), m.jointPosition(0, 1), m.jointPosition(0, 2));
    std::printf("[damped sphere, %s] rotation after %g s: %.2e rad from the known %.3f rad\n", f, T,
                (got - exact).norm(), exact.norm());
    EXPECT_LT((got - exact).norm(), 1e-11 * exact.norm());
  }
}

// Stiff spherical damping: a sphere of 1e-7 kg m^2 damped at 0.1 N m s / rad about two of
// frame i's axes (h c / I = 1000 at 1 ms: implicit Euler, 1 / (1 + h c / I) a step) and at
// 1e-9 about the third (h c / I = 0.01: RK4's stages, its amplification a step). The rows of
// a ball joint on a sphere are orthogonal in the inverse mass, so the classification is
// per component, and each component follows its own rule, but for the splitting's position
// move (stiff_damping.cpp, item 4: h (u' - u) / 2 with omega' kept in body components): it
// turns the angular velocity by at most h/2 |u' - u| |omega| a step, the same in both
// formulations (first order, as implicit Euler itself; measured 4 % of the stiff components
// after the first step, when they are already 1000 times smaller; on the stages' component,
// where the first-order terms cancel, 4.5e-8 relative).
TEST(SphericalDamping, StiffComponentsByImplicitEulerTheOthersInTheStages) {
  const double I = 1e-7, h = 1e-3;
  const Vector3d c(0.1, 1e-9, 0.1), w0(0.3, -0.2, 0.5);
  const Vector3d w0_i = kTurned.transpose() * w0;
  auto rk4 = [](double s) { return 1 - s + s * s / 2 - s * s * s / 6 + s * s * s * s / 24; };
  Mechanism runs[2];
  for (int f = 0; f < 2; ++f) {
    SCOPED_TRACE(kFormulations[f]);
    Mechanism& m = runs[f];
    buildIn(m, kFormulations[f], [&](Mechanism& mm) {
      Body ball = body("ball", 1e-3, Vector3d(I, I, I), Vector3d::Zero());
      ball.w = w0;
      const int b = mm.addBody(ball);
      mm.addJoint(makeJoint("spherical", "socket", Mechanism::kGround, frame(Vector3d::Zero(), kTurned), b,
                            frame(Vector3d::Zero(), kTurned)));
      mm.setGravity(Vector3d::Zero());
      for (int k = 0; k < 3; ++k) mm.setJointDamping(0, k, c(k));
    });
    double turn = 0;  // the bound on the splitting's turn of omega so far
    for (int n = 1; n <= 3; ++n) {
      m.step(h);
      turn += h / 2 * w0.norm() * w0.norm();  // (|u' - u| <= |omega| <= |w0|)
      for (int k = 0; k < 3; ++k) {
        const double s = h * c(k) / I;
        const double expected = w0_i(k) * std::pow(s > 2 ? 1 / (1 + s) : rk4(s), n);
        EXPECT_NEAR(m.jointVelocity(0, k), expected, s > 2 ? turn : 1e-7 * std::fabs(w0_i(k)))
            << "step " << n << ", axis " << k;
      }
    }
    for (int n = 3; n < 1000; ++n) m.step(h);
    EXPECT_NEAR(m.jointVelocity(0, 0), 0.0, 1e-15 * w0.norm());
    EXPECT_NEAR(m.jointVelocity(0, 2), 0.0, 1e-15 * w0.norm());
    EXPECT_NEAR(m.jointVelocity(0, 1), w0_i(1) * std::exp(-c(1) / I * 1.0), 1e-7 * std::fabs(w0_i(1)));
    EXPECT_LE(m.kineticEnergy(), 0.5 * I * w0.squaredNorm());
  }
  const double d = difference(runs[0], runs[1]);
  std::printf("[stiff damped sphere] joint against absolute after 1 s: %.2e\n", d);
  EXPECT_LT(d, 1e-10);
}

// A damped spherical double pendulum hanging from an arm that spins on a revolute about z
// (frame i of the first ball joint turns with the arm: the rates are in that moving frame,
// in both formulations). The second ball joint is written child-first (the bob is its body
// i): its coordinates are those of the parent in the child's frame, damped there.
void spinningDoublePendulum(Mechanism& m, double c_scale) {
  Body arm = body("arm", 2.0, Vector3d(0.01, 0.05, 0.05), Vector3d(0.25, 0, 0));
  arm.w = Vector3d(0, 0, 3.0);
  arm.v = Vector3d(0, 0.75, 0);
  const int a = m.addBody(arm);
  m.addJoint(makeJoint("revolute", "spindle", Mechanism::kGround, frame(Vector3d::Zero()), a,
                       frame(Vector3d(-0.25, 0, 0))));
  const Matrix3d R1 = Eigen::AngleAxisd(0.3, Vector3d(1, 1, 0).normalized()).toRotationMatrix();
  Body bob1 = body("bob1", 1.0, Vector3d(0.004, 0.006, 0.008), Vector3d(0.5, 0, -0.3));
  bob1.w = Vector3d(0.5, -1.0, 3.0);
  bob1.v = Vector3d(0.2, 1.5, 0.1);
  const int b1 = m.addBody(bob1);
  m.addJoint(makeJoint("spherical", "shoulder", a, frame(Vector3d(0.25, 0, 0), R1), b1, frame(Vector3d(0, 0, 0.3), R1)));
  const Matrix3d R2 = Eigen::AngleAxisd(-0.8, Vector3d(0, 1, 2).normalized()).toRotationMatrix();
  Body bob2 = body("bob2", 0.5, Vector3d(0.002, 0.003, 0.0025), Vector3d(0.6, 0.1, -0.6));
  bob2.w = Vector3d(-1.0, 0.4, 2.0);
  const int b2 = m.addBody(bob2);
  m.addJoint(makeJoint("spherical", "elbow", b2, frame(Vector3d(-0.1, -0.1, 0.3), R2), b1,
                       frame(Vector3d(0, 0, -0.3), R2)));
  const double c1[3] = {0.004, 0.01, 0.006}, c2[3] = {0.003, 0.002, 0.005};
  for (int k = 0; k < 3; ++k) m.setJointDamping(1, k, c_scale * c1[k]), m.setJointDamping(2, k, c_scale * c2[k]);
}

TEST(SphericalDamping, SpinningDoublePendulumMovesAsInAbsoluteCoordinates) {
  double at[2] = {0, 0};
  const double hs[2] = {1e-3, 5e-4};
  for (int i = 0; i < 2; ++i) {
    Mechanism a, j;
    buildIn(a, "absolute", [](Mechanism& m) { spinningDoublePendulum(m, 1.0); });
    buildIn(j, "joint", [](Mechanism& m) { spinningDoublePendulum(m, 1.0); });
    EXPECT_LT(difference(a, j), 1e-12);  // the same assembled state
    double E = j.kineticEnergy() + j.potentialEnergy();
    for (long s = 0, n = std::lround(1.0 / hs[i]); s < n; ++s) {
      a.step(hs[i]), j.step(hs[i]);
      const double E1 = j.kineticEnergy() + j.potentialEnergy();
      ASSERT_LE(E1, E + 1e-12 * std::fabs(E)) << "t = " << j.time();  // damping only takes energy
      E = E1;
    }
    at[i] = difference(a, j);
    for (int k = 0; k < 3; ++k)
      EXPECT_NEAR(j.jointEffort(1, k), -j.system().damping[1][k] * j.jointVelocity(1, k), 1e-14);
  }
  std::printf("[damped spherical double pendulum on a spinning arm] joint against absolute after 1 s: %.2e at 1 ms, "
              "%.2e at 0.5 ms\n", at[0], at[1]);
  EXPECT_LT(at[0], 1e-8);
  EXPECT_LT(at[1], 1e-9);
  // and the damping does take energy: against the undamped pendulum
  Mechanism free, damped;
  buildIn(free, "joint", [](Mechanism& m) { spinningDoublePendulum(m, 0.0); });
  buildIn(damped, "joint", [](Mechanism& m) { spinningDoublePendulum(m, 1.0); });
  for (int s = 0; s < 1000; ++s) free.step(1e-3), damped.step(1e-3);
  EXPECT_LT(damped.kineticEnergy() + damped.potentialEnergy(), free.kineticEnergy() + free.potentialEnergy() - 1e-3);
}

// ---- Coulomb friction

// A block of mass m on a prismatic joint along z (no gravity) with friction f.
void block(Mechanism& m, double mass, double f) {
  m.addBody(body("block", mass, Vector3d(0.01, 0.01, 0.01), Vector3d::Zero()));
  m.addJoint(makeJoint("prismatic", "rail", Mechanism::kGround, frame(Vector3d::Zero()), 1, frame(Vector3d::Zero())));
  m.setGravity(Vector3d::Zero());
  m.setJointFriction(0, 0, f);
}

// Under a constant effort tau below f the block stays where it is (friction supplies -tau);
// above it slides at a = (tau - f) / m from rest: q = a t^2 / 2, exact for RK4 (friction is
// constant over the steps).
TEST(JointFriction, BlockStaysBelowBreakawayAndSlidesAtTheCoulombRateAbove) {
  const double mass = 2.0, f = 3.0, h = 1e-3, T = 1.0;
  for (double ratio : {0.6, 0.999, 1.5}) {
    const double tau = ratio * f, a = std::max(0.0, (tau - f) / mass);
    Mechanism runs[2];
    for (int i = 0; i < 2; ++i) {
      SCOPED_TRACE(kFormulations[i]);
      Mechanism& m = runs[i];
      buildIn(m, kFormulations[i], [&](Mechanism& mm) { block(mm, mass, f); });
      m.setJointEffort(0, 0, tau);
      for (int s = 0; s < std::lround(T / h); ++s) m.step(h);
      const double free_travel = tau / mass * T * T / 2;  // without friction: the scale
      if (a == 0.0) {
        EXPECT_LE(std::fabs(m.jointPosition(0, 0)), 1e-15 * free_travel) << "tau / f = " << ratio;
        EXPECT_LE(std::fabs(m.jointVelocity(0, 0)), 1e-15 * tau / mass * T) << "tau / f = " << ratio;
        EXPECT_NEAR(m.jointEffort(0, 0), 0.0, 1e-15 * tau);  // friction holds the effort
      } else {
        EXPECT_NEAR(m.jointPosition(0, 0), a * T * T / 2, 1e-13 * free_travel) << "tau / f = " << ratio;
        EXPECT_NEAR(m.jointVelocity(0, 0), a * T, 1e-13 * a * T) << "tau / f = " << ratio;
        EXPECT_NEAR(m.jointEffort(0, 0), tau - f, 1e-15 * tau);
      }
      std::printf("[block, %s] tau / f = %.3f: q = %.3e m (known %.3e)\n", kFormulations[i], ratio,
                  m.jointPosition(0, 0), a * T * T / 2);
    }
    EXPECT_NEAR(runs[0].jointPosition(0, 0), runs[1].jointPosition(0, 0), 1e-14 * (tau / mass));
  }
}

// Sliding at v0 with no effort the block decelerates at f / m and stops at t* = m v0 / f
// after m v0^2 / 2f, then stays. The step that stops it holds friction at the effort that
// stops it within the step: its travel is h v_n / 2 where the exact one is v_n^2 m / 2f,
// at most f h^2 / 2m apart. Never reverses, never gains energy.
TEST(JointFriction, SlidingBlockStopsAtTheKnownDistance) {
  const double mass = 2.0, f = 3.0, v0 = 1.2345, h = 1e-3;  // stops at t* = 0.823 s
  const double stop = mass * v0 * v0 / (2 * f);
  double ends[2];
  for (int i = 0; i < 2; ++i) {
    SCOPED_TRACE(kFormulations[i]);
    Mechanism m;
    buildIn(m, kFormulations[i], [&](Mechanism& mm) { block(mm, mass, f); }, {CoordinateTarget{0, 0, v0}});
    double q = 0, E = m.kineticEnergy();
    for (int s = 0; s < 1500; ++s) {
      m.step(h);
      ASSERT_GE(m.jointPosition(0, 0), q) << s;
      ASSERT_LE(m.kineticEnergy(), E) << s;
      q = m.jointPosition(0, 0), E = m.kineticEnergy();
      const double t = m.time();
      if (t < 0.8) {
        ASSERT_NEAR(m.jointVelocity(0, 0), v0 - f / mass * t, 1e-12 * v0) << "t = " << t;
      }
    }
    EXPECT_NEAR(m.jointVelocity(0, 0), 0.0, 1e-15 * v0);
    ends[i] = m.jointPosition(0, 0);
    std::printf("[sliding block, %s] stops at %.12f m, known %.12f m (bound f h^2 / 2m = %.1e)\n", kFormulations[i],
                ends[i], stop, f * h * h / (2 * mass));
    EXPECT_NEAR(ends[i], stop, f * h * h / (2 * mass));
  }
  EXPECT_NEAR(ends[0], ends[1], 1e-14 * stop);
}

// The same in rotation: a wheel of axial inertia I on a revolute with friction f (N m)
// under an effort tau, and about an axis turned away from every global one.
TEST(JointFriction, WheelStaysOrSpinsUpAtTheCoulombRate) {
  const double I = 0.03, f = 0.2, h = 1e-3, T = 1.0;
  const Matrix3d R = Eigen::AngleAxisd(1.1, Vector3d(0.3, 1, -0.4).normalized()).toRotationMatrix();
  for (double tau : {0.15, 0.5}) {
    const double alpha = std::max(0.0, (tau - f) / I);
    double q[2];
    for (int i = 0; i < 2; ++i) {
      SCOPED_TRACE(kFormulations[i]);
      Mechanism m;
      buildIn(m, kFormulations[i], [&](Mechanism& mm) {
        // (inertia I about the axis, R's z)
        mm.addBody(mechanism_sim::body("wheel", 1.5, R * Vector3d(0.02, 0.02, I).asDiagonal() * R.transpose(),
                                       Vector3d(0.1, 0.2, 0.3)));
        mm.addJoint(makeJoint("revolute", "axle", Mechanism::kGround, frame(Vector3d(0.1, 0.2, 0.3), R), 1,
                              frame(Vector3d::Zero(), R)));
        mm.setJointFriction(0, 0, f);
      });  // (gravity acts on the axle's bearing only: the wheel is balanced)
      m.setJointEffort(0, 0, tau);
      for (int s = 0; s < std::lround(T / h); ++s) m.step(h);
      q[i] = m.jointPosition(0, 0);
      // (tolerance: of the travel without friction; the absolute formulation's rotations
      // carry 1.7e-12 of it at 10 rad/s, measured)
      EXPECT_NEAR(q[i], alpha * T * T / 2, 3e-12 * tau / I * T * T / 2) << "tau = " << tau;
      EXPECT_NEAR(m.jointVelocity(0, 0), alpha * T, 1e-13 * tau / I) << "tau = " << tau;
    }
    EXPECT_NEAR(q[0], q[1], 3e-12 * tau / I * T * T / 2);
    std::printf("[wheel] tau / f = %.2f: %.3e rad, joint against absolute %.1e rad\n", tau / f, q[1], q[1] - q[0]);
  }
}

// A 1 kg puck on a planar joint slides at (3, 1) m/s against friction 2 N: one force of 2 N
// against the velocity (a disc), so it stops on the straight line after |v|^2 / 2a = 2.5 m.
// (test_solver.cpp's case, in both formulations.)
TEST(JointFriction, PlanarFrictionIsADiscInBothFormulations) {
  for (const char* f : kFormulations) {
    SCOPED_TRACE(f);
    Mechanism m;
    buildIn(m, f, [](Mechanism& mm) {
      mm.addBody(body("puck", 1.0, Vector3d(1e-3, 1e-3, 1e-3), Vector3d::Zero()));
      mm.addJoint(makeJoint("planar", "table", Mechanism::kGround, frame(Vector3d::Zero()), 1, frame(Vector3d::Zero())));
      for (int k = 0; k < 3; ++k) mm.setJointFriction(0, k, 2.0);
      mm.setGravity(Vector3d::Zero());
    }, {CoordinateTarget{0, 0, 3.0}, CoordinateTarget{0, 1, 1.0}});
    const Vector3d direction = Vector3d(3, 1, 0).normalized();
    double off_line = 0;
    for (int k = 0; k < 2000; ++k) {
      m.step(1e-3);
      off_line = std::max(off_line, Vector3d(m.jointPosition(0, 0), m.jointPosition(0, 1), 0).cross(direction).norm());
    }
    const Vector3d end(m.jointPosition(0, 0), m.jointPosition(0, 1), 0);
    EXPECT_LT((end - 2.5 * direction).norm(), 1e-6);
    EXPECT_LT(off_line, 1e-9);
    EXPECT_NEAR(m.jointVelocity(0, 0), 0.0, 1e-12);
    EXPECT_NEAR(m.jointVelocity(0, 1), 0.0, 1e-12);
  }
}

// A 1 kg slider on a radial rail of a turntable spinning at 20 rad/s, at 0.5 m, with
// friction 2000 N: its centripetal load m W^2 q = 200 N is below it, so it sticks. In joint
// coordinates the load is in q_ddot itself (in absolute ones it is the rail's gamma).
TEST(JointFriction, SliderOnSpinningTurntableSticksInBothFormulations) {
  for (const char* f : kFormulations) {
    SCOPED_TRACE(f);
    Mechanism m;
    buildIn(m, f, [](Mechanism& mm) {
      const int t = mm.addBody(body("table", 1000.0, Vector3d(1e6, 1e6, 2e6), Vector3d::Zero()));
      const int s = mm.addBody(body("slider", 1.0, Vector3d(1e-3, 1e-3, 1e-3), Vector3d(0.5, 0, 0)));
      mm.addJoint(makeJoint("revolute", "spindle", Mechanism::kGround, frame(Vector3d::Zero()), t, frame(Vector3d::Zero())));
      const Matrix3d radial = Eigen::AngleAxisd(M_PI / 2, Vector3d::UnitY()).toRotationMatrix();
      mm.addJoint(makeJoint("prismatic", "rail", t, frame(Vector3d::Zero(), radial), s, frame(Vector3d(-0.5, 0, 0), radial)));
      mm.setJointFriction(1, 0, 2000.0);
      mm.setGravity(Vector3d::Zero());
    }, {CoordinateTarget{0, 0, 20.0}});
    const double q0 = m.jointPosition(1, 0);
    for (int k = 0; k < 2000; ++k) m.step(1e-3);
    std::printf("[turntable, %s] the slider moved %.1e m in 2 s\n", f, m.jointPosition(1, 0) - q0);
    // (absolute coordinates: the effective inertia from the penalty form, to 1 / kappa;
    // test_solver.cpp's own case allows 1e-9 m)
    const double tol = std::string(f) == "joint" ? 1e-12 : 1e-9;
    EXPECT_NEAR(m.jointPosition(1, 0), q0, tol);
    EXPECT_NEAR(m.jointVelocity(1, 0), 0.0, tol);
    // friction holds the centripetal load: -m W^2 r on the slider's coordinate
    EXPECT_NEAR(m.jointEffort(1, 0), -1.0 * 20.0 * 20.0 * 0.5, 1e-3) << f;
  }
}

// A chain of 4 links hanging from a cart on a prismatic rail, friction and damping on every
// joint, released from horizontal: links stick and slip as the swing slows; and the
// spinning spherical double pendulum above with friction on its ball joints (frame i
// turning with the arm: the rates' own velocity term is in the stopping effort of both
// formulations). The two formulations agree.
void frictionChain(Mechanism& m) {
  const int cart = m.addBody(body("cart", 3.0, Vector3d(0.05, 0.05, 0.05), Vector3d::Zero()));
  const Matrix3d along_x = Eigen::AngleAxisd(M_PI / 2, Vector3d::UnitY()).toRotationMatrix();  // z along x
  m.addJoint(makeJoint("prismatic", "rail", Mechanism::kGround, frame(Vector3d::Zero(), along_x), cart,
                       frame(Vector3d::Zero(), along_x)));
  int parent = cart;
  for (int k = 0; k < 4; ++k) {
    const double L = 0.4, mass = 1.0 - 0.15 * k;
    const int b = m.addBody(mechanism_sim::body("link" + std::to_string(k), mass, models::rodInertia(mass, L), Vector3d((k + 0.5) * L, 0, 0)));
    m.addJoint(makeJoint("revolute", "j" + std::to_string(k), parent,
                         models::axisY(k == 0 ? Vector3d::Zero() : Vector3d(0.5 * L, 0, 0)), b,
                         models::axisY(Vector3d(-0.5 * L, 0, 0))));
    parent = b;
  }
  const double fr[5] = {4.0, 1.5, 0.8, 0.4, 0.2};
  for (int j = 0; j < 5; ++j) m.setJointFriction(j, 0, fr[j]);
  for (int j = 1; j < 5; ++j) m.setJointDamping(j, 0, 0.01 * j);
}

void frictionBall(Mechanism& m) {
  spinningDoublePendulum(m, 0.5);
  for (int k = 0; k < 3; ++k) m.setJointFriction(1, k, 0.05 + 0.02 * k), m.setJointFriction(2, k, 0.03);
  m.setJointFriction(0, 0, 0.5);
}

TEST(JointFriction, ChainsWithFrictionMoveAsInAbsoluteCoordinates) {
  struct Case {
    const char* name;
    void (*model)(Mechanism&);
  } cases[] = {{"chain on a cart", frictionChain}, {"ball joints on a spinning arm", frictionBall}};
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    double at[2];
    const double hs[2] = {1e-3, 5e-4};
    for (int i = 0; i < 2; ++i) {
      Mechanism a, j;
      buildIn(a, "absolute", c.model);
      buildIn(j, "joint", c.model);
      int sticking = 0;
      for (long s = 0, n = std::lround(2.0 / hs[i]); s < n; ++s) {
        a.step(hs[i]), j.step(hs[i]);
        for (int k = 0; k < j.numJoints(); ++k)  // (a joint held by friction below its limit)
          for (int d = 0; d < j.joint(k).dof(); ++d)
            if (j.state().friction[k][d] != 0 && std::fabs(j.state().friction[k][d]) < j.system().friction[k][d])
              ++sticking;
      }
      at[i] = difference(a, j);
      if (i == 0) std::printf("[%s] coordinate-steps held by friction: %d\n", c.name, sticking);
      EXPECT_GT(sticking, 0);
      for (int k = 0; k < j.numJoints(); ++k)
        for (int d = 0; d < j.joint(k).dof(); ++d)
          EXPECT_LE(std::fabs(j.state().friction[k][d]), j.system().friction[k][d]);
    }
    std::printf("[%s, friction] joint against absolute after 2 s: %.2e at 1 ms, %.2e at 0.5 ms\n", c.name, at[0],
                at[1]);
    EXPECT_LT(at[1], 1e-8);
  }
}

// Friction and damping set after build(): the joint formulation keeps running (no refusal,
// no switch) and applies them from the next step; friction set back to 0 stops acting.
TEST(JointFriction, SetAfterBuildInBothFormulations) {
  for (const char* f : kFormulations) {
    SCOPED_TRACE(f);
    Mechanism m;
    buildIn(m, f, [](Mechanism& mm) { block(mm, 2.0, 0.0); });
    m.setJointEffort(0, 0, 1.0);
    m.setJointFriction(0, 0, 3.0);  // holds the block
    EXPECT_STREQ(m.formulation(), f);
    for (int s = 0; s < 100; ++s) m.step(1e-3);
    EXPECT_LE(std::fabs(m.jointPosition(0, 0)), 1e-15);
    m.setJointFriction(0, 0, 0.0);  // slides at 1 / 2 m/s^2 from here
    for (int s = 0; s < 100; ++s) m.step(1e-3);
    EXPECT_NEAR(m.jointVelocity(0, 0), 0.5 * 0.1, 1e-14);
    m.setJointEffort(0, 0, 0.0);
    m.setJointDamping(0, 0, 0.4);  // decays as exp(-0.2 t)
    for (int s = 0; s < 1000; ++s) m.step(1e-3);
    EXPECT_NEAR(m.jointVelocity(0, 0), 0.05 * std::exp(-0.2), 1e-13);
  }
}

}  // namespace
}  // namespace mechanism_sim
