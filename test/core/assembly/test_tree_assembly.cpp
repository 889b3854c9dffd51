// assembleOnTree (assembly/tree_assembly.cpp) on its own: the continuation in the tree's
// joint coordinates. Oracles: the tree's joints hold to round-off at the pose it returns
// (they are exact by construction, the forward kinematics of q), the loop's own equation
// |C - D| = c (the coupler's end on the rocker's circle) closes, and every limited
// coordinate ends within its limits whatever its start.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "assembly/four_bar_parts.h"
#include "core/absolute/stepper.h"
#include "core/assembly/tree_assembly.h"
#include "core/joint_space/tree.h"

namespace mechanism_sim {
namespace {

using namespace test_util::assembly;

// The largest residual of the equations of the tree's joints (not the cut ones).
double treeJointsResidual(const System& sys, const TreeModel& model, const Evaluation& ev) {
  std::vector<char> cut(sys.numJoints(), 0);
  for (int j : model.cut_joints) cut[j] = 1;
  double worst = 0;
  for (int j = 0; j < sys.numJoints(); ++j) {
    if (cut[j]) continue;
    const ConstraintLayout& L = sys.layout[sys.joint_constraint[j]];
    if (L.size > 0) worst = std::max(worst, ev.Phi.segment(L.row, L.size).cwiseAbs().maxCoeff());
  }
  return worst;
}

TEST(TreeAssembly, AFourBarSixTenthsOfAMetreApartClosesWithItsTreeJointsExact) {
  Mechanism m;
  Parts p{m};
  FourBar fb;
  fb.build(p);
  m.build();
  const System& sys = m.system();
  State s = m.state();
  Stepper st(sys);
  const TreeModel model(sys);
  ASSERT_EQ(model.cut_joints.size(), 1u);
  st.load(sys, s.x.data(), s.u.data());
  st.evaluate(sys, s);
  ASSERT_GT(st.evaluation().Phi.cwiseAbs().maxCoeff(), 0.1);  // the file's pose is open
  const double residual = assembleOnTree(sys, s, st, {}, model);
  EXPECT_LT(residual, 1e-12);
  EXPECT_LT(treeJointsResidual(sys, model, st.evaluation()), 1e-14);
  // C = D + c (cos, sin) of the rocker: the coupler's end on the rocker's circle about D.
  const Vector3d C = s.x.segment<3>(BodyCoordinates::x(fb.coupler - 1)) +
                     Eigen::Quaterniond(s.x[BodyCoordinates::x(fb.coupler - 1) + 3], s.x[BodyCoordinates::x(fb.coupler - 1) + 4],
                                        s.x[BodyCoordinates::x(fb.coupler - 1) + 5], s.x[BodyCoordinates::x(fb.coupler - 1) + 6])
                             .toRotationMatrix() *
                         (fb.C1 - p.r[fb.coupler]);
  EXPECT_NEAR((C - fb.D).norm(), fb.c, 1e-12);
}

// The rocker's limits exclude both the file's pose and the free closing's rocker angle: the
// iterates are clamped, so the pose returned has the rocker within them.
TEST(TreeAssembly, ALimitedCoordinateEndsWithinItsLimits) {
  const double q_free = FourBar().freeRockerAngle();
  Mechanism m;
  Parts p{m};
  FourBar fb;
  fb.build(p);
  const double lo = q_free > 0 ? q_free - 0.4 : q_free + 0.1, hi = lo + 0.3;
  ASSERT_TRUE(q_free < lo || q_free > hi);
  ASSERT_TRUE(0.0 < lo || 0.0 > hi);
  m.setJointLimits(fb.rocker_joint, 0, lo, hi);
  m.build();
  const System& sys = m.system();
  State s = m.state();
  Stepper st(sys);
  const TreeModel model(sys);
  assembleOnTree(sys, s, st, {}, model);
  Row rows[kMaxJointDofs];
  const Joint& rocker = *sys.joints[fb.rocker_joint];
  const Evaluation& ev = st.evaluation();
  rocker.coordinates(ev.kin[rocker.bodyI()], ev.kin[rocker.bodyJ()], s.tracked[rocker.id()], rows);
  EXPECT_GE(rows[0].Phi, lo - 1e-12);
  EXPECT_LE(rows[0].Phi, hi + 1e-12);
  EXPECT_LT(treeJointsResidual(sys, model, ev), 1e-14);
}

}  // namespace
}  // namespace mechanism_sim
