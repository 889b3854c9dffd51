// The screw joint: a nut falls on a vertical screw at the analytic acceleration; a screw of
// Its tree calculation matches its constraint rows.
// zero lead moves as a revolute joint.
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

// A nut on a vertical screw falls with z'' = -g m alpha^2 / (m alpha^2 + I_zz).
TEST(Dynamics, NutFallsOnVerticalScrewAtTheAnalyticAcceleration) {
  for (const char* formulation : kFormulations) {
    SCOPED_TRACE(formulation);
    const double mass = 2.0, Izz = 0.01, alpha = 0.01;
    Mechanism m;
    useFormulation(m, formulation);
    const int nut = m.addBody(body("nut", mass, Vector3d(0.007, 0.007, Izz), Vector3d(0, 0, 1)));
    JointParams p;
    p.alpha = alpha;
    m.addJoint(makeJoint("screw", "screw", Mechanism::kGround, frame(Vector3d(0, 0, 1)), nut,
                         frame(Vector3d::Zero()), p));
    m.build();
    m.assemble();
    runChecked(m, 1000, 1e-3);
    const double a = -g0 * mass * alpha * alpha / (mass * alpha * alpha + Izz);
    // 1e-10: the accelerations are solved to 1e-11 relative, integrated over 1000 steps.
    EXPECT_NEAR(m.position(nut).z() - 1.0, 0.5 * a * 1.0, 1e-10);
    EXPECT_NEAR(m.jointPosition(0, 0), 0.5 * a / alpha, 1e-9);  // phi = z / alpha
    EXPECT_NEAR(m.jointVelocity(0, 0), a / alpha, 1e-9);
  }
}

// A compound pendulum with a screw of zero lead moves exactly as with a revolute.
TEST(Dynamics, ScrewOfZeroPitchMovesAsRevolute) {
  auto make = [](const char* type, const char* formulation) {
    auto m = std::make_unique<Mechanism>();
    useFormulation(*m, formulation);
    Body b = body("arm", 1.2, Vector3d(0.01, 0.05, 0.04), Vector3d(0.3, 0.1, 0.0));
    const int arm = m->addBody(b);
    const Matrix3d Rp = Eigen::AngleAxisd(-M_PI / 2, Vector3d::UnitX()).toRotationMatrix();
    m->addJoint(makeJoint(type, "j", Mechanism::kGround, frame(Vector3d::Zero(), Rp), arm,
                          frame(-b.r, Rp), JointParams{0.0, 0.0}));
    m->build();
    m->assemble();
    return m;
  };
  for (const char* formulation : kFormulations) {
  SCOPED_TRACE(formulation);
  auto screw = make("screw", formulation), revolute = make("revolute", formulation);
  for (int s = 0; s < 3000; ++s) {
    screw->step(1e-3);
    revolute->step(1e-3);
  }
  // Same motion, different equations: they agree to the solver tolerances.
  EXPECT_NEAR(screw->jointPosition(0, 0), revolute->jointPosition(0, 0), 1e-8);
  EXPECT_LT((screw->position(1) - revolute->position(1)).norm(), 1e-8);
  EXPECT_GT(std::fabs(revolute->jointPosition(0, 0)), 0.1);  // it did swing
  }
}

// The tree calculation (Rz(phi), alpha (phi - phi0) along bz, S = (bz; alpha bz)) against the
// joint's equations and coordinates (tree_calculation.h).
TEST(TreeCalculation, ScrewMatchesItsConstraintRows) {
  test_util::checkTreeCalculation("screw", JointParams{0.07, 0.3});
}

}  // namespace
}  // namespace mechanism_sim
