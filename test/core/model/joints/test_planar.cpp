// The planar joint: a body on a vertical plane flies a parabola and keeps its spin.
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

// A body on a vertical planar joint (the plane x-z, normal y) moves as a free body in that
// plane: its centre of mass flies a parabola, its spin about the normal stays, whatever the
// joint point's offset from the centre of mass.
TEST(Dynamics, BodyOnAVerticalPlaneFliesAParabolaAndKeepsItsSpin) {
  for (const char* formulation : kFormulations) {
    SCOPED_TRACE(formulation);
    Mechanism m;
    useFormulation(m, formulation);
    const Vector3d r(0.2, 0.0, 1.0), sp(0.1, 0.0, -0.05);  // the joint point off the centre of mass
    const int b = m.addBody(body("puck", 1.5, Vector3d(0.02, 0.03, 0.04), r));
    // z of the joint frames along the plane's normal, y of the world
    const Matrix3d N = Eigen::AngleAxisd(-M_PI / 2, Vector3d::UnitX()).toRotationMatrix();
    m.addJoint(makeJoint("planar", "plane", Mechanism::kGround, frame(r + sp, N), b, frame(sp, N)));
    m.build();
    const Vector3d v0(1.5, 0.0, 2.0);
    const double w0 = 3.0;  // spin about the world's y
    // the body's state: the centre of mass's velocity and the spin, set by the joint's rates
    // at its point (v_P = v_cm + w x (P - cm))
    const Vector3d w(0, w0, 0), vP = v0 + w.cross(sp);
    const Vector3d vP_joint = N.transpose() * vP;
    m.assemble({}, {CoordinateTarget{0, 0, vP_joint.x()}, CoordinateTarget{0, 1, vP_joint.y()},
                    CoordinateTarget{0, 2, (N.transpose() * w).z()}});
    runChecked(m, 1500, 1e-3);
    const double t = m.time();
    const Vector3d expected = r + v0 * t + 0.5 * Vector3d(0, 0, -g0) * t * t;
    EXPECT_LE((m.position(b) - expected).norm(), 1e-9);
    EXPECT_NEAR(m.jointVelocity(0, 2), (N.transpose() * w).z(), 1e-9);
  }
}

// The tree calculation (Rz(q2), (q0, q1, 0), and the bias of the turning translation axes)
// against the joint's equations and coordinates (tree_calculation.h).
TEST(TreeCalculation, PlanarMatchesItsConstraintRows) {
  test_util::checkTreeCalculation("planar", JointParams{});
}

}  // namespace
}  // namespace mechanism_sim
