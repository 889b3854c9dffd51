// The tree KKT layout (absolute/kkt_topology.cpp) with limits on joints that hang from
// moving bodies: every ordinary arm. The tree KKT
// factorization holds a joint's limit (and drive) as rows of the joint's block; asking
// for a block between the two bodies of such a limit (which a tree does not have) once
// made every limited joint below a moving link fail to build.
#include <gtest/gtest.h>

#include <cmath>

#include "bodies.h"
#include "mechanism_sim/core/models.h"

namespace mechanism_sim {
namespace {

constexpr double g0 = 9.81;

// A chain of n rods of length L, hinged about y, each with a limit, hanging straight at
// `tilt` rad from -z (the first joint at +-tilt, the others at 0). The top joint's stops
// are at +-1.5 rad, the others' at [lower, upper].
struct Chain {
  Mechanism m;
  Chain(int n, double L, double lower, double upper, double tilt = 0.0) {
    const Quaterniond A(Eigen::AngleAxisd(tilt, Vector3d::UnitY()));
    int parent = Mechanism::kGround;
    for (int k = 0; k < n; ++k) {
      const Vector3d top = A * Vector3d(0, 0, -k * L);
      Body rod = body("rod" + std::to_string(k), 1.0, Vector3d(L * L / 12, L * L / 12, 1e-3).asDiagonal(),
                      top - A * Vector3d(0, 0, L / 2));
      rod.p = A;
      const int b = m.addBody(rod);
      const Vector3d on_parent = parent == Mechanism::kGround ? top : Vector3d(0, 0, -L / 2);
      m.addJoint(makeJoint("revolute", "j" + std::to_string(k), parent, models::axisY(on_parent), b,
                           models::axisY(Vector3d(0, 0, L / 2))));
      if (k == 0) m.setJointLimits(k, 0, -1.5, 1.5);  // the top joint: wide, ground-hung
      else m.setJointLimits(k, 0, lower, upper);
      parent = b;
    }
  }
  double energy() const { return m.kineticEnergy() + m.potentialEnergy(); }
};

// Released sideways, the lower rods swing onto their stops: the run builds and steps, no
// joint passes its stop, the joints stay closed, and the stops (no rebound) only take
// energy away.
TEST(LimitedTree, ChainSwingsOntoItsStopsWithoutPassingThemOrGainingEnergy) {
  const double L = 0.5, stop = 0.3;
  Chain c(3, L, -stop, stop, 1.2);
  c.m.build();
  c.m.assemble();
  ASSERT_NEAR(std::fabs(c.m.jointPosition(0, 0)), 1.2, 1e-12);
  const double E0 = c.energy(), scale = 3 * 1.0 * g0 * L;
  double lowest = E0;
  bool reached = false;
  for (int i = 0; i < 2000; ++i) {
    c.m.step(1e-3);
    for (int j = 1; j < 3; ++j) {
      const double q = c.m.jointPosition(j, 0);
      ASSERT_LE(std::fabs(q), stop + 1e-9) << "joint " << j << " at t = " << c.m.time();
      if (std::fabs(q) > stop - 1e-9) reached = true;
    }
    ASSERT_LE(std::fabs(c.m.jointPosition(0, 0)), 1.5 + 1e-9);
    ASSERT_LT(c.m.positionViolation(), 1e-10 * L);
    const double E = c.energy();
    ASSERT_LE(E, lowest + 1e-9 * scale) << "energy rose at t = " << c.m.time();
    lowest = std::min(lowest, E);
  }
  EXPECT_TRUE(reached) << "no lower joint reached its stop: the test did not test the stops";
  EXPECT_LT(lowest, E0 - 1e-3 * scale) << "an inelastic stop took no energy";
}

// A joint with a drive and a limit has seven rows for its block of six: the limit stays
// weighted (penalty form) between two moving bodies. The drive's prescribed motion is the
// known answer.
TEST(LimitedTree, DrivenJointWithALimitBelowAMovingBodyFollowsItsDrive) {
  const double L = 0.5, w = 0.8;
  Chain c(2, L, -2.0, 2.0);
  c.m.addDrive(1, 0, DriveProfile::velocity(w), 0.0);
  c.m.build();
  c.m.assemble();
  for (int i = 0; i < 1000; ++i) c.m.step(1e-3);
  EXPECT_NEAR(c.m.jointPosition(1, 0), w * 1.0, 1e-9);
  EXPECT_NEAR(c.m.jointVelocity(1, 0), w, 1e-9);
  EXPECT_LT(c.m.positionViolation(), 1e-10 * L);
}

}  // namespace
}  // namespace mechanism_sim
