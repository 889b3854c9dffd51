// Reactions of the tree joints in the joint formulation (tree_reactions.h: the recursive
// Newton-Euler pass, then each joint's multipliers from the wrench it transmits): on trees
// the multipliers are unique, so they must be the absolute formulation's at the same
// state; a pendulum's pin carries its weight at rest and m g cos(theta) + m L omega^2 along
// the rod when it swings; with a mimic coupler and a limit at its stop every body balances.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <functional>
#include <memory>
#include <random>

#include "bodies.h"
#include "core/joint_space/loop_closure.h"
#include "mechanism_sim/core/models.h"
#include "core/absolute/stepper.h"
#include "core/joint_space/tree_reactions.h"
#include "pendulum.h"

namespace mechanism_sim {
namespace {

using test_util::frame;

IntegratorOptions formulation(const char* f) {
  IntegratorOptions io;
  io.formulation = f;
  return io;
}

// Joint frame with bz along x (bx = -z, by = y) or along y (bx = x, by = -z).
Matrix3d bzAlongX() {
  Matrix3d R;
  R.col(0) = -Vector3d::UnitZ(), R.col(1) = Vector3d::UnitY(), R.col(2) = Vector3d::UnitX();
  return R;
}
Matrix3d bzAlongY() {
  Matrix3d R;
  R.col(0) = Vector3d::UnitX(), R.col(1) = -Vector3d::UnitZ(), R.col(2) = Vector3d::UnitY();
  return R;
}

// What the reactions queries report: every joint's reaction (Mechanism::jointReactions)
// and its constraint's alone (Mechanism::reaction: -Phi_q^T lambda on body j).
struct Reported {
  std::vector<Reaction> joints, rows;
};
Reported reported(const Mechanism& m) {
  Reported r;
  r.joints = m.jointReactions();
  for (int j = 0; j < m.numJoints(); ++j) r.rows.push_back(m.reaction(m.jointConstraintIndex(j)));
  return r;
}

// Largest difference of forces and of torques, each against the largest of its kind in b.
double relativeDifference(const std::vector<Reaction>& a, const std::vector<Reaction>& b) {
  double df = 0, dt = 0, sf = 0, st = 0;
  for (size_t k = 0; k < a.size(); ++k) {
    df = std::max(df, (a[k].force - b[k].force).norm());
    dt = std::max(dt, (a[k].torque - b[k].torque).norm());
    sf = std::max(sf, b[k].force.norm());
    st = std::max(st, b[k].torque.norm());
  }
  return std::max(sf > 0 ? df / sf : df, st > 0 ? dt / st : dt);
}

// A mechanism to build: its description, and its inputs (set after build()).
struct Model {
  std::function<void(Mechanism&)> describe, inputs;
};

// The model in joint coordinates, stepped `steps` ms; then its reactions against the
// absolute formulation's at that state (the same Mechanism switched to absolute
// coordinates: its stepper solves the KKT system there). Returns the relative difference.
double againstAbsolute(const char* what, const Model& model, const std::vector<CoordinateTarget>& velocities,
                       int steps) {
  Mechanism m;
  model.describe(m);
  m.setIntegrator(formulation("joint"));
  m.build();
  m.assemble({}, velocities);
  model.inputs(m);
  for (int k = 0; k < steps; ++k) m.step(1e-3);
  EXPECT_STREQ(m.formulation(), "joint");
  const Reported joint = reported(m);
  Eigen::VectorXd x = m.state().x;
  m.setIntegrator(formulation("absolute"));  // (settles there: accelerations, multipliers)
  EXPECT_STREQ(m.formulation(), "absolute");
  const Reported absolute = reported(m);
  const double moved = (m.state().x - x).cwiseAbs().maxCoeff();
  const double d_joints = relativeDifference(joint.joints, absolute.joints);
  const double d_rows = relativeDifference(joint.rows, absolute.rows);
  std::printf("[%s] joint against absolute: reactions %.2e, constraint rows alone %.2e (relative; the absolute "
              "settle moved x by %.1e)\n", what, d_joints, d_rows, moved);
  return std::max(d_joints, d_rows);
}

// Double pendulum: a revolute about y, then a slider along the first link with its centre
// of mass off the axis; an effort on the slider, damping on the pin.
const Model revolutePrismatic{[](Mechanism& m) {
  const int b1 = m.addBody(body("link", 1.5, Vector3d(0.02, 0.03, 0.04).asDiagonal(), Vector3d(0.6, 0, 0)));
  const int b2 = m.addBody(body("slider", 0.8, Vector3d(0.01, 0.02, 0.015).asDiagonal(), Vector3d(1.0, 0, 0.05)));
  m.addJoint(makeJoint("revolute", "pin", Mechanism::kGround, models::axisY(Vector3d::Zero()), b1,
                       models::axisY(Vector3d(-0.6, 0, 0))));
  m.addJoint(makeJoint("prismatic", "slide", b1, frame(Vector3d(0.2, 0, 0), bzAlongX()), b2,
                       frame(Vector3d(-0.1, 0, -0.05), bzAlongX())));
  m.setJointDamping(0, 0, 0.05);
}, [](Mechanism& m) { m.setJointEffort(1, 0, 0.4); }};

// A spatial chain: a revolute about z, a cylindrical joint along the first link, a screw
// written child first (the tree runs from its body j to its body i), a welded tip.
const Model cylindricalScrew{[](Mechanism& m) {
  const int b1 = m.addBody(body("arm", 1.2, Vector3d(0.01, 0.03, 0.03).asDiagonal(), Vector3d(0.3, 0, 0)));
  const int b2 = m.addBody(body("sleeve", 0.9, Vector3d(0.02, 0.01, 0.02).asDiagonal(), Vector3d(0.9, 0.1, 0)));
  const int b3 = m.addBody(body("nut", 0.5, Vector3d(0.004, 0.006, 0.005).asDiagonal(), Vector3d(0.9, 0.5, -0.1)));
  const int b4 = m.addBody(body("tip", 0.3, Vector3d(0.002, 0.002, 0.003).asDiagonal(), Vector3d(1.1, 0.5, -0.1)));
  JointParams screw;
  screw.alpha = 0.02;
  m.addJoint(makeJoint("revolute", "yaw", Mechanism::kGround, frame(Vector3d::Zero()), b1,
                       frame(Vector3d(-0.3, 0, 0))));
  m.addJoint(makeJoint("cylindrical", "sleeve", b1, frame(Vector3d(0.3, 0, 0), bzAlongX()), b2,
                       frame(Vector3d(-0.3, -0.1, 0), bzAlongX())));
  m.addJoint(makeJoint("screw", "nut", b3, frame(Vector3d(0, -0.2, 0.1), bzAlongY()), b2,
                       frame(Vector3d(0, 0.2, 0), bzAlongY()), screw));
  m.addJoint(makeJoint("fixed", "weld", b3, frame(Vector3d(0.1, 0, 0)), b4, frame(Vector3d(-0.1, 0, 0))));
  m.setJointDamping(1, 0, 0.02);
}, [](Mechanism& m) {
  m.setJointEffort(0, 0, 0.2);
  m.setJointEffort(1, 1, -0.5);
}};

// A free-floating base (no joint to ground) with a spherical joint to a link and a
// revolute to a second; a body wrench on the base and a spring from the base to the tip.
const Model floatingSpherical{[](Mechanism& m) {
  Body base = body("base", 5.0, Vector3d(0.1, 0.2, 0.15).asDiagonal(), Vector3d(0, 0, 1));
  base.v = Vector3d(0.2, 0, 0.5);
  base.w = Vector3d(0.3, -0.2, 0.5);
  const int b1 = m.addBody(base);
  const int b2 = m.addBody(body("upper", 1.0, Vector3d(0.01, 0.02, 0.02).asDiagonal(), Vector3d(0.5, 0, 1)));
  const int b3 = m.addBody(body("lower", 0.7, Vector3d(0.01, 0.01, 0.005).asDiagonal(), Vector3d(0.8, 0, 0.7)));
  m.addJoint(makeJoint("spherical", "shoulder", b1, frame(Vector3d(0.2, 0, 0)), b2, frame(Vector3d(-0.3, 0, 0))));
  m.addJoint(makeJoint("revolute", "elbow", b2, models::axisY(Vector3d(0.3, 0, 0)), b3,
                       models::axisY(Vector3d(0, 0, 0.3))));
  SpringDamper s;
  s.name = "tendon";
  s.body_i = b1, s.body_j = b3, s.k = 50.0, s.c = 0.5, s.L0 = 0.5;
  m.addSpring(s);
}, [](Mechanism& m) {
  m.setBodyWrench(1, Vector3d(1, 2, 3), Vector3d(0.1, 0, 0.2));  // (the base)
  m.setJointEffort(0, 2, 0.1);
}};

TEST(TreeReactions, EqualTheAbsoluteFormulationsOnTrees) {
  EXPECT_LT(againstAbsolute("revolute + prismatic", revolutePrismatic, {{0, 0, 1.2}, {1, 0, -0.3}}, 300), 1e-9);
  EXPECT_LT(againstAbsolute("revolute + cylindrical + screw (reversed) + fixed", cylindricalScrew,
                            {{0, 0, 0.8}, {1, 0, 1.5}, {1, 1, 0.2}, {2, 0, 3.0}}, 300),
            1e-9);
  EXPECT_LT(againstAbsolute("floating base + spherical + revolute", floatingSpherical, {{1, 0, 2.0}}, 300), 1e-9);
}

// Hanging at rest, the pin carries the weight and no moment.
TEST(TreeReactions, PendulumAtRestCarriesItsWeight) {
  const double m = 1.5, L = 0.8;
  Mechanism mech;
  const int b = mech.addBody(body("bob", m, 0.02 * Matrix3d::Identity(), Vector3d(0, 0, -L)));
  mech.addJoint(makeJoint("revolute", "pin", Mechanism::kGround, models::axisY(Vector3d::Zero()), b,
                          models::axisY(Vector3d(0, 0, L))));
  mech.setIntegrator(formulation("joint"));
  mech.build();
  mech.assemble();
  for (int k = 0; k < 10; ++k) mech.step(1e-3);
  const Reaction r = mech.jointReactions()[0];
  EXPECT_LT((r.force - Vector3d(0, 0, m * kG)).norm(), 1e-12 * m * kG);
  EXPECT_LT(r.torque.norm(), 1e-12 * m * kG * L);
}

// Swinging, the rod pulls the bob towards the pin with m g cos(theta) + m L omega^2
// (theta from the downward vertical): the radial part of m (a - g), whatever the inertia;
// the pin carries no moment about its axis.
TEST(TreeReactions, SwingingPendulumTension) {
  Pendulum p;
  p.m = 1.5, p.L = 0.8, p.Ic = 0.02;
  Mechanism mech;
  const int b = p.add(mech);
  mech.setIntegrator(formulation("joint"));
  mech.build();
  mech.assemble();
  double worst = 0, peak = 0;
  for (int k = 0; k < 1500; ++k) {
    mech.step(1e-3);
    const Vector3d d = mech.position(b) - p.pivot;  // pin -> bob
    const double cos_theta = -d.z() / d.norm(), omega = mech.jointVelocity(0, 0);
    const double tension = p.m * kG * cos_theta + p.m * p.L * omega * omega;
    const Reaction r = mech.jointReactions()[0];
    worst = std::max({worst, std::fabs(r.force.dot(-d / d.norm()) - tension), std::fabs(r.torque.y()) / p.L});
    peak = std::max(peak, std::fabs(tension));
  }
  std::printf("[swinging pendulum] tension against m g cos(theta) + m L omega^2: %.2e N (peak %.2f N)\n", worst, peak);
  EXPECT_LT(worst, 1e-10 * peak);
  EXPECT_GT(peak, 2.0 * p.m * kG);  // (the centripetal part was there)
}

// Newton-Euler of every body from the reported reactions (each joint's on its body j, the
// opposite on its body i, both about the joint point B_j): m (a - g) is the sum of the
// forces, A (J' w_dot' + w' x J' w') the sum of the moments about the centre of mass.
// Largest residual, forces and moments over the length scale `L`, against the largest
// weight.
double newtonEulerResidual(const Mechanism& m, double L) {
  const std::vector<Reaction> r = m.jointReactions();
  const State& s = m.state();
  double worst = 0, scale = 0;
  for (int b = 1; b < m.numBodies(); ++b) {
    const Body& B = m.body(b);
    const Vector3d a = s.acc.segment<3>(6 * (b - 1)), w_dot = s.acc.segment<3>(6 * (b - 1) + 3);
    const Vector3d w = s.u.segment<3>(6 * (b - 1) + 3);
    Vector3d F = B.m * (a - m.gravity());
    Vector3d N = m.rotation(b) * (B.Jp * w_dot + w.cross(B.Jp * w));
    for (int j = 0; j < m.numJoints(); ++j) {
      const Joint& J = m.joint(j);
      const Vector3d P = m.position(J.bodyJ()) + m.rotation(J.bodyJ()) * J.frameJ().sp_B;  // where the torque is about
      const double sign = J.bodyJ() == b ? 1.0 : J.bodyI() == b ? -1.0 : 0.0;
      F -= sign * r[j].force;
      N -= sign * (r[j].torque + (P - m.position(b)).cross(r[j].force));
    }
    worst = std::max({worst, F.norm(), N.norm() / L});
    scale = std::max(scale, B.m * m.gravity().norm());
  }
  return worst / scale;
}

// A planar chain of three revolutes about y: the first falls onto its upper stop (0.3 rad)
// and rests there, the third follows the second through a mimic coupler (q3 = -0.5 q2);
// an effort on the second, damping on the third. Every body balances, and the reactions
// are the absolute formulation's.
TEST(TreeReactions, BodiesBalanceWithACouplerAndALimit) {
  const Model chain{[](Mechanism& m) {
    const int b1 = m.addBody(body("l1", 1.0, 0.01 * Matrix3d::Identity(), Vector3d(0.4, 0, 0)));
    const int b2 = m.addBody(body("l2", 0.8, 0.008 * Matrix3d::Identity(), Vector3d(1.1, 0, 0)));
    const int b3 = m.addBody(body("l3", 0.5, 0.004 * Matrix3d::Identity(), Vector3d(1.6, 0, 0)));
    m.addJoint(makeJoint("revolute", "j1", Mechanism::kGround, models::axisY(Vector3d::Zero()), b1,
                         models::axisY(Vector3d(-0.4, 0, 0))));
    m.addJoint(makeJoint("revolute", "j2", b1, models::axisY(Vector3d(0.4, 0, 0)), b2,
                         models::axisY(Vector3d(-0.3, 0, 0))));
    m.addJoint(makeJoint("revolute", "j3", b2, models::axisY(Vector3d(0.3, 0, 0)), b3,
                         models::axisY(Vector3d(-0.2, 0, 0))));
    m.setJointLimits(0, 0, -1.0, 0.3);
    m.addCoupler("mimic", 2, 0, 1, 0, -0.5, 0.0);
    m.setJointDamping(2, 0, 0.05);
  }, [](Mechanism& m) { m.setJointEffort(1, 0, 0.3); }};
  Mechanism m;
  chain.describe(m);
  m.setIntegrator(formulation("joint"));
  m.build();
  m.assemble({}, {{1, 0, 1.0}});
  chain.inputs(m);
  ASSERT_STREQ(m.formulation(), "joint");
  double worst = 0, worst_free = 0;
  int at_stop = 0;
  for (int k = 0; k < 1200; ++k) {
    m.step(1e-3);
    const double res = newtonEulerResidual(m, 0.4);
    if (m.state().limit_side[0] != 0) {
      ++at_stop;
      worst = std::max(worst, res);
    } else {
      worst_free = std::max(worst_free, res);
    }
  }
  std::printf("[chain, coupler, limit] Newton-Euler residual per body: %.2e at the stop (%d states), %.2e before\n",
              worst, at_stop, worst_free);
  EXPECT_GT(at_stop, 500);
  EXPECT_LT(worst, 1e-12);
  EXPECT_LT(worst_free, 1e-12);
  EXPECT_LT(againstAbsolute("chain, coupler, limit", chain, {{1, 0, 1.0}}, 1200), 1e-9);
}

// A loop closure (not yet integrated in joint coordinates: doc/limitations.md) is a load
// on its two bodies. An RSSR loop (crank about z, coupler by spheres, rocker about x, the
// second sphere cut) at one state, through the core calls the joint stepper makes: the
// closures' multipliers from constrainedForwardDynamics, the tree joints' from
// treeJointMultipliers, against the absolute Stepper's at the same state (the loop's
// equations are independent: unique multipliers). No effort is left over beyond the
// applied ones.
TEST(TreeReactions, CutJointIsALoadOnItsBodies) {
  System sys;
  sys.bodies.push_back(Body());
  std::mt19937 rng(3);
  auto rotation = [&]() {
    std::normal_distribution<double> n(0.0, 1.0);
    return Quaterniond(n(rng), n(rng), n(rng), n(rng)).normalized();
  };
  auto addBody = [&](double m, const Vector3d& moments, const Vector3d& r) {
    Body b = body("b" + std::to_string(sys.bodies.size()), m, (m * moments).asDiagonal(), r);
    b.p = rotation();
    sys.bodies.push_back(b);
    return static_cast<int>(sys.bodies.size()) - 1;
  };
  auto frameOn = [&](int b, const Vector3d& P, const Matrix3d& axes) {
    const Matrix3d A = b == 0 ? Matrix3d::Identity() : sys.bodies[b].p.toRotationMatrix();
    const Vector3d r = b == 0 ? Vector3d::Zero() : sys.bodies[b].r;
    return frame(A.transpose() * (P - r), A.transpose() * axes);
  };
  auto addJoint = [&](const std::string& type, int bi, int bj, const Vector3d& P, const Matrix3d& axes) {
    auto j = makeJoint(type, type + std::to_string(sys.joints.size()), bi, frameOn(bi, P, axes), bj, frameOn(bj, P, axes));
    sys.joints.push_back(j.get());
    sys.joint_constraint.push_back(sys.numConstraints());
    sys.constraints.push_back(std::shared_ptr<Constraint>(std::move(j)));
  };
  const Vector3d O(0, 0, 0), B(0.3, 0.1, 0), C(0.9, 0.4, 0.5), D(1.0, 0.2, 0.1);
  const int crank = addBody(0.8, Vector3d(0.05, 0.06, 0.07), 0.5 * (O + B));
  const int coupler = addBody(1.2, Vector3d(0.08, 0.06, 0.09), 0.5 * (B + C));
  const int rocker = addBody(1.0, Vector3d(0.05, 0.07, 0.06), 0.5 * (C + D));
  addJoint("revolute", 0, crank, O, Matrix3d::Identity());
  addJoint("spherical", crank, coupler, B, Matrix3d::Identity());
  addJoint("revolute", 0, rocker, D, bzAlongX());
  addJoint("spherical", coupler, rocker, C, Matrix3d::Identity());
  sys.finalize();
  const TreeModel model(sys);
  ASSERT_EQ(model.cut_joints.size(), 1u);
  TreeWorkspace ws(model);
  LoopClosures cl(model, sys);
  // the built pose (assembled), rates onto the loop, an effort on the crank, a body wrench
  Eigen::VectorXd q = model.neutralPositions(sys), qd = Eigen::VectorXd::Zero(model.nv);
  qd(model.links[crank - 1].iv) = 2.0;
  qd(model.links[coupler - 1].iv + 2) = 0.7;
  forwardKinematics(model, q, qd, ws);
  cl.evaluate(model, sys, ws);
  ASSERT_TRUE(projectClosureVelocities(model, sys, cl, q, qd, ws).converged);
  Inputs in = zeroInputs(sys);
  in.effort[0][0] = 1.5;
  in.force[coupler] = Vector3d(2, -1, 3);
  Eigen::VectorXd tau, qdd;
  jointEfforts(model, in, tau);
  constrainedForwardDynamics(model, sys, cl, q, qd, tau, ws, qdd, &in);
  State s = initialState(sys);
  absoluteState(model, ws, s.x, s.u);
  bodyAccelerations(model, ws, qdd, s.acc);
  for (const TreeLink& L : model.links)  // the tree joints' tracked angles: their coordinates
    for (int k = 0; k < L.nv; ++k)
      if (L.ptr && L.ptr->trackedSlot(k) >= 0 && L.kind != TreeJointKind::kSpherical)
        s.tracked[L.ptr->id()][L.ptr->trackedSlot(k)] = q(L.iq + k);
  Eigen::VectorXd lambda = Eigen::VectorXd::Zero(sys.m);
  cl.systemMultipliers(lambda);
  TreeReactionWorkspace w(sys);
  treeJointMultipliers(sys, model, s, in, w, lambda);

  State a = s;
  Stepper stepper(sys);
  stepper.analyzeDependencies(sys, a);
  stepper.settle(sys, a, in);
  const double moved = (a.x - s.x).cwiseAbs().maxCoeff();
  const double diff = (lambda - a.lambda).cwiseAbs().maxCoeff() / a.lambda.cwiseAbs().maxCoeff();
  std::printf("[RSSR, cut sphere] multipliers against the absolute solve: %.2e (relative; x moved %.1e); effort left "
              "over %.2e\n", diff, moved, w.worst_effort);
  EXPECT_LT(diff, 1e-9);
  EXPECT_LT(w.worst_effort, 1e-12);
}

}  // namespace
}  // namespace mechanism_sim
