#include "mechanism_sim/core/model/joints/spherical.h"

namespace mechanism_sim {

// Pose of frame j in frame i: the rotation vector (x, y, z).
Eigen::Isometry3d SphericalJoint::relativePose(const double* q, const JointParams&) {
  return pose(expRotation(Vector3d(q[0], q[1], q[2])).toRotationMatrix(), Vector3d::Zero());
}

std::unique_ptr<Joint> SphericalJoint::make(const std::string& name, int bi,
                                            const JointFrame& fi, int bj, const JointFrame& fj,
                                            const JointParams&) {
  return std::make_unique<SphericalJoint>(name, bi, fi, bj, fj);
}

void SphericalJoint::equations(const JointGeometry& g, const BodyKin&, const BodyKin&,
                               const Tracked&, RowWriter& out) const {
  putPoint(g, out);  // d_ij = 0
}

// Rates: omega_rel = F_i^T (A_Oj w_j - A_Oi w_i), F_i = A_Oi Rp_i the frame-i axes, so
// q_x = [0, -Rp_i^T, 0, F_i^T A_Oj]. Positions: rotation vector of F_i^T F_j.
// gamma: the rates' own velocity term, d/dt rate = q_x a - gamma (joint.h). With F_i_dot =
// omega_i~ F_i, d/dt F_i^T = -F_i^T omega_i~, so d/dt rate = q_x a - (F_i^T omega_i) x rate:
// gamma = (Rp_i^T w'_i) x rate, zero on a joint to ground. (The rates are not derivatives
// of the positions; gamma is that of the rates: friction sizes its stopping effort with it,
// and jointAcceleration reports d/dt rate, as the joint formulation's q_ddot.)
void SphericalJoint::coordinates(const BodyKin& ki, const BodyKin& kj, const Tracked&, Row* out) const {
  const Matrix3d Fi = ki.A_Oi * frameI().Rp;
  const Matrix3d Fj = kj.A_Oi * frameJ().Rp;
  const Vector3d rotvec = logRotation(Quaterniond(Matrix3d(Fi.transpose() * Fj)));
  const Vector3d rate = Fi.transpose() * (kj.A_Oi * kj.w - ki.A_Oi * ki.w);
  const Vector3d gamma = (frameI().Rp.transpose() * ki.w).cross(rate);
  const Matrix3d Gi = -frameI().Rp.transpose();
  const Matrix3d Gj = Fi.transpose() * kj.A_Oi;
  for (int k = 0; k < 3; ++k) {
    out[k] = Row();
    out[k].Phi = rotvec(k);
    out[k].Phi_dot = rate(k);
    out[k].gamma = gamma(k);
    out[k].J.segment<3>(3) = Gi.row(k);
    out[k].J.segment<3>(9) = Gj.row(k);
  }
}

// Tree model: q the unit quaternion (w x y z) of frame j in frame i, q_dot the relative
// angular velocity in frame-i components (as coordinates()' rates), in frame j R^T q_dot:
// S = [R^T; 0]. With R_dot = R omega_j~, d(R^T)/dt q_dot = -omega_j x (R^T q_dot) =
// -omega_j x omega_j = 0: no bias.
namespace {
void sphericalCalc(const JointParams&, const double* q, const double*, Matrix3d& R, Vector3d&, MotionSubspace& S,
                   Vector6d&) {
  R = Quaterniond(q[0], q[1], q[2], q[3]).normalized().toRotationMatrix();
  S.topLeftCorner<3, 3>() = R.transpose();
}
}  // namespace

TreeJointModel SphericalJoint::treeModel() {
  TreeJointModel m;
  m.kind = TreeJointKind::kSpherical;
  m.nq = 4, m.nv = 3;
  m.quaternion = 0;
  m.calc = &sphericalCalc;
  return m;
}

// The quaternion of F_i^T F_j (frame j in frame i).
void SphericalJoint::treePositions(const BodyKin& ki, const BodyKin& kj, const Tracked&, double* q) const {
  const Matrix3d Ri = ki.A_Oi * frameI().Rp, Rj = kj.A_Oi * frameJ().Rp;
  const Quaterniond p(Ri.transpose() * Rj);
  q[0] = p.w(), q[1] = p.x(), q[2] = p.y(), q[3] = p.z();
}

}  // namespace mechanism_sim
