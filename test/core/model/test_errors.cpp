// The error hierarchy (errors.h): every misuse of the API throws the library's own type,
// catchable as mechanism_sim::Error, with its message; a model that cannot be built is a
// ModelError, a call the API does not take a UsageError.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <string>

#include "mechanism_sim/core/models.h"

namespace mechanism_sim {
namespace {

// A pendulum: one body on a revolute about y at the origin, optionally velocity driven.
struct Pendulum {
  Mechanism mech;
  explicit Pendulum(bool driven = false, bool build = true) {
    Body b;
    b.name = "bob";
    b.m = 1.0;
    b.Jp = 0.01 * Matrix3d::Identity();
    b.r = Vector3d(0.5, 0, 0);
    const int body = mech.addBody(b);
    mech.addJoint(makeJoint("revolute", "pivot", Mechanism::kGround, models::axisY(Vector3d::Zero()), body,
                            models::axisY(Vector3d(-0.5, 0, 0))));
    if (driven) mech.addDrive(0, 0, DriveProfile::velocity(1.0));
    if (build) {
      mech.build();
      mech.assemble();
    }
  }
};

// f throws E, which is a mechanism_sim::Error, and its message contains `says`.
template <class E>
void expectError(const std::function<void()>& f, const std::string& says) {
  try {
    f();
    ADD_FAILURE() << "nothing thrown (expected '" << says << "')";
  } catch (const E& e) {
    EXPECT_NE(dynamic_cast<const Error*>(&e), nullptr) << e.what();
    EXPECT_NE(std::string(e.what()).find(says), std::string::npos) << e.what();
  } catch (const std::exception& e) {
    ADD_FAILURE() << "another type thrown: " << e.what();
  }
}

TEST(Errors, CallsBeforeBuildAreUsageErrors) {
  Pendulum p(true, false);
  expectError<UsageError>([&] { p.mech.step(1e-3); }, "Mechanism::step before build()");
  expectError<UsageError>([&] { p.mech.setJointEffort(0, 0, 1.0); }, "before build()");
  expectError<UsageError>([&] { p.mech.setBodyWrench(1, Vector3d::Zero(), Vector3d::Zero()); }, "before build()");
  expectError<UsageError>([&] { p.mech.commandDriveVelocity(0, 1.0, 1.0); }, "before build()");
  expectError<UsageError>([&] { p.mech.removeDrive(0); }, "before build()");
}

TEST(Errors, CallsAfterBuildThatChangeTheLayoutAreUsageErrors) {
  Pendulum p;
  Body b;
  b.name = "late";
  b.m = 1.0;
  b.Jp = Matrix3d::Identity();
  expectError<UsageError>([&] { p.mech.addBody(b); }, "Mechanism::addBody after build()");
}

TEST(Errors, BadIndicesAreUsageErrors) {
  Pendulum p(true);
  expectError<UsageError>([&] { p.mech.setJointEffort(5, 0, 1.0); }, "no such joint coordinate");
  expectError<UsageError>([&] { p.mech.setJointEffort(0, 1, 1.0); }, "no such joint coordinate");
  expectError<UsageError>([&] { p.mech.setJointEffort(-1, 0, 1.0); }, "no such joint coordinate");
  expectError<UsageError>([&] { p.mech.removeDrive(3); }, "no such drive");
}

TEST(Errors, NonFiniteArgumentsAreUsageErrors) {
  Pendulum p(true);
  expectError<UsageError>([&] { p.mech.setJointEffort(0, 0, NAN); }, "effort must be finite");
  expectError<UsageError>([&] { p.mech.setBodyWrench(1, Vector3d(NAN, 0, 0), Vector3d::Zero()); },
                          "wrench must be finite");
  expectError<UsageError>([&] { p.mech.commandDriveVelocity(0, INFINITY, 1.0); }, "drive velocity must be finite");
  expectError<UsageError>([&] { p.mech.commandDriveVelocity(0, 1.0, 0.0); }, "acceleration must be positive");
  expectError<UsageError>([&] { p.mech.step(0.0); }, "step must be positive and finite");
  expectError<UsageError>([&] { p.mech.step(NAN); }, "step must be positive and finite");
  expectError<UsageError>([] { DriveProfile::velocity(NAN); }, "drive velocity must be finite");
  expectError<UsageError>([] { DriveProfile::spline({0.0}, {1.0}); }, "spline drive: needs at least 2 points");
}

// A step refused for its argument leaves the mechanism as it was: it steps on afterwards.
TEST(Errors, ARefusedStepLeavesTheStateAlone) {
  Pendulum p;
  const Mechanism::Snapshot before = p.mech.snapshot();
  EXPECT_THROW(p.mech.step(-1.0), UsageError);
  EXPECT_EQ(p.mech.time(), before.t);
  EXPECT_EQ(p.mech.snapshot().x, before.x);
  EXPECT_NO_THROW(p.mech.step(1e-3));
}

TEST(Errors, AnotherMechanismsSnapshotIsAUsageError) {
  Pendulum one;
  Mechanism two;
  models::pendulumChain(two, 2);
  two.build();
  two.assemble();
  expectError<UsageError>([&] { one.mech.restore(two.snapshot()); }, "the snapshot is of another mechanism");
}

TEST(Errors, AnUnknownJointTypeIsAModelError) {
  expectError<ModelError>([] { makeJoint("hinge", "j", 1, JointFrame(), 2, JointFrame()); },
                          "joint 'j': unknown joint type 'hinge'");
  expectError<ModelError>([] { makeJoint("screw", "j", 1, JointFrame(), 2, JointFrame(), JointParams{NAN, 0.0}); },
                          "screw joint 'j': lead must be finite");
}

TEST(Errors, UsageErrorIsNeitherAModelNorASimulationError) {
  const UsageError e("x");
  const Error& base = e;
  EXPECT_EQ(dynamic_cast<const ModelError*>(&base), nullptr);
  EXPECT_EQ(dynamic_cast<const SimulationError*>(&base), nullptr);
  EXPECT_STREQ(e.what(), "x");
}

}  // namespace
}  // namespace mechanism_sim
