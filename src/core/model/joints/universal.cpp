#include "mechanism_sim/core/model/joints/universal.h"

#include <cmath>

namespace mechanism_sim {

// Pose of frame j in frame i: Rx(axis1) Ry(axis2).
Eigen::Isometry3d UniversalJoint::relativePose(const double* q, const JointParams&) {
  return pose(Eigen::AngleAxisd(q[0], Vector3d::UnitX()).toRotationMatrix() *
                  Eigen::AngleAxisd(q[1], Vector3d::UnitY()).toRotationMatrix(),
              Vector3d::Zero());
}

std::unique_ptr<Joint> UniversalJoint::make(const std::string& name, int bi,
                                            const JointFrame& fi, int bj, const JointFrame& fj,
                                            const JointParams&) {
  return std::make_unique<UniversalJoint>(name, bi, fi, bj, fj);
}

void UniversalJoint::equations(const JointGeometry& g, const BodyKin&, const BodyKin&,
                               const Tracked&, RowWriter& out) const {
  putPoint(g, out);               // d_ij = 0                         (3)
  out.put(Cn1(g.bx_i, g.by_j));   // C(n1)(bx_i, by_j) = 0 (8.11)     (1)
}

// With R = Fi^T Fj = Rx(t1) Ry(t2): R(2,1) = sin t1, R(1,1) = cos t1, R(0,2) = sin t2,
// R(0,0) = cos t2, each entry a C(n1) of one axis of each frame.
void UniversalJoint::coordinates(const BodyKin& ki, const BodyKin& kj, const Tracked& t, Row* out) const {
  const JointGeometry g = geometry(ki, kj, kBxI | kByI | kBzI | kBxJ | kByJ | kBzJ);
  out[0] = angleOf(Cn1(g.by_i, g.by_j), Cn1(g.bz_i, g.by_j), t[0]);
  out[1] = angleOf(Cn1(g.bx_i, g.bx_j), Cn1(g.bx_i, g.bz_j), t[1]);
}

// Tree model: R = Rx(q0) Ry(q1). The angular velocity in frame j is q0_dot Ry(q1)^T ex +
// q1_dot ey; the first column turns with q1: c = q0_dot q1_dot d(Ry^T ex)/dq1 =
// q0_dot q1_dot (-s1, 0, c1).
namespace {
void universalCalc(const JointParams&, const double* q, const double* qd, Matrix3d& R, Vector3d&, MotionSubspace& S,
                   Vector6d& c) {
  const double c1 = std::cos(q[1]), s1 = std::sin(q[1]);
  R = Eigen::AngleAxisd(q[0], Vector3d::UnitX()).toRotationMatrix() *
      Eigen::AngleAxisd(q[1], Vector3d::UnitY()).toRotationMatrix();
  S(0, 0) = c1, S(2, 0) = s1;
  S(1, 1) = 1;
  c(0) = -qd[0] * qd[1] * s1;
  c(2) = qd[0] * qd[1] * c1;
}
}  // namespace

TreeJointModel UniversalJoint::treeModel() {
  TreeJointModel m;
  m.kind = TreeJointKind::kUniversal;
  m.nq = m.nv = 2;
  m.calc = &universalCalc;
  return m;
}

}  // namespace mechanism_sim
