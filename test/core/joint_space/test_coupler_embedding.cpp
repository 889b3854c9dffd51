// Couplers the joint-space tree holds itself (TreeModel's embed_couplers, TreeLink::tie:
// constraint embedding of a URDF mimic) against the same couplers solved as closure rows,
// the way the joint formulation ran every coupler before: one mechanism, a hand whose
// fingers follow its palm's joint through a welded plate (two revolute slaves in a chain, a
// prismatic one below them, a free joint below a slave: the master an ancestor), a parallel
// gripper whose second jaw and a pad on it follow the first (siblings: the master's
// coordinate eliminated at their common ancestor), limits, damping, Coulomb friction and
// efforts on slaves and masters, and a coupler the tree does not hold (its master is itself
// held: a closure row either way). At one state the
// accelerations and every multiplier agree to round-off; over 2 s the motions agree, the
// held couplers hold exactly, and the absolute formulation moves the same way.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "assembly/four_bar_parts.h"
#include "bodies.h"
#include "core/joint_space/joint_stepper.h"
#include "mechanism_sim/core/mechanism.h"
#include "core/joint_space/tree_reactions.h"

namespace mechanism_sim {
namespace {

using test_util::frame;

using test_util::assembly::Parts;

IntegratorOptions withFormulation(const char* f) {
  IntegratorOptions io;
  io.formulation = f;
  return io;
}

// The hand (bodies at their centres, identity orientations, every joint at 0 to start).
// Joints: 0 wrist (ground-base), 1 palm (master), 2 plate (fixed), 3 finger (r 0.9),
// 4 finger tip (r -0.6, offset 0.05; limits), 5 slider (prismatic, r 0.02 m/rad), 6 flap
// (free, below the finger), 7 thumb (r 0.5 of the finger: a closure row), 8 mount (fixed),
// 9 jaw_a (master), 10 jaw_b (r -1), 11 pad (r 3 rad/m, on jaw_b).
void hand(Mechanism& m, const char* formulation) {
  Parts parts{m};
  const int base = parts.add("base", 2.0, Vector3d(0, 0, 0.1));
  const int palm = parts.add("palm", 1.0, Vector3d(0.2, 0, 0.1));
  const int plate = parts.add("plate", 0.3, Vector3d(0.3, 0, 0.1));
  const int finger = parts.add("finger", 0.2, Vector3d(0.4, 0.05, 0.1));
  const int tip = parts.add("tip", 0.1, Vector3d(0.5, 0.05, 0.1));
  const int slider = parts.add("slider", 0.05, Vector3d(0.55, 0.05, 0.1));
  const int flap = parts.add("flap", 0.1, Vector3d(0.4, 0.12, 0.1));
  const int thumb = parts.add("thumb", 0.2, Vector3d(0.1, 0.1, 0.1));
  parts.join("revolute", "wrist", Mechanism::kGround, base, Vector3d(0, 0, 0), Vector3d(0, 0, 1));
  parts.join("revolute", "palm", base, palm, Vector3d(0.1, 0, 0.1), Vector3d(1, 0, 0));
  parts.join("fixed", "plate", palm, plate, Vector3d(0.25, 0, 0.1), Vector3d(0, 0, 1));
  parts.join("revolute", "finger", plate, finger, Vector3d(0.35, 0.05, 0.1), Vector3d(0, 1, 0.2));
  parts.join("revolute", "tip", finger, tip, Vector3d(0.45, 0.05, 0.1), Vector3d(0.1, 1, 0));
  parts.join("prismatic", "slider", tip, slider, Vector3d(0.55, 0.05, 0.1), Vector3d(1, 0.3, 0));
  parts.join("revolute", "flap", finger, flap, Vector3d(0.4, 0.1, 0.1), Vector3d(1, 0, 0));
  parts.join("revolute", "thumb", base, thumb, Vector3d(0.05, 0.1, 0.1), Vector3d(1, 0, 0.3));
  // a parallel gripper on the base: two jaws on a welded mount, the second jaw and a pad on
  // it following the first (siblings: the master's coordinate is eliminated at the base)
  const int mount = parts.add("mount", 0.3, Vector3d(0, -0.1, 0.1));
  const int jaw_a = parts.add("jaw_a", 0.1, Vector3d(0.05, -0.15, 0.1));
  const int jaw_b = parts.add("jaw_b", 0.1, Vector3d(-0.05, -0.15, 0.1));
  const int pad = parts.add("pad", 0.05, Vector3d(-0.05, -0.2, 0.1));
  parts.join("fixed", "mount", base, mount, Vector3d(0, -0.08, 0.1), Vector3d(0, 0, 1));
  parts.join("prismatic", "jaw_a", mount, jaw_a, Vector3d(0.05, -0.15, 0.1), Vector3d(1, 0.2, 0));
  parts.join("prismatic", "jaw_b", mount, jaw_b, Vector3d(-0.05, -0.15, 0.1), Vector3d(1, -0.2, 0));
  parts.join("revolute", "pad", jaw_b, pad, Vector3d(-0.05, -0.18, 0.1), Vector3d(0, 0.3, 1));
  m.addCoupler("finger_mimic", 3, 0, 1, 0, 0.9, 0.0);
  m.addCoupler("tip_mimic", 4, 0, 1, 0, -0.6, 0.05);
  m.addCoupler("slider_mimic", 5, 0, 1, 0, 0.02, 0.0);
  m.addCoupler("thumb_mimic", 7, 0, 3, 0, 0.5, 0.0);
  m.addCoupler("jaw_mimic", 10, 0, 9, 0, -1.0, 0.0);
  m.addCoupler("pad_mimic", 11, 0, 9, 0, 3.0, 0.0);
  m.setJointLimits(4, 0, -0.3, 0.3);
  m.setJointLimits(10, 0, -0.04, 0.04);
  m.setJointDamping(3, 0, 0.02);
  m.setJointDamping(6, 0, 0.01);
  m.setJointDamping(9, 0, 0.5);
  m.setJointDamping(11, 0, 0.001);
  m.setJointFriction(4, 0, 0.002);
  m.setJointFriction(10, 0, 0.01);
  m.setIntegrator(withFormulation(formulation));
  m.build();
  m.assemble();
  m.setJointEffort(1, 0, 0.4);
  m.setJointEffort(3, 0, 0.05);
  m.setJointEffort(0, 0, 0.1);
  m.setJointEffort(9, 0, 0.05);
}

Inputs handInputs(const System& sys) {
  Inputs in = zeroInputs(sys);
  in.effort[1][0] = 0.4, in.effort[3][0] = 0.05, in.effort[0][0] = 0.1, in.effort[9][0] = 0.05;
  return in;
}

double largest(const Eigen::VectorXd& v) { return v.size() ? v.cwiseAbs().maxCoeff() : 0.0; }

// Accelerations and multipliers (every row: the tree joints' from the reactions pass) of
// the two steppers settled at s; returns the larger relative difference.
double atState(const System& sys, const State& s, const Inputs& in, const char* where) {
  JointStepper held(sys, true), rows(sys, false);
  State a = s, b = s;
  held.settle(sys, a, in);
  rows.settle(sys, b, in);
  Eigen::VectorXd la = a.lambda, lb = b.lambda;
  TreeReactionWorkspace wa(sys), wb(sys);
  treeJointMultipliers(sys, held.model(), a, in, wa, la);
  treeJointMultipliers(sys, rows.model(), b, in, wb, lb);
  const double dq = largest(a.qddot - b.qddot) / largest(b.qddot);
  const double dl = largest(la - lb) / largest(lb);
  std::printf("[coupler embedding] %s: accelerations %.2e, multipliers %.2e (relative); efforts left over %.1e, %.1e\n",
              where, dq, dl, wa.worst_effort, wb.worst_effort);
  EXPECT_LT(wa.worst_effort, 1e-12) << where;
  return std::max(dq, dl);
}

TEST(CouplerEmbedding, HeldCouplersAreTheClosureRowsSolvedInTheRecursion) {
  Mechanism m;
  hand(m, "joint");
  ASSERT_STREQ(m.formulation(), "joint") << m.formulationReason();
  const System& sys = m.system();
  const Inputs in = handInputs(sys);
  {
    const JointStepper held(sys, true), rows(sys, false);
    const TreeModel& t = held.model();
    // finger, tip and slider are held by the palm's link; the thumb (whose master, the
    // finger, is held itself) is not; jaw_b and the pad are held by the base, the jaws'
    // common ancestor, jaw_a's link tied to itself
    ASSERT_EQ(t.ties.size(), 5u);
    const int palm = t.joint_link[1], jaw_a = t.joint_link[9], base = t.joint_link[0];
    for (int j : {3, 4, 5}) EXPECT_EQ(t.links[t.joint_link[j]].tie, palm) << "joint " << j;
    EXPECT_EQ(t.links[t.joint_link[7]].tie, -1);
    EXPECT_TRUE(t.links[palm].tie_master);
    for (int j : {10, 11}) EXPECT_EQ(t.links[t.joint_link[j]].tie, jaw_a) << "joint " << j;
    EXPECT_EQ(t.links[jaw_a].tie, jaw_a);
    EXPECT_EQ(t.links[base].pivot, t.links[jaw_a].iv);
    EXPECT_TRUE(rows.model().ties.empty());
  }
  EXPECT_LT(atState(sys, m.state(), in, "at the start"), 1e-10);
  // on to the tip's limit, then at that state (the limit's row on a held coordinate)
  bool limited = false;
  for (int k = 0; k < 3000 && !limited; ++k) {
    m.step(1e-3);
    limited = m.state().limit_side[0] != 0;
  }
  ASSERT_TRUE(limited) << "the tip never reached its limit: the test did not test a limit on a held coordinate";
  EXPECT_LT(atState(sys, m.state(), in, "at the tip's limit"), 1e-10);
}

TEST(CouplerEmbeddingRun, HeldCouplersMoveAsClosureRowsAndInAbsoluteCoordinates) {
  Mechanism j, a;
  hand(j, "joint");
  hand(a, "absolute");
  const System& sys = j.system();
  const Inputs in = handInputs(sys);
  JointStepper held(sys, true), rows(sys, false);
  State sh = j.state(), sr = j.state();
  held.settle(sys, sh, in);
  rows.settle(sys, sr, in);
  double exact = 0.0, abs_diff = -1.0, t_stop = 0.0;
  const TreeModel& t = held.model();
  for (int k = 0; k < 2000; ++k) {
    held.step(sys, sh, in, 1e-3);
    rows.step(sys, sr, in, 1e-3);
    j.step(1e-3), a.step(1e-3);
    for (int l : t.ties) {
      const TreeLink& L = t.links[l];
      exact = std::max(exact, std::fabs(sh.q(L.iq) - (L.tie_mult * sh.q(t.links[L.tie].iq) + L.tie_offset)));
    }
    // against the absolute formulation until the tip's stop: an inelastic impact each
    // formulation takes by its own projection (their difference after it is the impact's,
    // with or without held couplers: joint_space/test_joint_stepper.cpp's limits)
    if (t_stop == 0.0 && (j.state().limit_side[0] != 0 || a.state().limit_side[0] != 0)) t_stop = j.time();
    if (t_stop == 0.0) {
      abs_diff = 0.0;
      for (int q = 0; q < j.numJoints(); ++q)
        if (j.joint(q).dof() > 0) abs_diff = std::max(abs_diff, std::fabs(j.jointPosition(q, 0) - a.jointPosition(q, 0)));
    }
  }
  const double rows_diff = largest(sh.q - sr.q);
  std::printf("[coupler embedding] after 2 s: held against rows %.2e; joint (held) against absolute %.2e the step "
              "before the tip's stop (t = %.3f s); held couplers off by %.1e\n",
              rows_diff, abs_diff, t_stop, exact);
  EXPECT_LT(rows_diff, 1e-8);
  ASSERT_GT(t_stop, 0.05) << "the tip stopped too soon (or never) for a comparison of the free motion";
  EXPECT_LT(abs_diff, 1e-8);
  EXPECT_LT(exact, 1e-15);  // q_s = r q_m + o to its rounding (holdTies after every step)
  EXPECT_EQ(sh.limit_side[0], sr.limit_side[0]);
  EXPECT_GT(largest(sh.q), 0.1);  // (it moved)
}

// A parallel gripper on a wrist turning about z: jaw_b = -jaw_a, each with its stop
// (a in [0, 0.04], b in [-0.04, 0]: the same stop), jaw_a 1 cm open to start.
void gripper(Mechanism& m, const char* formulation) {
  Parts parts{m};
  const int wrist = parts.add("wrist", 1.0, Vector3d(0, 0, 0.05));
  const int a = parts.add("jaw_a", 0.1, Vector3d(0.03, 0, 0.1));
  const int b = parts.add("jaw_b", 0.1, Vector3d(-0.03, 0, 0.1));
  parts.join("revolute", "wrist", Mechanism::kGround, wrist, Vector3d(0, 0, 0), Vector3d(0, 0, 1));
  parts.join("prismatic", "jaw_a", wrist, a, Vector3d(0.03, 0, 0.1), Vector3d(1, 0, 0));
  parts.join("prismatic", "jaw_b", wrist, b, Vector3d(-0.03, 0, 0.1), Vector3d(1, 0, 0));
  m.addCoupler("jaw_mimic", 2, 0, 1, 0, -1.0, 0.0);
  m.setJointLimits(1, 0, 0.0, 0.04);
  m.setJointLimits(2, 0, -0.04, 0.0);
  m.setIntegrator(withFormulation(formulation));
  m.build();
  m.assemble({{1, 0, 0.01}});
}

// A parallel gripper whose jaws have the same limits (q_b = -q_a, a in [0, 0.04], b in
// [-0.04, 0]): held, the second jaw's limit is implied by the first's and left out; driven
// into the stop, the jaws move as with every row (coupler and both limits, dependent at
// the stop, solved least-norm), and the first jaw's limit carries what both carried there:
// lambda_a' = lambda_a + r lambda_b.
TEST(CouplerEmbedding, AnImpliedSlaveLimitIsCarriedByItsMaster) {
  Mechanism m;
  gripper(m, "joint");
  const System& sys = m.system();
  Inputs in = zeroInputs(sys);
  in.effort[0][0] = 0.3, in.effort[1][0] = 0.5;  // the wrist turns, the jaws close on their stops
  JointStepper held(sys, true), rows(sys, false);
  ASSERT_EQ(held.model().ties.size(), 1u);
  State sh = m.state(), sr = m.state();
  held.settle(sys, sh, in);
  rows.settle(sys, sr, in);
  const int la = sys.layout[sys.limits[0].constraint].row, lb = sys.layout[sys.limits[1].constraint].row;
  int stopped = 0;
  double worst_lambda = 0.0, scale = 0.0;
  for (int k = 0; k < 1000; ++k) {
    held.step(sys, sh, in, 1e-3);
    rows.step(sys, sr, in, 1e-3);
    EXPECT_EQ(sh.limit_side[1], 0) << "the implied limit never activates";
    if (sh.limit_side[0] != 0 && sr.limit_side[0] != 0 && sr.limit_side[1] != 0) {
      ++stopped;
      worst_lambda = std::max(worst_lambda, std::fabs(sh.lambda[la] - (sr.lambda[la] - sr.lambda[lb])));
      scale = std::max(scale, std::fabs(sh.lambda[la]));
    }
  }
  const double diff = largest(sh.q - sr.q);
  std::printf("[coupler embedding] gripper on its stops: %d steps at both stops, positions held against rows %.2e, "
              "the stop's multiplier against the rows' sum %.2e (relative)\n",
              stopped, diff, worst_lambda / scale);
  EXPECT_GT(stopped, 500);
  EXPECT_LT(diff, 1e-9);
  EXPECT_NEAR(sh.q(held.model().links[held.model().joint_link[1]].iq), 0.04, 1e-12);
  EXPECT_GT(scale, 0.1);
  EXPECT_LT(worst_lambda, 1e-9 * scale);
}

// Two groups that would share a link: the jaws' common ancestor (the wrist) is also the
// master of a flap on the base. The group found first (breadth-first: the jaws) is held at
// the wrist; the flap's coupler stays a row, and the accelerations are those of all rows.
TEST(CouplerEmbedding, GroupsThatWouldShareALinkLeaveOneARow) {
  Mechanism m;
  Parts parts{m};
  const int base = parts.add("base", 2.0, Vector3d(0, 0, 0.1));
  const int wrist = parts.add("wrist", 1.0, Vector3d(0.2, 0, 0.1));
  const int mount = parts.add("mount", 0.3, Vector3d(0, -0.1, 0.1));
  const int jaw_a = parts.add("jaw_a", 0.1, Vector3d(0.25, 0.05, 0.1));
  const int jaw_b = parts.add("jaw_b", 0.1, Vector3d(0.25, -0.05, 0.1));
  const int flap = parts.add("flap", 0.2, Vector3d(0, -0.2, 0.1));
  parts.join("revolute", "base", Mechanism::kGround, base, Vector3d(0, 0, 0), Vector3d(0, 0, 1));
  parts.join("revolute", "wrist", base, wrist, Vector3d(0.1, 0, 0.1), Vector3d(1, 0, 0));
  parts.join("fixed", "mount", base, mount, Vector3d(0, -0.08, 0.1), Vector3d(0, 0, 1));
  parts.join("prismatic", "jaw_a", wrist, jaw_a, Vector3d(0.25, 0.05, 0.1), Vector3d(0, 1, 0.2));
  parts.join("prismatic", "jaw_b", wrist, jaw_b, Vector3d(0.25, -0.05, 0.1), Vector3d(0, 1, -0.2));
  parts.join("revolute", "flap", mount, flap, Vector3d(0, -0.15, 0.1), Vector3d(1, 0, 0.3));
  m.addCoupler("jaw_mimic", 4, 0, 3, 0, -1.0, 0.0);
  m.addCoupler("flap_mimic", 5, 0, 1, 0, 0.5, 0.0);
  m.setIntegrator(withFormulation("joint"));
  m.build();
  m.assemble();
  const System& sys = m.system();
  Inputs in = zeroInputs(sys);
  in.effort[1][0] = 0.3, in.effort[3][0] = 0.2, in.effort[0][0] = 0.1;
  const JointStepper held(sys, true);
  const TreeModel& t = held.model();
  ASSERT_EQ(t.ties.size(), 1u);
  EXPECT_EQ(t.links[t.joint_link[4]].tie, t.joint_link[3]);
  EXPECT_EQ(t.links[t.joint_link[1]].pivot, t.links[t.joint_link[3]].iv);
  EXPECT_EQ(t.links[t.joint_link[5]].tie, -1);
  EXPECT_LT(atState(sys, m.state(), in, "groups sharing the wrist"), 1e-10);
}

// A State that comes from the absolute formulation with a held slave's implied limit active
// (a switch of formulation at the stops): the joint formulation lets that side go (the
// master's limit holds the stop), and the jaws open again when pulled.
TEST(CouplerEmbedding, AnImpliedLimitActiveInAnAbsoluteStateIsLetGo) {
  Mechanism m;
  gripper(m, "absolute");
  m.setJointEffort(1, 0, 0.5);
  for (int k = 0; k < 600; ++k) m.step(1e-3);
  ASSERT_NE(m.state().limit_side[1], 0) << "the absolute run did not reach the slave's stop: nothing to let go";
  m.setIntegrator(withFormulation("joint"));
  ASSERT_STREQ(m.formulation(), "joint");
  EXPECT_EQ(m.state().limit_side[1], 0);
  EXPECT_NE(m.state().limit_side[0], 0);  // (the master's holds the stop)
  m.setJointEffort(1, 0, -0.5);  // open (about 1 cm in 0.1 s)
  for (int k = 0; k < 100; ++k) m.step(1e-3);
  std::printf("[coupler embedding] opened after the switch: sides %d %d, jaws %.4f %.4f m, violation %.1e\n",
              m.state().limit_side[0], m.state().limit_side[1], m.jointPosition(1, 0), m.jointPosition(2, 0),
              m.positionViolation());
  EXPECT_EQ(m.state().limit_side[0], 0);
  EXPECT_EQ(m.state().limit_side[1], 0);
  EXPECT_LT(m.jointPosition(1, 0), 0.035);
  EXPECT_GT(m.jointPosition(1, 0), 0.0);
  EXPECT_EQ(m.jointPosition(2, 0), -m.jointPosition(1, 0));
  EXPECT_LT(m.positionViolation(), 1e-12);
}

}  // namespace
}  // namespace mechanism_sim
