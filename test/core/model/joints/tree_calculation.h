// A joint type's tree calculation (TreeJointModel, joint.h) against its constraint rows
// (test/core/model/joints/test_<type>.cpp). Body i anywhere and moving; body j placed by
// the calculation's pose (R, t) of frame j in frame i and moved relative to it by
// v_J = S q_dot (frame-j Plucker coordinates), at random q and q_dot of the model's size:
// - the joint's equations hold (Phi = 0) and so do their rates (Phi_q v = 0): S spans
//   motions the joint allows;
// - the joint's coordinates give back q (Joint::treePositions) and q_dot (Phi_dot of
//   Joint::coordinates(), q_x v): S q_dot is the motion of those coordinates' rates;
// - the pose is JointTypeInfo::relativePose's at the joint's coordinates;
// - c is the rate of change of S's coordinates along the motion, d/dt (S) q_dot, by
//   central differences (a quaternion moved on the manifold, on its rates' side).
#pragma once
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <random>
#include <string>

#include "fd_util.h"
#include "mechanism_sim/core/model/joint.h"

namespace mechanism_sim {
namespace test_util {

// The calculation's outputs, from R = 1, t = 0, S = 0, c = 0 (TreeJointCalc).
struct TreeCalc {
  Matrix3d R = Matrix3d::Identity();
  Vector3d t = Vector3d::Zero();
  MotionSubspace S;
  Vector6d c = Vector6d::Zero();
};

inline TreeCalc treeCalc(const TreeJointModel& m, const JointParams& params, const Eigen::VectorXd& q,
                         const Eigen::VectorXd& qd) {
  TreeCalc out;
  out.S.setZero(6, m.nv);
  m.calc(params, q.data(), qd.data(), out.R, out.t, out.S, out.c);
  return out;
}

// q moved by h q_dot: a quaternion by exp(h w) on its rates' side, the rest along q_dot.
inline Eigen::VectorXd treeAdvance(const TreeJointModel& m, const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                                   double h) {
  Eigen::VectorXd x = q;
  for (int k = 0; k < m.nv; ++k)
    if (m.quaternion < 0 || k < m.quaternion) x(k) += h * qd(k);
  if (m.quaternion >= 0) {
    const int n = m.quaternion;
    const Quaterniond Q(q(n), q(n + 1), q(n + 2), q(n + 3));
    const Quaterniond E = expRotation(h * Vector3d(qd(n), qd(n + 1), qd(n + 2)));
    const Quaterniond P = m.quaternion_in_child ? Q * E : E * Q;
    x.segment<4>(n) << P.w(), P.x(), P.y(), P.z();
  }
  return x;
}

inline void checkTreeCalculation(const std::string& type, const JointParams& params, unsigned seed = 1) {
  const TreeJointModel* model = treeJointModel(type);
  ASSERT_NE(model, nullptr) << type << ": no tree model";
  const TreeJointModel& m = *model;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.2, 1.2), rate(-2.0, 2.0);
  for (int trial = 0; trial < 8; ++trial) {
    SCOPED_TRACE("trial " + std::to_string(trial));
    JointFrame fi, fj;
    fi.sp_B = test::randomVector(rng, 0.5), fi.Rp = test::randomRotation(rng);
    fj.sp_B = test::randomVector(rng, 0.5), fj.Rp = test::randomRotation(rng);
    const std::unique_ptr<Joint> J = makeJoint(type, "joint", 1, fi, 2, fj, params);
    ASSERT_EQ(m.nv, J->dof());
    Eigen::VectorXd q(m.nq), qd(m.nv);
    for (int k = 0; k < m.nq; ++k) q(k) = u(rng);
    for (int k = 0; k < m.nv; ++k) qd(k) = rate(rng);
    if (m.quaternion >= 0) q.segment<4>(m.quaternion).normalize();
    const TreeCalc T = treeCalc(m, params, q, qd);
    ASSERT_EQ(T.S.cols(), m.nv);

    // body i, and body j placed by (R, t) and moved by S q_dot relative to frame i
    const BodyKin ki = test::randomBody(rng);
    const Matrix3d Fi = ki.A_Oi * fi.Rp, Fj = Fi * T.R;
    const Vector3d oi = ki.r + ki.A_Oi * fi.sp_B, oj = oi + Fi * T.t;
    BodyKin kj;
    kj.A_Oi = Fj * fj.Rp.transpose();
    kj.r = oj - kj.A_Oi * fj.sp_B;
    const Vector6d vJ = T.S * qd;
    const Vector3d omega_i = ki.A_Oi * ki.w, omega_j = omega_i + Fj * vJ.head<3>();
    const Vector3d v_oj = ki.v + omega_i.cross(oj - ki.r) + Fj * vJ.tail<3>();
    kj.w = kj.A_Oi.transpose() * omega_j;
    kj.v = v_oj + omega_j.cross(kj.r - oj);
    const double scale = 1.0 + q.norm() + qd.norm();

    // the equations and their rates
    const BodyKin* kin[2] = {&ki, &kj};
    std::vector<Tracked> tracked(1, J->initialTracked());
    for (int k = 0; k < J->dof(); ++k)
      if (J->trackedSlot(k) >= 0) tracked[0][J->trackedSlot(k)] = q(k);
    EvalContext ctx;
    ctx.tracked = tracked.data();
    Eigen::VectorXd Phi(J->size()), gamma(J->size());
    Eigen::MatrixXd Phi_q(J->size(), 12);
    J->evaluate(kin, ctx, Phi, Phi_q, gamma);
    Eigen::Matrix<double, 12, 1> v;
    v << ki.v, ki.w, kj.v, kj.w;
    EXPECT_LE(Phi.norm(), 1e-12 * scale) << type << ": the calculation's pose violates the equations";
    EXPECT_LE((Phi_q * v).norm(), 1e-12 * scale) << type << ": S q_dot violates the equations' rates";

    // the coordinates give back q and q_dot
    Eigen::VectorXd q_back(m.nq);
    J->treePositions(ki, kj, tracked[0], q_back.data());
    if (m.quaternion >= 0 && q_back.segment<4>(m.quaternion).dot(q.segment<4>(m.quaternion)) < 0)
      q_back.segment<4>(m.quaternion) *= -1.0;  // (q and -q are one rotation)
    EXPECT_LE((q_back - q).norm(), 1e-12 * scale) << type << ": q " << q.transpose() << ", back " << q_back.transpose();
    Row rows[kMaxJointDofs];
    J->coordinates(ki, kj, tracked[0], rows);
    double coords[kMaxJointDofs] = {};
    for (int k = 0; k < m.nv; ++k) {
      EXPECT_NEAR(rows[k].Phi_dot, qd(k), 1e-12 * scale) << type << ": the rate of coordinate " << k;
      EXPECT_NEAR(rows[k].J.dot(v), qd(k), 1e-12 * scale) << type << ": q_x v of coordinate " << k;
      coords[k] = rows[k].Phi;
    }

    // the pose is relativePose's
    const Eigen::Isometry3d P = jointTypeInfo(type).relativePose(coords, params);
    EXPECT_LE((P.linear() - T.R).norm(), 1e-12) << type;
    EXPECT_LE((P.translation() - T.t).norm(), 1e-12 * scale) << type;

    // c against central differences of S q_dot along the motion
    const double h = 1e-5;
    const TreeCalc Tp = treeCalc(m, params, treeAdvance(m, q, qd, h), qd);
    const TreeCalc Tm = treeCalc(m, params, treeAdvance(m, q, qd, -h), qd);
    const Vector6d c_fd = (Tp.S * qd - Tm.S * qd) / (2 * h);
    EXPECT_LE((c_fd - T.c).norm(), 1e-7 * (1 + qd.squaredNorm())) << type << ": c " << T.c.transpose()
                                                                  << ", differences " << c_fd.transpose();
  }
}

}  // namespace test_util
}  // namespace mechanism_sim
