// The fixed joint: its tree calculation (no coordinate, frames coincident) matches its
// constraint rows.
#include <gtest/gtest.h>

#include "tree_calculation.h"

namespace mechanism_sim {
namespace {

// No coordinate, R = 1, t = 0: the bodies placed so satisfy the joint's equations
// (tree_calculation.h).
TEST(TreeCalculation, FixedMatchesItsConstraintRows) {
  const TreeJointModel* m = treeJointModel("fixed");
  ASSERT_NE(m, nullptr);
  EXPECT_EQ(m->nq, 0);
  EXPECT_EQ(m->nv, 0);
  test_util::checkTreeCalculation("fixed", JointParams{});
}

}  // namespace
}  // namespace mechanism_sim
