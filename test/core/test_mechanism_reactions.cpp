// Joint reactions (Mechanism::jointReactions): a pendulum's pivot carries m (a - g), the
// centripetal load included; a door on two coaxial hinges (dependent equations) gets the
// least-norm split, the same whatever the history; a driven joint's torque is in its
// reaction.
#include <gtest/gtest.h>

#include <cmath>

#include "bodies.h"
#include "mechanism_sim/core/models.h"

namespace mechanism_sim {
namespace {

constexpr double kG = 9.81;

JointFrame axisZ(const Vector3d& sp) {
  JointFrame f;
  f.sp_B = sp;
  return f;
}


// Released from the horizontal about a revolute (axis y at the origin): with I_o = m L^2 +
// Ic the energy gives q_dot^2 = 2 m g L sin q / I_o and q_ddot = m g L cos q / I_o (q below
// the horizontal), so the centre of mass accelerates by L q_ddot along the tangent and
// L q_dot^2 towards the pivot, and the pivot pushes with m (a - g).
TEST(Reactions, PendulumPivotCarriesGravityAndTheCentripetalLoad) {
  const double m = 1.5, L = 0.8, Ic = 0.02, Io = m * L * L + Ic;
  Mechanism mech;
  const int b = mech.addBody(body("bob", m, Ic * Matrix3d::Identity(), Vector3d(L, 0, 0)));
  mech.addJoint(makeJoint("revolute", "pivot", Mechanism::kGround, models::axisY(Vector3d::Zero()), b,
                          models::axisY(Vector3d(-L, 0, 0))));
  mech.build();
  mech.assemble();
  double worst = 0, worst_torque = 0, peak = 0;
  for (int k = 0; k < 1500; ++k) {
    mech.step(1e-3);
    const double q = mech.jointPosition(0, 0);
    const Vector3d e_n(-std::cos(q), 0, std::sin(q));  // from the bob to the pivot
    const Vector3d e_t(-std::sin(q), 0, -std::cos(q));  // direction of increasing q
    const double q_dot2 = 2 * m * kG * L * std::sin(q) / Io, q_ddot = m * kG * L * std::cos(q) / Io;
    const Vector3d a = L * q_ddot * e_t + L * q_dot2 * e_n;
    const Vector3d expected = m * (a - Vector3d(0, 0, -kG));
    const Reaction r = mech.jointReactions()[0];
    worst = std::max(worst, (r.force - expected).norm());
    worst_torque = std::max(worst_torque, r.torque.norm());
    peak = std::max(peak, expected.norm());
  }
  std::printf("pendulum pivot: |F - m (a - g)| %.2e N (peak %.2f N, 3 m g = %.2f at the bottom for a point mass); |torque| %.2e N m\n",
              worst, peak, 3 * m * kG, worst_torque);
  EXPECT_LT(worst, 1e-8 * peak);
  EXPECT_LT(worst_torque, 1e-8 * peak * L);  // a revolute about y carries no moment in a planar swing
  EXPECT_GT(peak, 2.5 * m * kG);  // the centripetal load was there
}

// A door hanging on two coaxial hinges at +-d from its centre of mass along the axis
// (vertical, z): 5 of the 10 equations are dependent. The least-norm reactions share the
// weight equally, balance the moments, and do not depend on how the state was reached.
TEST(Reactions, DoorOnTwoHingesGetsTheLeastNormSplitWhateverTheHistory) {
  const double m = 20.0, d = 0.9, w = 0.4;
  Mechanism mech;
  Matrix3d J = Matrix3d::Identity();
  J.diagonal() << 2.0, 1.5, 0.6;
  const int b = mech.addBody(body("door", m, J, Vector3d(w, 0, 0)));
  for (int h = 0; h < 2; ++h) {
    const double z = h ? d : -d;
    mech.addJoint(makeJoint("revolute", h ? "upper" : "lower", Mechanism::kGround, axisZ(Vector3d(0, 0, z)), b,
                            axisZ(Vector3d(-w, 0, z))));
  }
  mech.setGravity(Vector3d(0, 0, -kG));
  mech.build();
  mech.assemble({}, {CoordinateTarget{0, 0, 1.0}});  // swinging at 1 rad/s
  ASSERT_GT(mech.dependencies().dependent, 0);
  const Mechanism::Snapshot start = mech.snapshot();
  for (int k = 0; k < 300; ++k) mech.step(1e-3);
  const std::vector<Reaction> r1 = mech.jointReactions();
  const Mechanism::Snapshot there = mech.snapshot();
  // total: m (a - g) with a = -w omega^2 towards the axis (no gravity torque about z)
  const Vector3d total = r1[0].force + r1[1].force;
  const double omega = mech.jointVelocity(0, 0);
  const Vector3d centre = mech.position(b);
  const Vector3d a = -omega * omega * Vector3d(centre.x(), centre.y(), 0);
  EXPECT_LT((total - m * (a - Vector3d(0, 0, -kG))).norm(), 1e-8 * m * kG);
  // equal shares of the weight (pushing one hinge up and the other down is a dependency:
  // the least-norm split has none of it)
  EXPECT_NEAR(r1[0].force.z(), 0.5 * m * kG, 1e-8 * m * kG);
  EXPECT_NEAR(r1[1].force.z(), 0.5 * m * kG, 1e-8 * m * kG);
  // moments about the centre of mass balance (a principal axis turning at constant rate
  // needs none): the weight hangs off the axis by w, and the hinges' couple holds it
  Vector3d moment = Vector3d::Zero();
  for (int h = 0; h < 2; ++h) {
    const Vector3d hinge = mech.position(b) + mech.rotation(b) * Vector3d(-w, 0, h ? d : -d);
    moment += r1[h].torque + (hinge - centre).cross(r1[h].force);
    EXPECT_NEAR(r1[h].torque.z(), 0.0, 1e-9 * m * kG * d);  // free about the axis
  }
  EXPECT_LT(moment.norm(), 1e-8 * m * kG * d);
  // another history to the same state: restore after stepping elsewhere (other warm start)
  mech.restore(start);
  mech.assemble({}, {CoordinateTarget{0, 0, -2.0}});
  for (int k = 0; k < 100; ++k) mech.step(2e-3);
  mech.restore(there);
  const std::vector<Reaction> r2 = mech.jointReactions();
  for (int h = 0; h < 2; ++h) {
    EXPECT_LT((r1[h].force - r2[h].force).norm(), 1e-10 * m * kG);
    EXPECT_LT((r1[h].torque - r2[h].torque).norm(), 1e-10 * m * kG * d);
  }
  std::printf("door: hinge forces (%.4f %.4f %.4f) and (%.4f %.4f %.4f) N\n", r1[0].force.x(), r1[0].force.y(),
              r1[0].force.z(), r1[1].force.x(), r1[1].force.y(), r1[1].force.z());
}

// The driving torque of a pendulum turned at constant speed is in the joint's reaction, as
// a moment about the axis: tau = -m g L cos q along +y.
TEST(Reactions, DrivenJointCarriesItsDrivingTorque) {
  const double m = 1.0, L = 0.5;
  Mechanism mech;
  const int b = mech.addBody(body("bob", m, 1e-3 * Matrix3d::Identity(), Vector3d(L, 0, 0)));
  mech.addJoint(makeJoint("revolute", "pivot", Mechanism::kGround, models::axisY(Vector3d::Zero()), b,
                          models::axisY(Vector3d(-L, 0, 0))));
  mech.addDrive(0, 0, DriveProfile::velocity(3.0));
  mech.build();
  mech.assemble();
  for (int k = 0; k < 700; ++k) {
    mech.step(1e-3);
    const double q = mech.jointPosition(0, 0);
    const Reaction r = mech.jointReactions()[0];
    ASSERT_NEAR(r.torque.y(), mech.jointEffort(0, 0), 1e-9);
    ASSERT_NEAR(r.torque.y(), -m * kG * L * std::cos(q), 1e-9);
  }
}

}  // namespace
}  // namespace mechanism_sim

