// Constrained forward dynamics on the joint-space tree (closure_dynamics.cpp: the closures'
// solves and constrainedForwardDynamics) against the absolute-coordinate solver: a planar
// four-bar, a spatial RSSR loop, random trees closed by one or two random joints, in metres and
// millimetres. Every mechanism is built at a pose where each joint's two frames coincide (joint
// coordinates zero), so the initial pose is assembled.
#include <gtest/gtest.h>

#include "loop_cases.h"
#include "random_loops.h"
#include "compare.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "core/absolute/evaluation.h"
#include "core/joint_space/loop_closure.h"
#include "mechanism_sim/core/models.h"
#include "core/absolute/stepper.h"

namespace mechanism_sim {
namespace {

using test_util::accelerationDifference;
using test_util::fourBar;
using test_util::rssr;
using test_util::absoluteFromJoint;
using test_util::Builder;
using test_util::isTranslation;
using test_util::randomLoops;
using test_util::randomRotation;
using test_util::uniform;

struct LoopComparison {
  bool ok = false;
  double acc = 0, lambda = 0, Gtlambda = 0, fd = 0, pos = 0, vel = 0;
  int dependent = 0, rows = 0, pos_iterations = 0;
  int idle = 0, kept = 0;  // closure rows left out as idle, and kept
  bool reused = false;  // the projections left their evaluation at (q, q_dot) ...
  double reuse = -1;    // ... and the dynamics from it differ from a fresh evaluation's by this
};

// At the assembled pose (q neutral) with random rates projected onto G q_dot = 0 and random
// loads: joint-space constrained dynamics against Stepper::settle; G against finite
// differences of Phi; the projections from a perturbed state.
LoopComparison compare(Builder& b, unsigned seed, const char* label) {
  System& sys = *b.sys;
  const double L = b.length;
  sys.finalize();
  LoopComparison out;
  EXPECT_EQ(jointSpaceUnsupported(sys, true), "") << label;
  EXPECT_NE(jointSpaceUnsupported(sys).find("closes a loop"), std::string::npos) << label;
  TreeModel model(sys);
  if (model.cut_joints.empty()) return out;
  TreeWorkspace ws(model);
  LoopClosures cl(model, sys);
  std::mt19937 rng(seed);
  Eigen::VectorXd q = model.neutralPositions(sys), qd(model.nv);
  for (const TreeLink& Lk : model.links)
    for (int k = 0; k < Lk.nv; ++k) {
      qd(Lk.iv + k) = uniform(rng, -2, 2) * (isTranslation(Lk, k) ? L : 1.0);
    }
  forwardKinematics(model, q, qd, ws);
  cl.evaluate(model, sys, ws);
  EXPECT_LT(cl.positionResidual(), 1e-14) << label << ": the built pose is not assembled";
  const ClosureProjectionReport vr = projectClosureVelocities(model, sys, cl, q, qd, ws);
  EXPECT_TRUE(vr.converged) << label << " velocity projection: " << vr.residual;

  // ---- dynamics against the absolute solver
  State s = absoluteFromJoint(sys, model, ws, q, qd);
  Inputs in = zeroInputs(sys);
  const double effort = 9.81 * std::fabs(sys.gravity.z()) / 9.81 * L;
  for (int j = 0; j < sys.numJoints(); ++j) {
    if (model.joint_link[j] < 0) continue;  // (efforts on cut joints: not modelled)
    for (int k = 0; k < sys.joints[j]->dof(); ++k) in.effort[j][k] = uniform(rng, -1, 1) * effort;
  }
  for (int bb = 1; bb <= sys.nb; ++bb) {
    in.force[bb] = std::fabs(sys.gravity.z()) * Vector3d(uniform(rng, -1, 1), uniform(rng, -1, 1), uniform(rng, -1, 1));
    in.torque[bb] = effort * Vector3d(uniform(rng, -1, 1), uniform(rng, -1, 1), uniform(rng, -1, 1));
  }
  // prismatic and the like take efforts in force units: scale those by 1/L
  for (int j = 0; j < sys.numJoints(); ++j) {
    const std::string t = sys.joints[j]->type();
    for (int k = 0; k < sys.joints[j]->dof(); ++k)
      if ((t == "prismatic" && k == 0) || (t == "cylindrical" && k == 1) || (t == "planar" && k < 2)) in.effort[j][k] /= L;
  }
  Eigen::VectorXd tau, qdd, acc;
  jointEfforts(model, in, tau);
  const ClosureSolveInfo info = constrainedForwardDynamics(model, sys, cl, q, qd, tau, ws, qdd, &in);
  bodyAccelerations(model, ws, qdd, acc);
  out.dependent = info.dependent;
  out.rows = info.rows;
  out.idle = cl.idleRowCount();
  out.kept = cl.m;

  Stepper stepper(sys);
  stepper.analyzeDependencies(sys, s);
  stepper.settle(sys, s, in);
  out.acc = accelerationDifference(acc, s.acc, sys.nb, L, sys.gravity.norm());
  Eigen::VectorXd lam_abs(cl.m);
  for (int e = 0; e < cl.m; ++e) lam_abs(e) = s.lambda(cl.sys_row[e]);
  // G^T lambda is unique even with dependent rows; lambda itself when G has full rank
  const Eigen::VectorXd f1 = cl.G.transpose() * cl.lambda, f2 = cl.G.transpose() * lam_abs;
  Eigen::VectorXd fs = (cl.Gabs.transpose() * lam_abs.cwiseAbs()).cwiseMax(1e-300);
  out.Gtlambda = ((f1 - f2).cwiseAbs().cwiseQuotient(fs)).maxCoeff();
  // per row of the same units: against the largest of that closure's multipliers in its
  // rows of the same kind (forces and moments kept apart by the closure's sizes)
  out.lambda = (cl.lambda - lam_abs).cwiseAbs().maxCoeff() / std::max(lam_abs.cwiseAbs().maxCoeff(), 1e-300);
  (void)f1;

  // ---- G against central differences of Phi along a random direction
  Eigen::VectorXd dv(model.nv);
  for (int k = 0; k < model.nv; ++k) dv(k) = uniform(rng, -1, 1);
  forwardKinematics(model, q, qd, ws);
  cl.evaluate(model, sys, ws);
  const Eigen::VectorXd Gdv = cl.G * dv;
  const double eps = 1e-5;
  Eigen::VectorXd qp = q, qm = q;
  retract(model, qp, eps * dv);
  retract(model, qm, -eps * dv);
  forwardKinematics(model, qp, qd, ws);
  cl.evaluate(model, sys, ws);
  const Eigen::VectorXd Pp = cl.Phi;
  forwardKinematics(model, qm, qd, ws);
  cl.evaluate(model, sys, ws);
  const Eigen::VectorXd fd = (Pp - cl.Phi) / (2 * eps);
  out.fd = (fd - Gdv).cwiseAbs().maxCoeff() / std::max(Gdv.cwiseAbs().maxCoeff(), 1e-300);

  // ---- projections from a perturbed state
  Eigen::VectorXd qx = q;
  retract(model, qx, 1e-2 * dv);
  const ClosureProjectionReport pr = projectClosurePositions(model, sys, cl, qx, ws, 1e-13);
  out.pos = pr.residual;
  out.pos_iterations = pr.iterations;
  Eigen::VectorXd qdx = qd + 0.1 * dv;
  const ClosureProjectionReport vr2 = projectClosureVelocities(model, sys, cl, qx, qdx, ws);
  out.vel = vr2.residual;
  // ---- the stepper's finish: projections with the kinematics at the rates, which move
  // nothing on a state already on the closures, leave ws and the evaluation at (q, q_dot);
  // the dynamics from them are those of a fresh evaluation there, bit for bit
  // (a rate projected again is judged against its own size, no longer the perturbed one's:
  // once more, so that it is on the closures by that measure too)
  projectClosureVelocities(model, sys, cl, qx, qdx, ws);
  const ClosureProjectionReport py = projectClosurePositions(model, sys, cl, qx, ws, 1e-13, 20, &qdx);
  const ClosureProjectionReport vy = projectClosureVelocities(model, sys, cl, qx, qdx, ws, 1e-13, 3, true, py.at_rates);
  out.reused = py.at_rates && py.iterations == 0 && vy.at_rates;
  if (out.reused) {
    Eigen::VectorXd qdd_reused, qdd_fresh;
    constrainedForwardDynamics(model, sys, cl, qx, qdx, tau, ws, qdd_reused, &in, true);
    const Eigen::VectorXd lambda_reused = cl.lambda;
    forwardKinematics(model, q, qd, ws);  // (another state in between)
    constrainedForwardDynamics(model, sys, cl, q, qd, tau, ws, qdd_fresh, &in);
    constrainedForwardDynamics(model, sys, cl, qx, qdx, tau, ws, qdd_fresh, &in);
    out.reuse = std::max((qdd_reused - qdd_fresh).cwiseAbs().maxCoeff(), (lambda_reused - cl.lambda).cwiseAbs().maxCoeff());
  }
  out.ok = true;
  return out;
}

void report(const char* label, const LoopComparison& c) {
  std::printf("[%s] rows %d (dependent %d): acc %.2e, lambda %.2e, G^T lambda %.2e, FD(G) %.2e, "
              "position projection %.2e (%d its), velocity projection %.2e\n",
              label, c.rows, c.dependent, c.acc, c.lambda, c.Gtlambda, c.fd, c.pos, c.pos_iterations, c.vel);
}

void checkLoop(const LoopComparison& c, const char* label, bool unique_lambda) {
  ASSERT_TRUE(c.ok) << label;
  EXPECT_LT(c.acc, 1e-10) << label;
  EXPECT_LT(c.Gtlambda, 1e-10) << label;
  if (unique_lambda) {
    EXPECT_LT(c.lambda, 1e-10) << label;
  }
  EXPECT_LT(c.fd, 1e-7) << label;
  EXPECT_LT(c.pos, 1e-12) << label;
  EXPECT_LT(c.vel, 1e-12) << label;
  EXPECT_TRUE(c.reused) << label << ": the projections of a state on the closures moved it";
  if (c.reused) {
    EXPECT_EQ(c.reuse, 0.0) << label << ": dynamics from the projections' evaluation";
  }
}

TEST(JointSpaceLoops, FourBarAgreesWithTheAbsoluteSolver) {
  for (double L : {1.0, 1e3}) {
    Builder b = fourBar(L, L);
    const char* label = L == 1.0 ? "four-bar, m" : "four-bar, mm";
    const LoopComparison c = compare(b, 11, label);
    report(label, c);
    EXPECT_EQ(c.dependent, 3) << label;  // the cut revolute's out-of-plane rows ...
    EXPECT_EQ(c.idle, 3) << label;       // ... left out of the closure's rows: no motion moves them
    EXPECT_EQ(c.kept, 2) << label;
    checkLoop(c, label, true);
  }
}

TEST(JointSpaceLoops, RssrAgreesWithTheAbsoluteSolver) {
  for (double L : {1.0, 1e3}) {
    Builder b = rssr(L, L);
    const char* label = L == 1.0 ? "RSSR, m" : "RSSR, mm";
    const LoopComparison c = compare(b, 12, label);
    report(label, c);
    EXPECT_EQ(c.dependent, 0) << label;
    EXPECT_EQ(c.idle, 0) << label;  // (a spatial loop: every row moves)
    checkLoop(c, label, true);
  }
}

TEST(JointSpaceLoops, RandomTreesWithRandomClosuresAgreeWithTheAbsoluteSolver) {
  int checked = 0, with_dependent = 0, with_idle = 0;
  double worst_acc = 0, worst_lambda = 0, worst_gt = 0, worst_fd = 0, worst_pos = 0, worst_vel = 0;
  for (double L : {1.0, 1e3})
    for (unsigned seed = 1; seed <= 24; ++seed) {
      const int n = 3 + static_cast<int>(seed % 6), loops = 1 + static_cast<int>(seed % 2);
      Builder b = randomLoops(seed, n, loops, L, L);
      const std::string label = std::string(L == 1.0 ? "m" : "mm") + " tree " + std::to_string(seed);
      b.sys->finalize();
      TreeModel probe(*b.sys);
      if (probe.cut_joints.size() != static_cast<size_t>(loops)) continue;
      const LoopComparison c = compare(b, 100 + seed, label.c_str());
      checkLoop(c, label.c_str(), c.dependent == 0);
      ++checked;
      with_dependent += c.dependent > 0;
      with_idle += c.idle > 0;
      worst_acc = std::max(worst_acc, c.acc);
      if (c.dependent == 0) worst_lambda = std::max(worst_lambda, c.lambda);
      worst_gt = std::max(worst_gt, c.Gtlambda);
      worst_fd = std::max(worst_fd, c.fd);
      worst_pos = std::max(worst_pos, c.pos);
      worst_vel = std::max(worst_vel, c.vel);
    }
  std::printf("[random loops] %d trees (%d with dependent closure rows, %d with idle ones): acc %.2e, lambda (full rank) %.2e, "
              "G^T lambda %.2e, FD(G) %.2e, position projection %.2e, velocity projection %.2e\n",
              checked, with_dependent, with_idle, worst_acc, worst_lambda, worst_gt, worst_fd, worst_pos, worst_vel);
  EXPECT_GE(checked, 20);
}

// RK4 over (q, q_dot) with the constrained dynamics, projections after each step.
void rk4Step(const TreeModel& model, const System& sys, LoopClosures& cl, TreeWorkspace& ws, Eigen::VectorXd& q,
             Eigen::VectorXd& qd, const Eigen::VectorXd& tau, double h) {
  Eigen::VectorXd k1q, k1v, k2q, k2v, k3q, k3v, k4q, k4v, qs, vs;
  auto rates = [&](const Eigen::VectorXd& qq, const Eigen::VectorXd& vv, Eigen::VectorXd& rq, Eigen::VectorXd& rv) {
    constrainedForwardDynamics(model, sys, cl, qq, vv, tau, ws, rv);
    positionRates(model, qq, vv, rq);
  };
  rates(q, qd, k1q, k1v);
  qs = q + 0.5 * h * k1q, vs = qd + 0.5 * h * k1v;
  normalizeQuaternions(model, qs);
  rates(qs, vs, k2q, k2v);
  qs = q + 0.5 * h * k2q, vs = qd + 0.5 * h * k2v;
  normalizeQuaternions(model, qs);
  rates(qs, vs, k3q, k3v);
  qs = q + h * k3q, vs = qd + h * k3v;
  normalizeQuaternions(model, qs);
  rates(qs, vs, k4q, k4v);
  q += h / 6 * (k1q + 2 * k2q + 2 * k3q + k4q);
  qd += h / 6 * (k1v + 2 * k2v + 2 * k3v + k4v);
  normalizeQuaternions(model, q);
  projectClosurePositions(model, sys, cl, q, ws);
  projectClosureVelocities(model, sys, cl, q, qd, ws);
}

TEST(JointSpaceLoops, FourBarIntegratedOneSecondTracksTheAbsoluteFormulation) {
  Builder b = fourBar(1.0, 1.0);
  System& sys = *b.sys;
  sys.finalize();
  TreeModel model(sys);
  TreeWorkspace ws(model);
  LoopClosures cl(model, sys);
  Eigen::VectorXd q = model.neutralPositions(sys), qd = Eigen::VectorXd::Zero(model.nv), tau = Eigen::VectorXd::Zero(model.nv);
  qd(0) = 1.5;
  projectClosureVelocities(model, sys, cl, q, qd, ws);
  State s = absoluteFromJoint(sys, model, ws, q, qd);
  Stepper stepper(sys);
  stepper.analyzeDependencies(sys, s);
  const Inputs in = zeroInputs(sys);
  const double h = 1e-3;
  const int crank = model.joint_link[0];
  ASSERT_EQ(model.links[crank].body, 1);
  double worst = 0;
  for (int n = 0; n < 1000; ++n) {
    rk4Step(model, sys, cl, ws, q, qd, tau, h);
    stepper.step(sys, s, in, h);
    Evaluation ev(sys);
    loadKinematics(sys, s.x.data(), s.u.data(), ev);
    Row rows[kMaxJointDofs];
    jointRows(sys, ev, s, 0, rows);
    worst = std::max(worst, std::fabs(rows[0].Phi - q(model.links[crank].iq)));
  }
  std::printf("[four-bar 1 s] crank angle %.12f rad (joint space), largest difference to the absolute run %.2e rad\n",
              q(model.links[crank].iq), worst);
  EXPECT_LT(worst, 1e-8);
}

// A branch passage's held direction is taken across the motion (branch_passage.cpp, "across
// the motion"): its reaction does no work on it. A four-bar 1e-5 rad from flat with its
// coordinate across the branch carried 1e-9 off (the integration's, as in a passage): the
// level set's normal there leans 1e-4 into the motion, and a reaction along it did work:
// 4e-9 of the constraint forces' |q_dot|^T |f| (the four-bars' random energy errors at
// 0.1 ms, one per passage, largest where a stage landed nearest the crossing; 3e-16 with
// the direction across the motion). The rates are projected
// as the stepper's are (the regular directions' equations), so the constraint forces'
// power q_dot^T M (q_ddot_free - q_ddot) is round-off.
TEST(JointSpaceLoops, AHeldDirectionsReactionDoesNoWorkOnTheMotion) {
  Mechanism mech;
  models::fourBarChain(mech, 1, 0.4, 1.0, 0.3);  // flat at q = 0.3 on the parallelogram
  mech.build();
  const System& sys = mech.system();
  TreeModel model(sys);
  TreeWorkspace ws(model);
  LoopClosures cl(model, sys);
  ASSERT_EQ(model.nv, 3);
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(model.nv);
  // the branches' tangents at the flat pose: G's null space there (the parallelogram's is
  // G's null vector at the built pose, linear in the joint coordinates)
  auto nullSpace = [&](const Eigen::VectorXd& q) {
    forwardKinematics(model, q, zero, ws);
    cl.evaluate(model, sys, ws, q);
    Eigen::JacobiSVD<Eigen::MatrixXd> svd(cl.G, Eigen::ComputeFullV);
    return Eigen::MatrixXd(svd.matrixV());
  };
  const Eigen::VectorXd q0 = model.neutralPositions(sys);
  Eigen::VectorXd t = nullSpace(q0).col(2);
  t /= t(model.links[model.joint_link[0]].iv);  // (crank 0's rate 1)
  const Eigen::VectorXd flat = q0 + 0.3 * t;
  const Eigen::MatrixXd V = nullSpace(flat);
  Eigen::VectorXd across = V.col(1) - V.col(1).dot(t) / t.squaredNorm() * t;
  if (std::fabs(V.col(2).dot(t)) < std::fabs(V.col(1).dot(t)))
    across = V.col(2) - V.col(2).dot(t) / t.squaredNorm() * t;
  across.normalize();
  const Eigen::VectorXd q = flat + 1e-5 * t + 1e-9 * across;
  Eigen::VectorXd qdot = 2.0 * t;
  Eigen::VectorXd a_ref = Eigen::VectorXd::Zero(model.nv);
  ClosureSolveMode mode;
  mode.passage_ref = &a_ref;
  projectClosureVelocities(model, sys, cl, q, qdot, ws, 1e-14, 3, false, false, mode);
  Eigen::VectorXd qdd, qdd_free;
  constrainedForwardDynamics(model, sys, cl, q, qdot, zero, ws, qdd, nullptr, false, mode);
  EXPECT_GT(cl.passageDirections(), 0) << "a passage";
  forwardDynamics(model, sys, q, qdot, zero, ws, qdd_free);
  AlignedVector<Matrix6d> Ic(model.nb);
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(model.nv, model.nv);
  jointSpaceInertia(model, ws, Ic, H);
  const Eigen::VectorXd f = H * (qdd_free - qdd);  // the constraint forces, R^T mu
  const double power = qdot.dot(f), scale = qdot.cwiseAbs().dot(f.cwiseAbs());
  std::printf("[four-bar 1e-5 rad from flat, 1e-9 across] constraint forces' power %.2e of %.2e\n", power, scale);
  EXPECT_LT(std::fabs(power), 1e-12 * scale);
}

}  // namespace
}  // namespace mechanism_sim
