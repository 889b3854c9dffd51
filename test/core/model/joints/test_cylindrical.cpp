// The cylindrical joint: spin and slide decouple for a body symmetric about the axis; with
// Its tree calculation matches its constraint rows.
// the slide held it moves as a revolute joint.
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

// A body symmetric about a vertical cylindrical joint: spin and slide decouple; it falls
// freely and spins at its initial rate.
TEST(Dynamics, CylindricalJointSpinAndSlideDecouple) {
  for (const char* formulation : kFormulations) {
    SCOPED_TRACE(formulation);
    Mechanism m;
    useFormulation(m, formulation);
    const int rotor = m.addBody(body("rotor", 1.5, Vector3d(0.02, 0.02, 0.03), Vector3d(0, 0, 2)));
    m.addJoint(makeJoint("cylindrical", "cyl", Mechanism::kGround, frame(Vector3d(0, 0, 2)), rotor,
                         frame(Vector3d::Zero())));
    m.build();
    m.assemble({}, {CoordinateTarget{0, 0, 7.0}, CoordinateTarget{0, 1, 0.5}});
    runChecked(m, 1500, 1e-3);
    const double t = 1.5;
    EXPECT_NEAR(m.jointPosition(0, 0), 7.0 * t, 1e-9);
    EXPECT_NEAR(m.jointVelocity(0, 0), 7.0, 1e-9);
    EXPECT_NEAR(m.jointPosition(0, 1), 0.5 * t - 0.5 * g0 * t * t, 1e-9);
  }
}

// A compound pendulum on a horizontal cylindrical joint whose slide a drive holds at 0 moves as
// the same pendulum on a revolute joint (Pinocchio's joint-helical test compares the same way).
TEST(Dynamics, CylindricalWithItsSlideHeldMovesAsRevolute) {
  for (const char* formulation : kFormulations) {
    SCOPED_TRACE(formulation);
    auto make = [&](const char* type) {
      auto m = std::make_unique<Mechanism>();
      useFormulation(*m, formulation);
      Body b = body("arm", 1.2, Vector3d(0.01, 0.05, 0.04), Vector3d(0.3, 0.1, 0.0));
      const int arm = m->addBody(b);
      const Matrix3d Rp = Eigen::AngleAxisd(-M_PI / 2, Vector3d::UnitX()).toRotationMatrix();
      m->addJoint(makeJoint(type, "j", Mechanism::kGround, frame(Vector3d::Zero(), Rp), arm, frame(-b.r, Rp)));
      if (std::string(type) == "cylindrical") m->addDrive(0, 1, DriveProfile::velocity(0.0));
      m->build();
      m->assemble();
      return m;
    };
    auto cylinder = make("cylindrical"), revolute = make("revolute");
    for (int s = 0; s < 3000; ++s) cylinder->step(1e-3), revolute->step(1e-3);
    EXPECT_NEAR(cylinder->jointPosition(0, 0), revolute->jointPosition(0, 0), 1e-8);
    EXPECT_NEAR(cylinder->jointPosition(0, 1), 0.0, 1e-12);
    EXPECT_LT((cylinder->position(1) - revolute->position(1)).norm(), 1e-8);
    EXPECT_GT(std::fabs(revolute->jointPosition(0, 0)), 0.1);  // it did swing
  }
}


// The tree calculation (Rz(q0), q1 along bz) against the joint's equations and coordinates
// (tree_calculation.h).
TEST(TreeCalculation, CylindricalMatchesItsConstraintRows) {
  test_util::checkTreeCalculation("cylindrical", JointParams{});
}

}  // namespace
}  // namespace mechanism_sim
