// Joint damping on light links (issue 18): stiff damping is integrated implicitly
// (stiff_damping.cpp), the rest stays in RK4's stages. Known answers: the exponential decay
// of a damped disc (RK4's amplification per step where the damping is not stiff, the
// relaxation of implicit Euler to the loaded rate tau / c where it is), a light chain that
// relaxes to the motion of its floating base without ever gaining energy, and the same
// mechanism in millimetres. Every test runs in both formulations (the joint one applies the
// same rule in joint coordinates, joint_stepper.cpp).
#include <gtest/gtest.h>

#include "bodies.h"

#include <cmath>

#include <Eigen/Geometry>

#include "mechanism_sim/core/mechanism.h"

namespace mechanism_sim {
namespace {

using test_util::body;
using test_util::frame;

const char* const kFormulations[] = {"absolute", "joint"};

IntegratorOptions formulationOptions(const char* formulation, const char* method = "rk4") {
  IntegratorOptions o;
  o.formulation = formulation;
  o.method = method;
  return o;
}

// RK4's amplification of y' = -y / tau over one step of s = h / tau.
double rk4Amplification(double s) { return 1 - s + s * s / 2 - s * s * s / 6 + s * s * s * s / 24; }

// A floating 5 kg base tumbling at w0 (no gravity) with a chain of `links` 1 g links of
// 1e-7 kg m^2 on revolutes about z, y, x, ... each damped at c and started at 0.3 rad/s.
// Lengths are multiplied by L (L = 1000: millimetres), inertias by L^2 and the damping
// (N m s / rad) by L^2: the same motion in other units.
void floatingChain(Mechanism& m, int links, double c, double L = 1.0, const char* formulation = "absolute") {
  const double L2 = L * L;
  Body base = body("base", 5.0, L2 * Vector3d(0.05, 0.06, 0.07), Vector3d::Zero());
  base.w = Vector3d(0.3, -0.2, 1.0);
  int parent = m.addBody(base);
  const Matrix3d axes[3] = {Matrix3d::Identity(), Eigen::AngleAxisd(-M_PI / 2, Vector3d::UnitX()).toRotationMatrix(),
                            Eigen::AngleAxisd(M_PI / 2, Vector3d::UnitY()).toRotationMatrix()};
  for (int k = 0; k < links; ++k) {
    const int b = m.addBody(body("light" + std::to_string(k), 1e-3, L2 * Vector3d(1e-7, 1e-7, 1e-7),
                                 Vector3d(0, 0, 0.2 * L * (k + 1))));
    m.addJoint(makeJoint("revolute", "j" + std::to_string(k), parent, frame(Vector3d(0, 0, 0.2 * L), axes[k % 3]), b,
                         frame(Vector3d::Zero(), axes[k % 3])));
    parent = b;
  }
  m.setGravity(Vector3d::Zero());
  for (int k = 0; k < links; ++k) m.setJointDamping(k, 0, c * L2);
  m.setIntegrator(formulationOptions(formulation));
  m.build();
  ASSERT_STREQ(m.formulation(), formulation);
  std::vector<CoordinateTarget> v;
  for (int k = 0; k < links; ++k) v.push_back({k, 0, 0.3});
  m.assemble({}, v);
}

// Light links damped at 0.1 N m s / rad (h rate = 1000 at 1 ms): the run of issue 18 died
// in its first step. Now: 5 s at 1 ms, on the constraints, the energy never rises, and the
// links' joint rates fall to what co-rotating with the base needs.
TEST(StiffDamping, LightChainOnAFloatingBaseRelaxesToItsParent) {
 for (const char* formulation : kFormulations) {
  SCOPED_TRACE(formulation);
  Mechanism m;
  floatingChain(m, 3, 0.1, 1.0, formulation);
  const double T0 = m.kineticEnergy();
  double T = T0, slowest = 0;
  for (int s = 1; s <= 5000; ++s) {
    m.step(1e-3);
    ASSERT_LE(m.relativePositionViolation(), 1e-12) << "t = " << m.time();
    ASSERT_LE(m.relativeVelocityViolation(), 1e-12) << "t = " << m.time();
    const double T1 = m.kineticEnergy();
    ASSERT_LE(T1, T * (1 + 1e-14)) << "the energy rose at t = " << m.time() << " by " << (T1 - T) / T;
    T = T1;
    if (s >= 50)
      for (int k = 0; k < 3; ++k) slowest = std::max(slowest, std::fabs(m.jointVelocity(k, 0)));
  }
  // from 0.3 rad/s to the creep under the centrifugal load of the link beyond (measured
  // 5.2e-4 rad/s on j1, the same at h / 10)
  EXPECT_LE(slowest, 1e-3);
  EXPECT_LT(T, T0);
  // the damping's effort is what the joint reports: -c q_dot at the state reached
  for (int k = 0; k < 3; ++k) EXPECT_EQ(m.jointEffort(k, 0), -0.1 * m.jointVelocity(k, 0));
 }
}

// Not stiff (h c / I = 0.02, 0.4 and 1.5, below RK4's threshold 2): the damping stays in
// RK4's stages, so each step multiplies the rate by RK4's amplification R(-h c / I); the
// exponential follows to RK4's accuracy. (At 1.5 RK4 gives 0.273 for exp(-1.5) = 0.223,
// implicit Euler 0.4: the stages are the more accurate there.) Also when the disc hangs on a 1 g hub of 1e-7 kg m^2 (a fixed joint): the
// damped mode moves the disc, not only the hub (the block-diagonal bound alone would call
// it stiff, and implicit Euler, 1.4^-5 = 0.186 for exp(-2) = 0.135, would fail).
TEST(StiffDamping, HeavyDiscDecaysAtRK4sRate) {
  for (const char* formulation : kFormulations)
  for (double rate : {20.0, 400.0, 1500.0, -400.0}) {  // c / I in 1/s; negative: on a light hub
    SCOPED_TRACE(formulation);
    const bool hub = rate < 0;
    rate = std::fabs(rate);
    const double I = 0.05, c = rate * (hub ? I + 1e-7 : I), w0 = 10.0, h = 1e-3;
    Mechanism m;
    const int b = m.addBody(body("disc", 1.0, Vector3d(0.025, 0.025, I), Vector3d::Zero()));
    if (hub) {
      const int l = m.addBody(body("hub", 1e-3, Vector3d(1e-7, 1e-7, 1e-7), Vector3d::Zero()));
      m.addJoint(makeJoint("revolute", "axle", Mechanism::kGround, frame(Vector3d::Zero()), l, frame(Vector3d::Zero())));
      m.addJoint(makeJoint("fixed", "mount", l, frame(Vector3d::Zero()), b, frame(Vector3d::Zero())));
    } else {
      m.addJoint(makeJoint("revolute", "axle", Mechanism::kGround, frame(Vector3d::Zero()), b, frame(Vector3d::Zero())));
    }
    m.setGravity(Vector3d::Zero());
    m.setJointDamping(0, 0, c);
    m.setIntegrator(formulationOptions(formulation));
    m.build();
    m.assemble({}, {CoordinateTarget{0, 0, w0}});
    const int n = static_cast<int>(std::lround(2.0 / (rate * h)));  // to exp(-2)
    for (int s = 0; s < n; ++s) m.step(h);
    const double w = m.jointVelocity(0, 0);
    EXPECT_NEAR(w, w0 * std::pow(rk4Amplification(h * rate), n), 1e-12 * w0) << "c / I = " << rate;
    // RK4's global error: n steps of (h rate)^5 / 120 relative
    EXPECT_NEAR(w, w0 * std::exp(-rate * n * h), n * std::pow(h * rate, 5) / 120 * w0) << "c / I = " << rate;
  }
}

// Stiff (h c / I = 1000): a 1e-7 kg m^2 disc damped at 0.1 N m s / rad under an effort tau
// relaxes (time constant I / c = 1 us) to the rate tau / c. Implicit Euler gives
// w_n = tau / c + (w0 - tau / c) / (1 + s)^n and the positions move by h (w_n + w_n+1) / 2,
// so after t the angle is tau / c t + (w0 - tau / c) h (1/2 + 1/s) where the exact one is
// tau / c t + (w0 - tau / c) I / c: the first step's half step of the initial excess rate.
// The same with every method.
TEST(StiffDamping, LightDiscRelaxesToTheLoadedRate) {
  for (const char* formulation : kFormulations)
  for (const char* method : {"rk4", "rk3", "rk2"}) {
    SCOPED_TRACE(formulation);
    const double I = 1e-7, c = 0.1, tau = 1e-3, w0 = 0.3, h = 1e-3, s = h * c / I;
    Mechanism m;
    const int b = m.addBody(body("disc", 1e-3, Vector3d(0.5 * I, 0.5 * I, I), Vector3d::Zero()));
    m.addJoint(makeJoint("revolute", "axle", Mechanism::kGround, frame(Vector3d::Zero()), b, frame(Vector3d::Zero())));
    m.setGravity(Vector3d::Zero());
    m.setJointDamping(0, 0, c);
    m.setIntegrator(formulationOptions(formulation, method));
    m.build();
    m.assemble({}, {CoordinateTarget{0, 0, w0}});
    m.setJointEffort(0, 0, tau);
    const double limit = tau / c, excess = w0 - limit;
    m.step(h);
    EXPECT_NEAR(m.jointVelocity(0, 0), limit + excess / (1 + s), 1e-12) << method;
    for (int n = 1; n < 1000; ++n) m.step(h);
    EXPECT_NEAR(m.jointVelocity(0, 0), limit, 1e-12) << method;
    // RK4 exactly; rk3 and Heun also carry their own error on the hub's undamped stage
    // rate (it spins up by h tau / I = 10 rad/s within each step): measured 1.0e-5 rad
    const double own = std::string(method) == "rk4" ? 1e-9 : 2e-5;
    EXPECT_NEAR(m.jointPosition(0, 0), limit * 1.0 + excess * h * (0.5 + 1 / s), own) << method;
    EXPECT_NEAR(m.jointPosition(0, 0), limit * 1.0 + excess * I / c, excess * h / 2 + own) << method;
    // the effort the joint reports: the load less the damping at the state reached (0)
    EXPECT_NEAR(m.jointEffort(0, 0), tau - c * m.jointVelocity(0, 0), 1e-15) << method;
    EXPECT_NEAR(m.jointEffort(0, 0), 0.0, 1e-12) << method;
  }
}

// The same light chain in millimetres (lengths x 1000, inertias and damping x 1e6) moves as
// in metres: the threshold is a ratio, nothing is measured against an absolute size.
TEST(StiffDamping, MillimetresBehaveAsMetres) {
  for (const char* formulation : kFormulations) {
  SCOPED_TRACE(formulation);
  Mechanism metres, millimetres;
  floatingChain(metres, 3, 0.1, 1.0, formulation);
  floatingChain(millimetres, 3, 0.1, 1000.0, formulation);
  for (int s = 0; s < 1000; ++s) metres.step(1e-3), millimetres.step(1e-3);
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(millimetres.jointPosition(k, 0), metres.jointPosition(k, 0), 1e-10) << k;
    EXPECT_NEAR(millimetres.jointVelocity(k, 0), metres.jointVelocity(k, 0), 1e-12) << k;
  }
  EXPECT_NEAR(millimetres.kineticEnergy() / 1e6, metres.kineticEnergy(), 1e-12 * metres.kineticEnergy());
  EXPECT_LE(millimetres.relativePositionViolation(), 1e-12);
  }
}

// A light link 1 (0.0101 kg m^2 about its axle) carrying a 1 kg link 2 on a damped elbow
// (c = 50 N m s / rad) turned by an effort of 500 N m, no gravity: the elbow's constrained
// inverse inertia swings from 180 (straight) to 4.8 (bent square) and 21 (folded) 1/(kg m^2)
// as it turns, so at 1 ms its decay rate h c P crosses the bound of 2 as it turns, fast near
// the straight pose (the mass matrix is nearly singular there). The joint formulation holds
// its classification over steps where the rates were far from the bound and changing slowly
// (joint_stepper.cpp). Against the same run classified at every step (the hold cleared
// before each step through a snapshot): every bit the same, while the hold served hundreds
// of steps. A switch one step late would move the elbow by a first-order step's error.
TEST(StiffDamping, HeldClassificationSwitchesWhereEachStepsWould) {
  Mechanism run[2];
  for (Mechanism& m : run) {
    const int l1 = m.addBody(body("link1", 0.04, Vector3d(1e-4, 1e-4, 1e-4), Vector3d(0.5, 0, 0)));
    const int l2 = m.addBody(body("link2", 1.0, Vector3d(0.01, 0.01, 0.01), Vector3d(1.5, 0, 0)));
    m.addJoint(makeJoint("revolute", "shoulder", Mechanism::kGround, frame(Vector3d::Zero()), l1,
                         frame(Vector3d(-0.5, 0, 0))));
    m.addJoint(makeJoint("revolute", "elbow", l1, frame(Vector3d(0.5, 0, 0)), l2, frame(Vector3d(-0.5, 0, 0))));
    m.setGravity(Vector3d::Zero());
    m.setJointDamping(1, 0, 50.0);
    m.setIntegrator(formulationOptions("joint"));
    m.build();
    m.assemble({}, {});
    m.setJointEffort(1, 0, 500.0);
  }
  int switches = 0, held = 0;
  char stiff = -1;
  for (int s = 1; s <= 2000; ++s) {
    run[0].step(1e-3);
    Mechanism::Snapshot each = run[1].snapshot();
    each.damping_hold.left = 0;
    run[1].restore(each);
    run[1].step(1e-3);
    const State::DampingHold& hold = run[0].state().damping_hold;
    ASSERT_EQ(hold.stiff.size(), 1u);
    if (stiff >= 0 && hold.stiff[0] != stiff) ++switches;
    stiff = hold.stiff[0];
    if (hold.left > 0 && hold.left < 16) ++held;  // (a step that took the held set)
    for (int j = 0; j < 2; ++j) {
      ASSERT_EQ(run[0].jointPosition(j, 0), run[1].jointPosition(j, 0)) << "t = " << run[0].time();
      ASSERT_EQ(run[0].jointVelocity(j, 0), run[1].jointVelocity(j, 0)) << "t = " << run[0].time();
    }
  }
  EXPECT_GT(run[0].jointPosition(1, 0), 6 * M_PI);  // (three turns)
  EXPECT_GE(switches, 6);
  EXPECT_GT(held, 500);
}

}  // namespace
}  // namespace mechanism_sim
