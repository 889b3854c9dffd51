// Drives and reactions through URDF: the driven slider-crank's torque against inverse
// dynamics by energy balance, reactions equal to the frame transform of -Phi_q^T lambda,
// a command-line drive, and a velocity command's ramp.
#include <gtest/gtest.h>

#include <cmath>

#include "mechanism_sim/urdf/model.h"

namespace mechanism_sim {
namespace {

const std::string kSource = MECHANISM_SIM_SOURCE_DIR;

// Inverse dynamics by energy balance: the drive's power tau w is the rate of change of
// kinetic plus potential energy, dE/dt by five-point central differences (error
// h^4 E^(5) / 30).
TEST(DriveFiles, SliderCrankDrivingTorqueBalancesTheEnergy) {
  auto m = loadModelFile(kSource + "/urdf/slider_crank_driven.urdf");
  const int crank = m->dofIndex("crank_joint");
  ASSERT_GE(crank, 0);
  ASSERT_GE(m->dofs()[crank].drive, 0);
  const double h = 1e-3, w = 2 * M_PI;
  std::vector<double> E, power;
  for (int k = 0; k <= 2000; ++k) {  // two turns
    if (k) m->step(h);
    E.push_back(m->kineticEnergy() + m->potentialEnergy());
    power.push_back(m->effort(crank) * m->velocity(crank));
    ASSERT_NEAR(m->velocity(crank), w, 1e-9);
  }
  double worst = 0, peak = 0;
  for (size_t k = 2; k + 2 < E.size(); ++k) {
    const double dEdt = (-E[k + 2] + 8 * E[k + 1] - 8 * E[k - 1] + E[k - 2]) / (12 * h);
    worst = std::max(worst, std::fabs(power[k] - dEdt));
    peak = std::max(peak, std::fabs(power[k]));
  }
  std::printf("driven slider-crank: peak power %.4f W, |tau w - dE/dt| %.2e W\n", peak, worst);
  EXPECT_GT(peak, 1.0);  // the drive works against gravity and inertia
  EXPECT_LT(worst, 1e-8 * peak);
  EXPECT_NEAR(m->position(crank), 2 * w, 1e-9);
}

// Reactions in the joint frame on the child are R^T of the constraint's wrench
// -Phi_q^T lambda (global, about the joint point), R the child link's orientation (for a
// URDF tree joint the joint frame is the child link's frame); checked on a mechanism whose
// equations are independent, with nothing applied along its joints.
TEST(DriveFiles, ReactionsAreTheChildFrameTransformOfPhiQTransposeLambda) {
  auto m = loadModelFile(kSource + "/urdf/rssr_linkage.urdf");
  ASSERT_EQ(m->dependencies().dependent, 0);
  for (int k = 0; k < 300; ++k) m->step(1e-3);
  const std::vector<JointReaction> r = m->jointReactions();
  const Mechanism& mech = m->mechanism();
  ASSERT_EQ(static_cast<int>(r.size()), mech.numJoints());
  int checked = 0;
  for (const TreeJoint& tj : m->treeJoints()) {
    if (tj.fixed) continue;
    int j = 0;
    while (j < mech.numJoints() && mech.joint(j).name() != tj.name) ++j;
    ASSERT_LT(j, mech.numJoints());
    const Reaction g = mech.reaction(mech.jointConstraintIndex(j));
    const Eigen::Isometry3d child = m->linkPose(m->linkIndex(tj.child));
    const Eigen::Vector3d f = child.linear().transpose() * g.force, t = child.linear().transpose() * g.torque;
    const double scale = 1e-9 * (1 + g.force.norm() + g.torque.norm());
    EXPECT_LT((r[j].force - f).norm(), scale) << tj.name;
    EXPECT_LT((r[j].torque - t).norm(), scale) << tj.name;
    EXPECT_EQ(r[j].joint, tj.name);
    ++checked;
  }
  EXPECT_GE(checked, 2);
}

// simulate --drive: a command-line drive replaces the file's initial velocity and moves
// the crank exactly as the driven file does.
TEST(DriveFiles, CommandLineDriveEqualsTheFileDrive) {
  LoadOptions o;
  o.drives.push_back({"crank_joint", 2 * M_PI});
  auto a = loadModelFile(kSource + "/urdf/slider_crank.urdf", o);
  auto b = loadModelFile(kSource + "/urdf/slider_crank_driven.urdf");
  const int ca = a->dofIndex("crank_joint"), cb = b->dofIndex("crank_joint");
  for (int k = 0; k < 500; ++k) a->step(1e-3), b->step(1e-3);
  EXPECT_NEAR(a->position(ca), b->position(cb), 1e-12);
  EXPECT_NEAR(a->effort(ca), b->effort(cb), 1e-9);
  LoadOptions bad;
  bad.drives.push_back({"no_such_joint", 1.0});
  EXPECT_THROW(loadModelFile(kSource + "/urdf/slider_crank.urdf", bad), LoadError);
}

TEST(DriveFiles, VelocityCommandRampsTheDrivenCrank) {
  auto m = loadModelFile(kSource + "/urdf/slider_crank_driven.urdf");
  const int crank = m->dofIndex("crank_joint");
  m->commandDriveVelocity(crank, 0.0, 2 * M_PI);  // stop within 1 s
  for (int k = 0; k < 500; ++k) m->step(1e-3);
  EXPECT_NEAR(m->velocity(crank), M_PI, 1e-9);
  for (int k = 0; k < 600; ++k) m->step(1e-3);
  EXPECT_NEAR(m->velocity(crank), 0.0, 1e-9);
  EXPECT_NEAR(m->position(crank), M_PI, 1e-9);  // 2 pi / 2 over the ramp
  EXPECT_THROW(m->commandDriveVelocity(m->dofIndex("slider_joint"), 1.0, 1.0), UsageError);
  m->reset();
  EXPECT_NEAR(m->velocity(crank), 2 * M_PI, 1e-9);  // the ramp is in the State
}

// The parallel gripper rests against its stops from t = 0.065 s with velocities of
// round-off size: its equations are judged against what its loads would do (gravity, the
// actuator), not round-off over round-off, so every iteration meets its tolerance.
TEST(DriveFiles, AMechanismAtRestAgainstItsStopsMeetsEveryTolerance) {
  auto m = loadModelFile(kSource + "/urdf/parallel_gripper.urdf");
  for (int k = 0; k < 2000; ++k) m->step(1e-3);
  EXPECT_EQ(m->solverStats().shortfalls(), 0) << m->solverStats().describe();
  EXPECT_LT(m->relativeVelocityViolation(), 1e-12);
  EXPECT_LT(m->relativePositionViolation(), 1e-12);
}

}  // namespace
}  // namespace mechanism_sim
