// The Mechanism facade (mechanism.cpp): snapshots, the formulation switch, and calls out of
// order. Oracles: bit identity where the arithmetic is the same (a restored snapshot steps
// on to the same bits as the run it was taken from, in each formulation), and the pendulum's
// exact motion (pendulum.h: RK4 at 10 us on the scalar equation) where it is not: a snapshot
// of one formulation restored into a mechanism running the other, or a run switched between
// formulations, ends where the pendulum is, within RK4's error at 1 ms (1e-10 m after 10 s,
// absolute/test_solver.cpp), and the restored state reads as the snapshot did.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "mechanism_sim/core/mechanism.h"
#include "mechanism_sim/core/models.h"
#include "pendulum.h"

namespace mechanism_sim {
namespace {

IntegratorOptions formulation(const char* f) {
  IntegratorOptions io;
  io.formulation = f;
  return io;
}

// Whether two States hold the same bits where a run is defined: clock, positions,
// velocities, multipliers, accelerations, limit sides, tracked angles, joint state.
void expectSameBits(const State& a, const State& b, const char* what) {
  SCOPED_TRACE(what);
  EXPECT_EQ(a.t, b.t);
  EXPECT_EQ(a.steps, b.steps);
  EXPECT_EQ(a.x, b.x);
  EXPECT_EQ(a.u, b.u);
  EXPECT_EQ(a.acc, b.acc);
  EXPECT_EQ(a.tracked, b.tracked);
  EXPECT_EQ(a.limit_side, b.limit_side);
  EXPECT_EQ(a.q, b.q);
  EXPECT_EQ(a.qdot, b.qdot);
}

// A loop with a limit beside a pendulum: a four-bar (a closure in joint coordinates, the
// penalty form in absolute ones) and a bob whose pivot stops it at 0.6 rad (it falls onto
// the stop within the run, so the limit's side changes between snapshot and end).
void loopAndStop(Mechanism& m) {
  models::fourBarChain(m, 1);
  Pendulum p;
  p.pivot = Vector3d(0, 2, 0);
  p.Ic = 1e-3;  // (a point-like bob, 1e-6, fails at the stop: absolute/test_projection.cpp)
  p.add(m);
  m.setJointLimits(m.numJoints() - 1, 0, -0.6, 0.6);
}

// A snapshot is the State: restored, the run steps on to the bits of the run it was taken
// from, in either formulation, with efforts changing at every step.
TEST(MechanismSnapshot, RestoredRunsRepeatTheSameBitsInBothFormulations) {
  for (const char* f : {"absolute", "joint"}) {
    SCOPED_TRACE(f);
    Mechanism m;
    loopAndStop(m);
    m.setIntegrator(formulation(f));
    m.build();
    m.assemble();
    ASSERT_STREQ(m.formulation(), f) << m.formulationReason();
    for (int k = 0; k < 150; ++k) m.step(1e-3);
    const Mechanism::Snapshot snap = m.snapshot();
    ASSERT_EQ(snap.limit_side[0], 0) << "the bob has not reached its stop yet";
    auto run = [&m]() {
      for (int k = 0; k < 600; ++k) {
        m.setJointEffort(0, 0, 0.5 * std::sin(0.02 * k));
        m.step(1e-3);
      }
      return m.snapshot();
    };
    const State first = run();
    EXPECT_EQ(first.limit_side[0], 1) << "the bob rests on its stop by the end";
    m.restore(snap);
    EXPECT_EQ(m.time(), snap.t);
    EXPECT_EQ(m.stepsTaken(), snap.steps);
    const State second = run();
    expectSameBits(first, second, "restored run");
    // and once more, from a restore after a restore
    m.restore(snap);
    m.restore(snap);
    expectSameBits(first, run(), "restored twice");
  }
}

// A snapshot of one formulation restored into a mechanism that runs the other (switched by
// setIntegrator): the state reads as it did, and the run goes on to the pendulum's exact
// motion. Both ways: joint to absolute (the joint state dropped) and absolute to joint (the
// joint state settled from the bodies').
TEST(MechanismSnapshot, ASnapshotOfOneFormulationContinuesInTheOther) {
  const Pendulum p;
  const double h = 1e-3, T = 2.0;
  for (auto [from, to] : {std::make_pair("joint", "absolute"), std::make_pair("absolute", "joint")}) {
    SCOPED_TRACE(std::string(from) + " -> " + to);
    Mechanism m;
    p.add(m);
    m.setIntegrator(formulation(from));
    m.build();
    m.assemble();
    for (int k = 0; k < 700; ++k) m.step(h);
    const Mechanism::Snapshot snap = m.snapshot();
    const Vector3d at_snap = m.position(1);
    const double q_snap = m.jointPosition(0, 0), v_snap = m.jointVelocity(0, 0);
    // switch and wander off: the other formulation runs on from here for a while
    m.setIntegrator(formulation(to));
    ASSERT_STREQ(m.formulation(), to);
    EXPECT_EQ(m.formulationReason(), std::string(to) + " coordinates, as asked");
    for (int k = 0; k < 123; ++k) m.step(h);
    // restored: the state reads as the snapshot did
    m.restore(snap);
    EXPECT_STREQ(m.formulation(), to);
    EXPECT_EQ(m.time(), snap.t);
    // (into joint coordinates the bodies are placed again from q: the absolute state's
    // violation, within the position tolerance, is the difference)
    EXPECT_LT((m.position(1) - at_snap).norm(), 1e-12 * p.L);
    EXPECT_NEAR(m.jointPosition(0, 0), q_snap, 1e-14);
    EXPECT_NEAR(m.jointVelocity(0, 0), v_snap, 1e-13 * std::fabs(v_snap));
    EXPECT_LT(m.positionViolation(), 1e-14 * p.L);
    // and the run goes on in the other formulation to where the pendulum is
    for (int k = 700; k < 2000; ++k) m.step(h);
    EXPECT_EQ(m.time(), snap.t + 1300 * h) << "a new run of steps starts at the snapshot's time";
    EXPECT_LT((m.position(1) - p.exact(m.time())).norm(), 1e-9 * p.L) << "t = " << m.time();
    EXPECT_NEAR(m.time(), T, 1e-12);
  }
}

// Switching the formulation of a running mechanism (no snapshot) continues the motion: a
// pendulum switched at every 250 steps ends where it is exactly, as an unswitched run does.
TEST(MechanismSnapshot, SwitchingFormulationsWhileRunningKeepsTheMotion) {
  const Pendulum p;
  Mechanism m, joint_only;
  p.add(m);
  p.add(joint_only);
  joint_only.setIntegrator(formulation("joint"));
  for (Mechanism* x : {&m, &joint_only}) x->build(), x->assemble();
  const char* next[] = {"joint", "absolute"};
  for (int k = 0; k < 2000; ++k) {
    if (k % 250 == 0) m.setIntegrator(formulation(next[(k / 250) % 2]));
    m.step(1e-3);
    joint_only.step(1e-3);
  }
  EXPECT_EQ(m.time(), joint_only.time());
  EXPECT_LT((m.position(1) - p.exact(m.time())).norm(), 1e-9 * p.L);
  EXPECT_LT((joint_only.position(1) - p.exact(joint_only.time())).norm(), 1e-9 * p.L);
}

// Stepping or restoring before build() is a UsageError that says so, and leaves the
// mechanism to be built and run as if it had not been called.
TEST(MechanismUsage, StepAndRestoreBeforeBuildAreUsageErrors) {
  const Pendulum p;
  Mechanism m;
  p.add(m);
  try {
    m.step(1e-3);
    ADD_FAILURE() << "step before build() was accepted";
  } catch (const UsageError& e) {
    EXPECT_NE(std::string(e.what()).find("before build()"), std::string::npos) << e.what();
  }
  Mechanism other;
  p.add(other);
  other.build();
  other.assemble();
  EXPECT_THROW(m.restore(other.snapshot()), UsageError);
  m.build();
  m.assemble();
  EXPECT_EQ(m.time(), 0.0);
  for (int k = 0; k < 500; ++k) m.step(1e-3);
  EXPECT_LT((m.position(1) - p.exact(0.5)).norm(), 1e-9 * p.L);
}

}  // namespace
}  // namespace mechanism_sim
