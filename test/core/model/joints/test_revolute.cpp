// The revolute joint: a pendulum released from the horizontal has the exact period.
// Its tree calculation matches its constraint rows.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>

#include "bodies.h"
#include "joint_motion.h"
#include "tree_calculation.h"
#include "mechanism_sim/core/mechanism.h"
#include "mechanism_sim/core/models.h"

namespace mechanism_sim {
namespace {

constexpr double g0 = 9.81;

using test_util::body;
using test_util::frame;
using test_util::kFormulations;
using test_util::runChecked;
using test_util::useFormulation;

// A 1 kg point mass on a massless 1 m rod, released from the horizontal: the period is
// 4 sqrt(L/g) K(sin(pi/4)) = 2.36784194757624 s for g = 9.81.
TEST(Dynamics, PendulumReleasedHorizontallyHasTheExactPeriod) {
  for (const char* formulation : kFormulations) {
    SCOPED_TRACE(formulation);
    Mechanism m;
    useFormulation(m, formulation);
    const int b = m.addBody(body("bob", 1.0, Vector3d::Zero(), Vector3d(1, 0, 0)));
    m.addJoint(makeJoint("revolute", "pivot", Mechanism::kGround, models::axisY(Vector3d::Zero()), b,
                         models::axisY(Vector3d(-1, 0, 0))));
    m.build();
    m.assemble();
    const double h = 1e-3;
    double prev_w = 0, prev_t = 0, prev2_w = 0, prev2_t = 0;
    std::vector<double> turns;  // times where the angular velocity changes sign
    for (int s = 0; s < 5000; ++s) {
      m.step(h);
      const double w = m.jointVelocity(0, 0);
      if (s > 2 && ((prev_w < 0) != (w < 0))) {
        // Root of the parabola through the last three (t, w).
        const double t0 = prev2_t, t1 = prev_t, t2 = m.time();
        const double a = ((w - prev_w) / (t2 - t1) - (prev_w - prev2_w) / (t1 - t0)) / (t2 - t0);
        const double bq = (prev_w - prev2_w) / (t1 - t0) - a * (t0 + t1);
        const double c = prev2_w - a * t0 * t0 - bq * t0;
        const double disc = std::sqrt(bq * bq - 4 * a * c);
        double r1 = (-bq + disc) / (2 * a), r2 = (-bq - disc) / (2 * a);
        turns.push_back(std::fabs(r1 - 0.5 * (t1 + t2)) < std::fabs(r2 - 0.5 * (t1 + t2)) ? r1 : r2);
      }
      prev2_w = prev_w, prev2_t = prev_t, prev_w = w, prev_t = m.time();
    }
    ASSERT_GE(turns.size(), 3u);
    EXPECT_NEAR(turns[1], 2.36784194757624, 1e-7);
    EXPECT_NEAR(turns[0], 2.36784194757624 / 2, 1e-7);
    EXPECT_NEAR(turns[2] - turns[0], 2.36784194757624, 1e-7);
  }
}

// The tree calculation (Rz(q) and S = (bz; 0)) against the joint's equations and coordinates
// (tree_calculation.h).
TEST(TreeCalculation, RevoluteMatchesItsConstraintRows) {
  test_util::checkTreeCalculation("revolute", JointParams{});
}

}  // namespace
}  // namespace mechanism_sim
