// The spherical joint: a conical pendulum turns steadily at its analytic rate.
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

// A conical pendulum: a bob on a spherical joint at angle theta from the vertical, turning
// about the vertical at Omega = sqrt(g / (L cos theta)), keeps its height and its rate
// (isotropic inertia: no gyroscopic torque).
TEST(Dynamics, ConicalPendulumTurnsSteadilyAtItsRate) {
  const double L = 0.8, theta = 0.6, Omega = std::sqrt(g0 / (L * std::cos(theta)));
  for (const char* formulation : kFormulations) {
    SCOPED_TRACE(formulation);
    Mechanism m;
    useFormulation(m, formulation);
    const Vector3d r(L * std::sin(theta), 0, -L * std::cos(theta));
    const int bob = m.addBody(body("bob", 2.0, Vector3d(1e-4, 1e-4, 1e-4), r));
    m.addJoint(makeJoint("spherical", "ball", Mechanism::kGround, frame(Vector3d::Zero()), bob, frame(-r)));
    m.build();
    m.assemble({}, {CoordinateTarget{0, 0, 0.0}, CoordinateTarget{0, 1, 0.0}, CoordinateTarget{0, 2, Omega}});
    runChecked(m, 2000, 1e-3);
    EXPECT_NEAR(m.position(bob).z(), r.z(), 1e-9);
    const double t = m.time(), phi = Omega * t;
    EXPECT_LE((m.position(bob) - Vector3d(L * std::sin(theta) * std::cos(phi), L * std::sin(theta) * std::sin(phi), r.z())).norm(), 1e-8);
    EXPECT_NEAR(m.jointVelocity(0, 2), Omega, 1e-8);
  }
}

// The tree calculation (the quaternion of frame j in frame i, rates in frame i) against the
// joint's equations and coordinates (tree_calculation.h).
TEST(TreeCalculation, SphericalMatchesItsConstraintRows) {
  test_util::checkTreeCalculation("spherical", JointParams{});
}

}  // namespace
}  // namespace mechanism_sim
