// What the closures of a tree are (ClosureRows, loop_closure.h), built once from the tree
// and the System. Known answers on the planar four-bar of loop_cases.h with a limit on its
// crank: the closures are the cut revolute's constraint and the limit's, in System order;
// the cut revolute keeps the two of its five rows that motion in the plane moves (the
// out-of-plane point row and the two axis rows are idle), the limit its one; each row maps
// to its System row; the loop's rows touch the coordinates on its two bodies' paths (all
// three), the limit's row (a direct row on q) its crank's only.
#include <gtest/gtest.h>

#include <vector>

#include "loop_cases.h"
#include "core/joint_space/loop_closure.h"

namespace mechanism_sim {
namespace {

using test_util::Builder;
using test_util::fourBar;

TEST(ClosureRows, FourBarWithACrankLimit) {
  for (double L : {1.0, 1e3}) {
    Builder b = fourBar(L, L);
    b.addLimit(0, 0, -1.0, 1.0);  // the crank's revolute
    System& sys = *b.sys;
    sys.finalize();
    const TreeModel model(sys);
    ASSERT_EQ(model.cut_joints.size(), 1u);
    const LoopClosures cl(model, sys);
    ASSERT_EQ(cl.constraints.size(), 2u);
    const int cut = sys.joint_constraint[model.cut_joints[0]];
    EXPECT_EQ(cl.constraints[0], cut);
    EXPECT_EQ(sys.constraints[cl.constraints[1]]->limit(), 0);
    EXPECT_FALSE(cl.onlyLimits());
    // rows: the loop's two in-plane rows, then the limit's
    EXPECT_EQ(cl.m, 3);
    EXPECT_EQ(cl.idleRowCount(), 3);
    EXPECT_EQ(cl.row, (std::vector<int>{0, 2}));
    EXPECT_EQ(cl.nv, 3);
    ASSERT_EQ(cl.sys_row.size(), 3u);
    const int r0 = sys.layout[cut].row;
    EXPECT_GE(cl.sys_row[0], r0);
    EXPECT_LT(cl.sys_row[0], cl.sys_row[1]);
    EXPECT_LT(cl.sys_row[1], r0 + 5);
    EXPECT_EQ(cl.sys_row[2], sys.layout[cl.constraints[1]].row);
    // the coordinates each row may touch
    for (int e = 0; e < 2; ++e) EXPECT_EQ(cl.rowColumns(e).size(), 3u) << "loop row " << e;
    EXPECT_EQ(cl.rowColumns(2), (std::vector<int>{model.links[model.joint_link[0]].iv}));
  }
}

TEST(ClosureRows, ATreeWithOnlyLimitsHasOnlyLimitRows) {
  Builder b = fourBar(1.0, 1.0);
  b.sys->joints.pop_back();  // (the closing revolute off: a tree)
  b.sys->joint_constraint.pop_back();
  b.sys->constraints.pop_back();
  b.addLimit(1, 0, -0.5, 0.5);
  b.addLimit(2, 0, -0.5, 0.5);
  System& sys = *b.sys;
  sys.finalize();
  const TreeModel model(sys);
  EXPECT_TRUE(model.cut_joints.empty());
  const LoopClosures cl(model, sys);
  EXPECT_TRUE(cl.onlyLimits());
  EXPECT_EQ(cl.m, 2);
  EXPECT_EQ(cl.idleRowCount(), 0);
  // a limit's row touches its coordinate and those of the links between it and the ground
  EXPECT_EQ(cl.rowColumns(0).size(), 2u);  // the coupler's revolute, on the crank
  EXPECT_EQ(cl.rowColumns(1).size(), 1u);  // the rocker's, on the ground
}

}  // namespace
}  // namespace mechanism_sim
