// The closures' rows (loop_closure.cpp: layout, evaluation, limits): couplers, drives, limits
// and cut-joint efforts as closures on the joint-space tree against the absolute-coordinate
// solver (Stepper::settle after analyzeDependencies) at one assembled state: accelerations of
// every body and the multiplier of every closure row (mapped to its System row), in metres and
// millimetres; G against finite differences of Phi (and nu against -dPhi/dt); the projections.
#include <gtest/gtest.h>

#include "bodies.h"
#include "random_loops.h"
#include "compare.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "mechanism_sim/core/model/couplers.h"
#include "mechanism_sim/core/model/drive.h"
#include "core/joint_space/loop_closure.h"
#include "core/absolute/stepper.h"

namespace mechanism_sim {
namespace {

using test_util::accelerationDifference;
using test_util::Builder;
using test_util::uniform;

Matrix3d axesWithZ(const Vector3d& z) {  // a right-handed frame with bz = z
  const Vector3d zn = z.normalized();
  const Vector3d x = (std::fabs(zn.x()) < 0.9 ? Vector3d::UnitX() : Vector3d::UnitY()).cross(zn).normalized();
  Matrix3d R;
  R << x, zn.cross(x), zn;
  return R;
}


// A spatial chain: revolute (y), revolute (z), prismatic (x), revolute (x), revolute (y),
// each link a rod to the next joint; the 1st joint written parent-last (reversed link).
Builder chain(double L) {
  Builder b(L, L);
  static const char* const kType[] = {"revolute", "revolute", "prismatic", "revolute", "revolute"};
  const Vector3d ax[] = {Vector3d::UnitY(), Vector3d::UnitZ(), Vector3d::UnitX(), Vector3d::UnitX(), Vector3d(0, 1, 1)};
  Vector3d p(0, 0, 0);
  int prev = 0;
  std::mt19937 rng(3);
  for (int k = 0; k < 5; ++k) {
    const Vector3d next = p + 0.4 * L * Vector3d(1.0, 0.3 * std::sin(1.3 * k), 0.2 * std::cos(k));
    const int bb = b.addBody(0.5 + 0.2 * k, Vector3d(0.02, 0.02 + 0.005 * k, 0.03), 0.5 * (p + next),
                             Quaterniond(Eigen::AngleAxisd(0.3 * k, Vector3d(1, 2, 3).normalized())).toRotationMatrix());
    if (k == 1) b.addJoint(kType[k], bb, prev, p, axesWithZ(ax[k]));
    else b.addJoint(kType[k], prev, bb, p, axesWithZ(ax[k]));
    prev = bb, p = next;
  }
  return b;
}

// The planar four-bar in x-z (axes along y), as joint_space/test_loop_closure.cpp; the closing
// joint (coupler-rocker at C) is the last one.
Builder fourBar(double L) {
  Builder b(L, L);
  const double pi = 3.141592653589793;
  const Vector3d O(0, 0, 0), D(1.0 * L, 0, 0);
  const Vector3d B = O + 0.35 * L * Vector3d(std::cos(1.1), 0, std::sin(1.1));
  const Vector3d C = D + 0.8 * L * Vector3d(std::cos(pi * 0.6), 0, std::sin(pi * 0.6));
  auto rod = [&](const Vector3d& a, const Vector3d& c, double m) {
    const Vector3d x = (c - a).normalized();
    Matrix3d R;
    R << x, Vector3d::UnitY(), x.cross(Vector3d::UnitY());
    const double l = (c - a).norm() / L;
    return b.addBody(m, Vector3d(0.002, l * l / 12, l * l / 12 + 0.002), 0.5 * (a + c), R);
  };
  const int crank = rod(O, B, 0.7), coupler = rod(B, C, 1.3), rocker = rod(D, C, 1.0);
  const Matrix3d Y = axesWithZ(Vector3d::UnitY());
  b.addJoint("revolute", 0, crank, O, Y);
  b.addJoint("revolute", crank, coupler, B, Y);
  b.addJoint("revolute", 0, rocker, D, Y);
  b.addJoint("revolute", coupler, rocker, C, Y);
  return b;
}

// The absolute State of a joint state with the context of `ctx_from` (random_loops.h).
State absoluteFromJoint(const System& sys, const TreeModel& model, TreeWorkspace& ws, const Eigen::VectorXd& q,
                        const Eigen::VectorXd& qd, const State& ctx_from) {
  return test_util::absoluteFromJoint(sys, model, ws, q, qd, &ctx_from);
}

struct Comparison {
  double solve = 0, acc = 0, lambda = 0, lambda_row = 0, fd = 0, fd_t = 0, pos = 0, vel = 0, lam_max = 0;
  int rows = 0, dependent = 0, released = 0;
};

// The state: q from the neutral pose projected onto Phi(q, t) = 0 (limits at their bounds,
// drives at f(t)), random rates projected onto G q_dot = nu, random efforts (cut joints'
// too when cut_effort) and loads; `base` carries t, limit sides and drive ramps.
Comparison compare(Builder& b, const State& base0, unsigned seed, bool cut_effort, const std::string& label,
                   bool unique_lambda = true, const std::function<void(Inputs&)>& adjust = nullptr) {
  System& sys = *b.sys;
  const double L = b.length;
  Comparison out;
  EXPECT_EQ(jointSpaceUnsupported(sys, true), "") << label;
  EXPECT_NE(jointSpaceUnsupported(sys), "") << label;
  TreeModel model(sys);
  TreeWorkspace ws(model);
  LoopClosures cl(model, sys);
  State base = base0;
  std::mt19937 rng(seed);
  Eigen::VectorXd q = model.neutralPositions(sys), qd(model.nv);
  auto translation = [&](const TreeLink& Lk, int k) {
    return Lk.kind == TreeJointKind::kPrismatic || (Lk.kind == TreeJointKind::kCylindrical && k == 1) ||
           (Lk.kind == TreeJointKind::kPlanar && k < 2);
  };
  for (const TreeLink& Lk : model.links)
    for (int k = 0; k < Lk.nv; ++k) qd(Lk.iv + k) = uniform(rng, -2, 2) * (translation(Lk, k) ? L : 1.0);
  // positions: the tracked angles follow q (a State made from q each time)
  State s = absoluteFromJoint(sys, model, ws, q, qd, base);
  cl.setContext(s.context());
  ClosureProjectionReport pr;
  for (int round = 0; round < 3; ++round) {
    pr = projectClosurePositions(model, sys, cl, q, ws, 1e-14, 30);
    s = absoluteFromJoint(sys, model, ws, q, qd, base);
    cl.setContext(s.context());
  }
  forwardKinematics(model, q, qd, ws);
  cl.evaluate(model, sys, ws);
  out.pos = cl.positionResidual();
  EXPECT_LT(out.pos, 1e-12) << label << ": position projection";
  const ClosureProjectionReport vr = projectClosureVelocities(model, sys, cl, q, qd, ws);
  out.vel = vr.residual;
  EXPECT_TRUE(vr.converged) << label << ": velocity projection " << vr.residual;
  s = absoluteFromJoint(sys, model, ws, q, qd, base);
  cl.setContext(s.context());

  Inputs in = zeroInputs(sys);
  const double effort = std::fabs(sys.gravity.z()) * L;
  for (int j = 0; j < sys.numJoints(); ++j) {
    if (model.joint_link[j] < 0 && !cut_effort) continue;
    const std::string t = sys.joints[j]->type();
    for (int k = 0; k < sys.joints[j]->dof(); ++k)
      in.effort[j][k] = uniform(rng, -1, 1) * effort / (t == "prismatic" ? L : 1.0);
  }
  for (int bb = 1; bb <= sys.nb; ++bb) {
    in.force[bb] = std::fabs(sys.gravity.z()) * Vector3d(uniform(rng, -1, 1), uniform(rng, -1, 1), uniform(rng, -1, 1));
    in.torque[bb] = effort * Vector3d(uniform(rng, -1, 1), uniform(rng, -1, 1), uniform(rng, -1, 1));
  }
  if (adjust) adjust(in);
  Eigen::VectorXd tau, qdd, acc;
  jointEfforts(model, in, tau);
  const ClosureSolveInfo info = constrainedForwardDynamics(model, sys, cl, q, qd, tau, ws, qdd, &in);
  bodyAccelerations(model, ws, qdd, acc);
  out.rows = info.rows, out.dependent = info.dependent;

  Stepper stepper(sys);
  stepper.analyzeDependencies(sys, s);
  const std::vector<signed char> sides = s.limit_side;
  std::vector<signed char> mine = sides;  // the closures' release rule on their first solve
  cl.releasePullingLimits(mine.data());
  stepper.settle(sys, s, in);
  EXPECT_EQ(mine, s.limit_side) << label << ": the limits released";
  int released = 0;
  for (size_t l = 0; l < sides.size(); ++l) released += sides[l] != s.limit_side[l];
  if (released) {
    // settle let go of limits that would pull (their multiplier of the wrong sign): the
    // closures' rule is the same, the caller's; solve again with the sides it left
    // (the closures read s's context).
    std::printf("[%s] settle released %d limit(s) that would pull; solving again with its sides\n", label.c_str(), released);
    cl.setContext(s.context());
    constrainedForwardDynamics(model, sys, cl, q, qd, tau, ws, qdd, &in);
    bodyAccelerations(model, ws, qdd, acc);
  }
  out.released = released;
  out.acc = accelerationDifference(acc, s.acc, sys.nb, L, sys.gravity.norm());
  Eigen::VectorXd lam_sys = Eigen::VectorXd::Zero(sys.m);
  cl.systemMultipliers(lam_sys);
  double worst = 0, worst_row = 0, big = 0;
  // Rows of limits left free are compared as zero: the closures give them lambda 0 (a
  // zero row); State::lambda keeps there what the solve before settle's release gave.
  std::vector<char> free_row(cl.m, 0);
  for (size_t i = 0; i < cl.constraints.size(); ++i) {
    const int l = sys.constraints[cl.constraints[i]]->limit();
    if (l >= 0 && s.limit_side[l] == 0) {
      free_row[cl.row[i]] = 1;
      EXPECT_EQ(cl.lambda(cl.row[i]), 0.0) << label << ": a free limit's multiplier";
    }
  }
  for (int e = 0; e < cl.m; ++e)
    if (!free_row[e]) big = std::max(big, std::fabs(s.lambda(cl.sys_row[e])));
  for (int e = 0; e < cl.m; ++e) {
    if (free_row[e]) continue;
    const double a = s.lambda(cl.sys_row[e]), d = std::fabs(lam_sys(cl.sys_row[e]) - a);
    worst = std::max(worst, d / std::max(big, 1e-300));
    if (std::fabs(a) > 1e-3 * big) worst_row = std::max(worst_row, d / std::fabs(a));
  }
  out.lambda = worst, out.lambda_row = worst_row, out.lam_max = big;
  {  // the allocation-free least-norm solve against Eigen's CompleteOrthogonalDecomposition::solve
    const Eigen::MatrixXd A = cl.G * cl.Y;
    Eigen::VectorXd d = Eigen::VectorXd::Zero(cl.m), b = cl.G * qdd;  // G q_ddot_free - gamma_q = b + G Y lambda - G q_ddot
    for (int e = 0; e < cl.m; ++e) {
      bool zero = true;
      for (int k = 0; k < cl.nv; ++k) zero = zero && !(std::fabs(cl.G(e, k)) > kClosureZeroEntry * cl.Gabs(e, k));
      d(e) = (!zero && A(e, e) > 0) ? 1.0 / std::sqrt(A(e, e)) : 0.0;
    }
    Eigen::MatrixXd As = d.asDiagonal() * A * d.asDiagonal();
    for (int e = 0; e < cl.m; ++e)
      if (d(e) == 0.0) As(e, e) = 1.0;
    b = A * cl.lambda;  // the right-hand side the solve saw (G q_ddot = gamma_q after it)
    Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd> cod(cl.m, cl.m);
    cod.setThreshold(kClosureRankThreshold);
    cod.compute(As);
    const Eigen::VectorXd ref = d.asDiagonal() * cod.solve(Eigen::VectorXd(d.asDiagonal() * b));
    Eigen::VectorXd mine(cl.m);
    cl.solve(b, mine);
    const double diff = (mine - ref).cwiseAbs().maxCoeff() / std::max(ref.cwiseAbs().maxCoeff(), 1e-300);
    EXPECT_LT(diff, 1e-12) << label << ": solve() against Eigen's COD";
    out.solve = diff;
  }
  EXPECT_LT(out.acc, 1e-10) << label;
  if (unique_lambda) {
    EXPECT_LT(out.lambda, 1e-10) << label;
  }

  if (cut_effort) {  // the cut joints' efforts act: without them the accelerations differ
    Inputs in0 = in;
    for (int j : model.cut_joints) in0.effort[j] = {0, 0, 0};
    Eigen::VectorXd qdd0, acc0;
    constrainedForwardDynamics(model, sys, cl, q, qd, tau, ws, qdd0, &in0);
    bodyAccelerations(model, ws, qdd0, acc0);
    const double without = accelerationDifference(acc0, s.acc, sys.nb, L, sys.gravity.norm());
    std::printf("[%s] without the cut joint's effort the accelerations would differ by %.2e\n", label.c_str(), without);
    EXPECT_GT(without, 1e-3) << label;
  }
  // ---- G against central differences of Phi along a random direction; nu against -Phi_t
  Eigen::VectorXd dv(model.nv);
  for (const TreeLink& Lk : model.links)
    for (int k = 0; k < Lk.nv; ++k) dv(Lk.iv + k) = uniform(rng, -1, 1) * (translation(Lk, k) ? L : 1.0);
  forwardKinematics(model, q, qd, ws);
  cl.evaluate(model, sys, ws);
  const Eigen::VectorXd Gdv = cl.G * dv, nu = cl.nu;
  const double eps = 1e-6;
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
  const double h = 1e-5;
  State sp = s, sm = s;
  sp.t += h, sm.t -= h;
  forwardKinematics(model, q, qd, ws);
  cl.evaluate(model, sys, ws, sp.context());
  const Eigen::VectorXd Pt = cl.Phi;
  cl.evaluate(model, sys, ws, sm.context());
  const Eigen::VectorXd fdt = -(Pt - cl.Phi) / (2 * h);
  out.fd_t = (fdt - nu).cwiseAbs().maxCoeff() / std::max(nu.cwiseAbs().maxCoeff(), 1e-300);
  if (nu.cwiseAbs().maxCoeff() == 0.0) out.fd_t = fdt.cwiseAbs().maxCoeff();
  EXPECT_LT(out.fd, 1e-7) << label;
  EXPECT_LT(out.fd_t, 1e-7) << label;
  std::printf("[%s] rows %d (dependent %d): acc %.2e, lambda %.2e (of max %.3g; per row %.2e), FD(G) %.2e, "
              "FD(nu) %.2e, position %.2e (%d its), velocity %.2e, solve vs Eigen COD %.1e\n",
              label.c_str(), out.rows, out.dependent, out.acc, out.lambda, out.lam_max, out.lambda_row, out.fd,
              out.fd_t, out.pos, pr.iterations, out.vel, out.solve);
  return out;
}

TEST(JointSpaceClosures, ChainWithActiveLimitsOnBothSides) {
  int kept_active = 0;
  for (double L : {1.0, 1e3})
    for (int side : {-1, 1}) {
      Builder b = chain(L);
      b.addLimit(0, 0, -0.2, 0.15);      // revolute
      b.addLimit(2, 0, -0.05 * L, 0.04 * L);  // prismatic
      b.addLimit(4, 0, -1.0, 1.0);       // left free
      b.sys->finalize();
      State base = initialState(*b.sys);
      base.limit_side[0] = static_cast<signed char>(side);
      base.limit_side[1] = static_cast<signed char>(-side);
      base.t = 0.3;
      const std::string label = std::string("chain, limits ") + (side < 0 ? "lower/upper" : "upper/lower") + (L == 1 ? ", m" : ", mm");
      const Comparison c = compare(b, base, 21, false, label, true, [&](Inputs& in) {
        // press each limited coordinate onto its bound, so settle keeps the limits active
        in.effort[0][0] += side * 40 * 9.81 * L * L;
        in.effort[2][0] += -side * 40 * 9.81 * L;
      });
      if (!c.released) {
        EXPECT_GT(c.lam_max, 0.0);
      }
      kept_active += c.released == 0;
    }
  EXPECT_EQ(kept_active, 4);  // the pressed limits all stayed active
}

// Not pressed: settle lets go of limits that would pull, and so does releasePullingLimits.
TEST(JointSpaceClosures, PullingLimitsAreReleasedAsTheAbsoluteSolverDoes) {
  int released = 0;
  for (double L : {1.0, 1e3})
    for (int side : {-1, 1}) {
      Builder b = chain(L);
      b.addLimit(0, 0, -0.2, 0.15);
      b.addLimit(2, 0, -0.05 * L, 0.04 * L);
      b.sys->finalize();
      State base = initialState(*b.sys);
      base.limit_side[0] = static_cast<signed char>(side);
      base.limit_side[1] = static_cast<signed char>(-side);
      const Comparison c = compare(b, base, 21, false, std::string("chain, limits not pressed, side ") + std::to_string(side) + (L == 1 ? ", m" : ", mm"));
      released += c.released;
    }
  EXPECT_GT(released, 0);
}

TEST(JointSpaceClosures, LimitsPastTheirBoundsAreActivated) {
  Builder b = chain(1.0);
  b.addLimit(0, 0, -0.2, 0.15);
  b.addLimit(2, 0, -0.05, 0.04);
  b.addLimit(3, 0, -1.0, 1.0);
  b.sys->finalize();
  const System& sys = *b.sys;
  TreeModel model(sys);
  TreeWorkspace ws(model);
  LoopClosures cl(model, sys);
  Eigen::VectorXd q = model.neutralPositions(sys), qd = Eigen::VectorXd::Zero(model.nv);
  q(model.links[model.joint_link[0]].iq) = 0.3;    // past upper
  q(model.links[model.joint_link[2]].iq) = -0.06;  // past lower
  q(model.links[model.joint_link[3]].iq) = 0.5;    // inside
  forwardKinematics(model, q, qd, ws);
  // the tracked angles of the tree joints at q (the caller's State would hold them)
  for (int j = 0; j < sys.numJoints(); ++j) {
    const Joint& J = *sys.joints[j];
    for (int k = 0; k < J.dof(); ++k)
      if (J.trackedSlot(k) >= 0) cl.tracked[sys.joint_constraint[j]][J.trackedSlot(k)] = q(model.links[model.joint_link[j]].iq + k);
  }
  std::vector<signed char> side(sys.limits.size(), 0);
  EXPECT_EQ(cl.activateReachedLimits(sys, model, q, qd, ws, side.data()), 2);
  EXPECT_EQ(side, (std::vector<signed char>{1, -1, 0}));
}

TEST(JointSpaceClosures, VelocityAndHarmonicDrivesAtNonzeroTime) {
  for (double L : {1.0, 1e3}) {
    Builder b = chain(L);
    b.addDrive(0, 0, DriveProfile::velocity(0.8), 0.1);
    b.addDrive(2, 0, DriveProfile::harmonic(0.01 * L, 0.05 * L, 1.3, 0.4), 0.0);
    b.addDrive(3, 0, DriveProfile::harmonic(0.2, 0.3, 0.7, -0.5), 0.0);
    b.sys->finalize();
    State base = initialState(*b.sys);
    base.t = 0.37;
    compare(b, base, 22, false, std::string("chain, velocity and harmonic drives, t 0.37") + (L == 1 ? ", m" : ", mm"));
  }
}

TEST(JointSpaceClosures, MimicCouplerBetweenTreeJoints) {
  for (double L : {1.0, 1e3}) {
    Builder b = chain(L);
    b.addCoupler(3, 0, -0.7, 0.05);  // q3 = -0.7 q0 + 0.05
    b.addCoupler(4, 1, 1.5, 0.0);    // across the reversed link
    b.sys->finalize();
    State base = initialState(*b.sys);
    compare(b, base, 23, false, std::string("chain, mimic couplers") + (L == 1 ? ", m" : ", mm"));
  }
}

TEST(JointSpaceClosures, FourBarWithDrivenCrank) {
  for (double L : {1.0, 1e3})
    for (bool harmonic : {false, true}) {
      Builder b = fourBar(L);
      b.addDrive(0, 0, harmonic ? DriveProfile::harmonic(0.05, 0.2, 0.9, 0.3) : DriveProfile::velocity(1.2), 0.02);
      b.sys->finalize();
      State base = initialState(*b.sys);
      base.t = 0.21;
      compare(b, base, 24, false,
              std::string("four-bar, ") + (harmonic ? "harmonic" : "velocity") + " drive on the crank" + (L == 1 ? ", m" : ", mm"));
    }
}

TEST(JointSpaceClosures, EffortOnCutJoint) {
  for (double L : {1.0, 1e3}) {
    Builder b = fourBar(L);
    b.sys->finalize();
    State base = initialState(*b.sys);
    compare(b, base, 25, true, std::string("four-bar, efforts on every joint, the cut one too") + (L == 1 ? ", m" : ", mm"));
    // only on the cut joint
    TreeModel model(*b.sys);
    ASSERT_EQ(model.cut_joints.size(), 1u);
  }
}

TEST(JointSpaceClosures, FrictionPassesAndDefaultRefusesClosures) {
  Builder b = chain(1.0);
  b.addLimit(0, 0, -0.2, 0.15);
  b.sys->finalize();
  EXPECT_EQ(jointSpaceUnsupported(*b.sys, true), "");
  EXPECT_NE(jointSpaceUnsupported(*b.sys).find("limit"), std::string::npos) << jointSpaceUnsupported(*b.sys);
  b.sys->friction.assign(b.sys->numJoints(), {0, 0, 0});
  b.sys->friction[1][0] = 0.3;  // an effort along the joint (JointStepper::frictionFor)
  EXPECT_EQ(jointSpaceUnsupported(*b.sys, true), "");
}

}  // namespace
}  // namespace mechanism_sim