namespace mechanism_sim {
namespace {

// A coupler's reaction (Mechanism::reaction) is taken about the joint point of the joint
// whose body it acts on: two sliders coupled by q_a = 2 q_b push along their axes through
// their joint points, so the torque about those points is zero (about the centre of mass,
// 0.3 m off the axis, it would not be).
TEST(Reactions, CouplerAndDriveReactionsAreAboutTheJointPoint) {
  Mechanism mech;
  for (int i = 0; i < 2; ++i) {
    Body b;
    b.name = i ? "b" : "a";
    b.m = 1.0 + i;
    b.Jp = 0.01 * Matrix3d::Identity();
    b.r = Vector3d(i, 0.3, 0);
    const int id = mech.addBody(b);
    JointFrame on_ground, on_body;
    on_ground.sp_B = Vector3d(i, 0, 0);
    on_body.sp_B = Vector3d(0, -0.3, 0);  // the joint point, 0.3 m from the centre of mass
    mech.addJoint(makeJoint("prismatic", i ? "slide_b" : "slide_a", Mechanism::kGround, on_ground, id, on_body));
  }
  const int coupler = mech.addCoupler("mimic", 0, 0, 1, 0, 2.0, 0.0);
  mech.addDrive(1, 0, DriveProfile::harmonic(0.0, 0.1, 1.0, 0.0));
  mech.setGravity(Vector3d::Zero());
  mech.build();
  mech.assemble();
  for (int k = 0; k < 200; ++k) mech.step(1e-3);
  const Reaction rc = mech.reaction(coupler);
  EXPECT_GT(rc.force.norm(), 1e-3);
  EXPECT_LT(rc.torque.norm(), 1e-12 * (1 + rc.force.norm()));
  const Reaction rd = mech.reaction(mech.system().drives[0].constraint);
  EXPECT_GT(rd.force.norm(), 1e-3);
  EXPECT_LT(rd.torque.norm(), 1e-12 * (1 + rd.force.norm()));
}

}  // namespace
}  // namespace mechanism_sim
