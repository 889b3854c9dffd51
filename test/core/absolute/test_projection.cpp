// The projections onto the constraints (absolute/projection.h). Oracles: a closed form and
// the projections' defining property. Positions: a pendulum bob whose pivot point is pulled
// off the pivot by delta is moved back to the mass-weighted nearest pose, the minimum of
// m |r - r0|^2 + I phi^2 over the circle, whose angle solves
//   m L^2 sin(phi) + I phi = m L delta cos(phi)
// (from phi ~ delta / L for a light moment to ~ 0 for a heavy one); a displaced four-bar
// (penalty form) back to the position tolerance, its correction M-orthogonal to the motion
// it allows. Velocities: the mass-orthogonal projection onto Phi_q v = 0, which keeps the
// tangential component T (T^T M T)^-1 T^T M u, T the allowed motions (null space of Phi_q):
// in closed form for the pendulum, from the null space for the four-bar; and a point-like bob
// stopped by its limit beside a loop comes to rest under the static torque m g L cos(q).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>

#include <Eigen/Dense>

#include "bodies.h"
#include "core/absolute/evaluation.h"
#include "core/absolute/projection.h"
#include "core/absolute/solver.h"
#include "mechanism_sim/core/models.h"
#include "pendulum.h"

namespace mechanism_sim {
namespace {

// A bob of mass m and moment I (about every axis) on a revolute about +y through the origin,
// its centre at (L, 0, 0) when the joint reads 0: the rotation phi about y puts it at
// L (cos phi, 0, -sin phi).
std::unique_ptr<System> pendulum(double m, double L, double I) {
  auto sys = std::make_unique<System>();
  Body ground;
  ground.name = "ground";
  sys->bodies.push_back(ground);
  sys->bodies.push_back(body("bob", m, I * Matrix3d::Identity(), Vector3d(L, 0, 0)));
  auto j = makeJoint("revolute", "pivot", 0, models::axisY(Vector3d::Zero()), 1, models::axisY(Vector3d(-L, 0, 0)));
  sys->joints.push_back(j.get());
  sys->joint_constraint.push_back(0);
  sys->constraints.push_back(std::shared_ptr<Constraint>(std::move(j)));
  sys->finalize();
  return sys;
}

// The solver, evaluation and scratch of a projection, for a System.
struct Projector {
  SolverStats stats;
  Evaluation ev;
  std::unique_ptr<ConstraintSolver> solver;
  Projection w;
  explicit Projector(const System& sys) : ev(sys), solver(makeSolver(sys, stats)), w(sys) {}
};

// Rotation angle about y of the body's orientation in s.
double angleAboutY(const State& s) {
  const Quaterniond p(s.x(3), s.x(4), s.x(5), s.x(6));
  return 2.0 * std::atan2(p.y(), p.w());
}

// The mass-weighted nearest pose's angle: m L^2 sin(phi) + I phi = m L delta cos(phi).
double nearestAngle(double m, double L, double I, double delta) {
  double phi = m * L * delta / (m * L * L + I);
  for (int k = 0; k < 50; ++k) {
    const double f = m * L * L * std::sin(phi) + I * phi - m * L * delta * std::cos(phi);
    const double df = m * L * L * std::cos(phi) + I + m * L * delta * std::sin(phi);
    phi -= f / df;
  }
  return phi;
}

// The bob at (L, 0, -delta), unrotated: its pivot point is delta below the pivot. The
// nearest pose on the circle in the mass metric takes the rotation or the translation as
// the moment is light or heavy; the projection's Newton steps, each M-orthogonal to the
// constraints' linearization where it is taken, reach it to second order in delta / L
// (delta = 1e-4 L: about 1e-8 of the angle; the unweighted nearest point, phi = delta / L
// whatever I, is off by a factor 1 + I / (m L^2), 1e-2 for the lightest moment here).
TEST(PositionProjection, PendulumReturnsToTheMassWeightedNearestPose) {
  const double m = 2.0, L = 0.8, delta = 1e-4 * L;
  for (double ratio : {0.01, 1.0, 100.0}) {  // I / (m L^2)
    SCOPED_TRACE(ratio);
    const double I = ratio * m * L * L;
    auto sys = pendulum(m, L, I);
    Projector p(*sys);
    EXPECT_STREQ(p.solver->name(), "tree KKT");
    State s = initialState(*sys);
    s.x(2) = -delta;
    evaluateAt(*sys, s, p.ev);
    ASSERT_GT(positionResidual(*sys, p.ev), sys->options.position_tol);
    EXPECT_TRUE(projectPositions(*sys, s, p.ev, *p.solver, p.w, p.stats, false));
    EXPECT_LE(positionResidual(*sys, p.ev), sys->options.position_tol);
    EXPECT_LT(positionViolation(p.ev), 1e-14 * L);
    EXPECT_EQ(p.stats.position_shortfalls, 0);
    const double phi = nearestAngle(m, L, I, delta);
    EXPECT_NEAR(angleAboutY(s), phi, 1e-6 * phi) << "phi* = " << phi;
    const Vector3d r(s.x(0), s.x(1), s.x(2));
    EXPECT_LT((r - L * Vector3d(std::cos(phi), 0, -std::sin(phi))).norm(), 1e-6 * delta);
  }
}

// A state on the constraints is left alone: no Newton step, the same bits.
TEST(PositionProjection, AStateOnTheConstraintsIsLeftAsItIs) {
  auto sys = pendulum(1.0, 1.0, 0.1);
  Projector p(*sys);
  State s = initialState(*sys);
  const Eigen::VectorXd x0 = s.x;
  evaluateAt(*sys, s, p.ev);
  EXPECT_FALSE(projectPositions(*sys, s, p.ev, *p.solver, p.w, p.stats, false));
  EXPECT_EQ(s.x, x0);
  EXPECT_EQ(p.stats.position_projections, 1);
}

// Velocities at the pendulum's pose phi = 0: the allowed motion is t = (v, w') =
// ((0, 0, -L), (0, 1, 0)) per unit rate; the projection keeps
//   phi_dot = t^T M u / t^T M t = (-m L v_z + I w_y) / (m L^2 + I)
// and removes every motion M-orthogonal to t.
TEST(VelocityProjection, PendulumKeepsTheMassWeightedTangentialRate) {
  const double m = 2.0, L = 0.8;
  std::mt19937 rng(31);
  std::uniform_real_distribution<double> u01(-1.0, 1.0);
  for (double ratio : {0.01, 1.0, 100.0}) {
    SCOPED_TRACE(ratio);
    const double I = ratio * m * L * L;
    auto sys = pendulum(m, L, I);
    for (int n = 0; n < 20; ++n) {
      Projector p(*sys);
      State s = initialState(*sys);
      for (int k = 0; k < 6; ++k) s.u(k) = u01(rng);
      const double rate = (-m * L * s.u(2) + I * s.u(4)) / (m * L * L + I);
      Eigen::VectorXd expected(6);
      expected << 0, 0, -L * rate, 0, rate, 0;
      evaluateAt(*sys, s, p.ev);
      p.solver->factor(*sys, p.ev, "velocity projection test", 0.0);
      EXPECT_TRUE(projectVelocities(*sys, s, p.ev, *p.solver, p.w, p.stats));
      EXPECT_LT((s.u - expected).cwiseAbs().maxCoeff(), 1e-13 * (1 + std::fabs(rate) * L)) << n;
      EXPECT_EQ(p.stats.velocity_shortfalls, 0);
    }
  }
}

// The dense Phi_q (m x n) of an evaluation, column by column.
Eigen::MatrixXd denseJacobian(const System& sys, const Evaluation& ev) {
  Eigen::MatrixXd J(sys.m, sys.n);
  Eigen::VectorXd e = Eigen::VectorXd::Zero(sys.n), col(sys.m);
  for (int i = 0; i < sys.n; ++i) {
    e(i) = 1.0;
    mulJ(sys, ev, sys.all_constraints, e.data(), col.data());
    J.col(i) = col;
    e(i) = 0.0;
  }
  return J;
}

// The motions Phi_q allows (an orthonormal basis of its null space).
Eigen::MatrixXd allowedMotions(const Eigen::MatrixXd& J) {
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(J, Eigen::ComputeFullV);
  const Eigen::VectorXd sv = svd.singularValues();
  int rank = 0;
  for (int i = 0; i < sv.size(); ++i) rank += sv(i) > 1e-9 * sv(0);
  return svd.matrixV().rightCols(J.cols() - rank);
}

Eigen::MatrixXd massMatrix(const System& sys) {
  Eigen::MatrixXd M = Eigen::MatrixXd::Zero(sys.n, sys.n);
  for (int b = 0; b < sys.nb; ++b) {
    M.block<3, 3>(6 * b, 6 * b) = sys.bodies[b + 1].m * Matrix3d::Identity();
    M.block<3, 3>(6 * b + 3, 6 * b + 3) = sys.bodies[b + 1].Jp;
  }
  return M;
}

// The variation (dr, body-frame rotation vector) from positions x0 to x.
Eigen::VectorXd variation(const System& sys, const Eigen::VectorXd& x0, const Eigen::VectorXd& x) {
  Eigen::VectorXd d(sys.n);
  for (int b = 0; b < sys.nb; ++b) {
    const int i = BodyCoordinates::x(b);
    d.segment<3>(6 * b) = x.segment<3>(i) - x0.segment<3>(i);
    const Quaterniond p0(x0(i + 3), x0(i + 4), x0(i + 5), x0(i + 6)), p(x(i + 3), x(i + 4), x(i + 5), x(i + 6));
    const Eigen::AngleAxisd turn(p0.conjugate() * p);
    d.segment<3>(6 * b + 3) = turn.angle() * turn.axis();
  }
  return d;
}

// A four-bar (a loop: every equation in penalty form, some of them dependent) displaced by
// 1e-4 of its size along random variations returns to the position tolerance; its
// correction is M-orthogonal to the motion the loop allows there, to second order in the
// displacement (the projection's Newton steps are exactly M-orthogonal where each is taken,
// H t = M t for an allowed motion t).
TEST(PositionProjection, DisplacedFourBarReturnsMOrthogonallyToItsMotion) {
  Mechanism mech;
  models::fourBarChain(mech, 1);
  mech.build();
  mech.assemble();
  const System& sys = mech.system();
  const Eigen::MatrixXd M = massMatrix(sys);
  std::mt19937 rng(32);
  std::normal_distribution<double> n01(0.0, 1.0);
  double worst = 0;
  for (int n = 0; n < 10; ++n) {
    Projector p(sys);
    EXPECT_STREQ(p.solver->name(), "penalty");
    State s = mech.snapshot();
    Eigen::VectorXd dq(sys.n);
    for (int i = 0; i < sys.n; ++i) dq(i) = 1e-4 * n01(rng) * (i % 6 < 3 ? sys.length_scale : 1.0);
    displace(sys, s.x, dq.data());
    const Eigen::VectorXd x0 = s.x;
    evaluateAt(sys, s, p.ev);
    ASSERT_GT(positionResidual(sys, p.ev), 1e-6);
    EXPECT_TRUE(projectPositions(sys, s, p.ev, *p.solver, p.w, p.stats, false));
    EXPECT_LE(positionResidual(sys, p.ev), sys.options.position_tol) << n;
    // (the tolerance is relative to each equation's terms, a few lengths: |Phi| to 1e-12 L)
    EXPECT_LT(positionViolation(p.ev), 1e-12 * sys.length_scale) << n;
    const Eigen::MatrixXd T = allowedMotions(denseJacobian(sys, p.ev));
    ASSERT_EQ(T.cols(), 1) << "a four-bar moves one way";
    const Eigen::VectorXd d = variation(sys, x0, s.x);
    const double along = std::fabs((T.transpose() * M * d)(0));
    const double size = std::sqrt((T.transpose() * M * T)(0, 0) * d.dot(M * d));
    EXPECT_LT(along, 1e-3 * size) << n;
    worst = std::max(worst, along / size);
  }
  std::printf("[four-bar projection] correction's M-weighted share along the motion: %.1e\n", worst);
}

// Velocities of the four-bar projected onto Phi_q v = 0: the allowed motion's
// M-weighted component of u is kept, everything M-orthogonal to it removed; the iterated
// penalty passes give the exact projection (their sum of corrections lies in
// range(H^-1 Phi_q^T), M-orthogonal to every allowed t since H t = M t), to the round-off of
// a solve with H, whose condition grows like kappa: a few kappa eps of the velocities
// removed (kappa = 1e7: about 1e-9).
TEST(VelocityProjection, FourBarKeepsTheComponentAlongItsMotion) {
  Mechanism mech;
  models::fourBarChain(mech, 1);
  mech.build();
  mech.assemble();
  const System& sys = mech.system();
  const Eigen::MatrixXd M = massMatrix(sys);
  std::mt19937 rng(33);
  std::normal_distribution<double> n01(0.0, 1.0);
  for (int n = 0; n < 10; ++n) {
    Projector p(sys);
    State s = mech.snapshot();
    for (int i = 0; i < sys.n; ++i) s.u(i) = n01(rng);
    const double size = s.u.cwiseAbs().maxCoeff();
    evaluateAt(sys, s, p.ev);
    const Eigen::MatrixXd T = allowedMotions(denseJacobian(sys, p.ev));
    ASSERT_EQ(T.cols(), 1);
    const Eigen::VectorXd expected = T * (T.transpose() * M * T).ldlt().solve(T.transpose() * M * s.u);
    p.solver->factor(sys, p.ev, "velocity projection test", 0.0);
    EXPECT_TRUE(projectVelocities(sys, s, p.ev, *p.solver, p.w, p.stats));
    EXPECT_EQ(p.stats.velocity_shortfalls, 0);
    const double roundoff = ConstraintSolver::kKappa * std::numeric_limits<double>::epsilon();
    EXPECT_LT((s.u - expected).cwiseAbs().maxCoeff(), 20 * roundoff * size) << n;
    // and a velocity that is already allowed is kept as it is
    const Eigen::VectorXd allowed = s.u;
    EXPECT_FALSE(projectVelocities(sys, s, p.ev, *p.solver, p.w, p.stats));
    EXPECT_EQ(s.u, allowed);
  }
}

// A point-like bob (central moment 1e-6 of m L^2) falling onto its stop beside a four-bar
// it has nothing to do with: the loop puts every equation in penalty form, and the velocity
// projection at the stop's impact must still remove the motion into the stop. It comes to
// rest there, held by the static torque m g L cos(q_stop), as it does alone (tree KKT form)
// and as a bob with a moment of 1e-4 m L^2 does beside the loop.
TEST(VelocityProjection, APointLikeBobStopsOnItsLimitBesideALoop) {
  for (double Ic : {1e-3, 1e-6}) {
    SCOPED_TRACE(Ic);
    Mechanism m;
    models::fourBarChain(m, 1);
    Pendulum p;
    p.Ic = Ic;
    p.pivot = Vector3d(0, 2, 0);
    p.add(m);
    const int joint = m.numJoints() - 1;
    m.setJointLimits(joint, 0, -0.6, 0.6);
    m.build();
    m.assemble();
    ASSERT_STREQ(m.formulation(), "absolute");
    try {
      for (int k = 0; k < 1000; ++k) m.step(1e-3);
    } catch (const Error& e) {
      ADD_FAILURE() << "t = " << m.time() << ": " << e.what();
      continue;
    }
    EXPECT_EQ(m.state().limit_side[0], 1);
    EXPECT_NEAR(m.jointPosition(joint, 0), 0.6, 1e-9);
    EXPECT_NEAR(m.jointVelocity(joint, 0), 0.0, 1e-9);
    EXPECT_NEAR(m.jointEffort(joint, 0), -p.m * kG * p.L * std::cos(0.6), 1e-9);
  }
}

}  // namespace
}  // namespace mechanism_sim
