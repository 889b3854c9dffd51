// The universal joint: its tree calculation matches its constraint rows.
#include <gtest/gtest.h>

#include "tree_calculation.h"

namespace mechanism_sim {
namespace {

// The tree calculation (R = Rx(q0) Ry(q1), the first axis turning with q1: its bias)
// against the joint's equations and coordinates (tree_calculation.h).
TEST(TreeCalculation, UniversalMatchesItsConstraintRows) {
  test_util::checkTreeCalculation("universal", JointParams{});
}

}  // namespace
}  // namespace mechanism_sim
