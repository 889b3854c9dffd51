// The prismatic joint: a body slides down a frictionless incline at g sin(beta).
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

// A body on a frictionless incline (30 degrees) slides with s'' = g sin 30; the joint
// point and the body's centre of mass differ, and the body is rotated.
TEST(Dynamics, BodySlidesOnInclinedPrismaticJoint) {
  for (const char* formulation : kFormulations) {
    SCOPED_TRACE(formulation);
    const double beta = M_PI / 6;
    // Prismatic axis z_i down the slope: in the x-z plane, descending along +x.
    const Matrix3d Rp = Eigen::AngleAxisd(M_PI / 2 + beta, Vector3d::UnitY()).toRotationMatrix();
    Mechanism m;
    useFormulation(m, formulation);
    Body b = body("block", 3.0, Vector3d(0.1, 0.2, 0.3), Vector3d(0.2, 0.1, 0.5));
    b.p = Quaterniond(Eigen::AngleAxisd(0.4, Vector3d(1, 2, 3).normalized()));
    const int blk = m.addBody(b);
    const Matrix3d A = b.p.toRotationMatrix();
    const Vector3d sp_j(0.05, -0.1, 0.02);
    m.addJoint(makeJoint("prismatic", "slide", Mechanism::kGround,
                         frame(b.r + A * sp_j, Rp), blk, frame(sp_j, A.transpose() * Rp)));
    m.build();
    m.assemble();
    runChecked(m, 2000, 1e-3);
    EXPECT_NEAR(m.jointPosition(0, 0), 0.5 * g0 * std::sin(beta) * 4.0, 1e-10);
    EXPECT_NEAR(m.jointVelocity(0, 0), g0 * std::sin(beta) * 2.0, 1e-10);
  }
}

// The tree calculation (q along bz and S = (0; bz)) against the joint's equations and
// coordinates (tree_calculation.h).
TEST(TreeCalculation, PrismaticMatchesItsConstraintRows) {
  test_util::checkTreeCalculation("prismatic", JointParams{});
}

}  // namespace
}  // namespace mechanism_sim
