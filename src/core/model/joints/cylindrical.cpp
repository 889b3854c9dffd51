#include "mechanism_sim/core/model/joints/cylindrical.h"

namespace mechanism_sim {

// Pose of frame j in frame i: Rz(rotation), translation along bz_i.
Eigen::Isometry3d CylindricalJoint::relativePose(const double* q, const JointParams&) {
  return pose(rotZ(q[0]), Vector3d(0, 0, q[1]));
}

std::unique_ptr<Joint> CylindricalJoint::make(const std::string& name, int bi,
                                              const JointFrame& fi, int bj,
                                              const JointFrame& fj, const JointParams&) {
  return std::make_unique<CylindricalJoint>(name, bi, fi, bj, fj);
}

// Seed table A8.1 (a).
void CylindricalJoint::equations(const JointGeometry& g, const BodyKin&, const BodyKin&,
                                 const Tracked&, RowWriter& out) const {
  putParallelAxes(g, out);  // C(p1)(bz_i, bz_j)   = 0 (A8.1)  (2)
  putOnAxis(g, out);        // C(p2)(bz_i, d_ij)   = 0 (A8.2)  (2)
}

void CylindricalJoint::coordinates(const BodyKin& ki, const BodyKin& kj, const Tracked& t, Row* out) const {
  const JointGeometry g = geometry(ki, kj, kBxI | kByI | kBzI | kBxJ | kGap);
  out[0] = relativeAngle(g.bx_i, g.by_i, g.bx_j, t[0]);
  out[1] = Cn2(g.bz_i, g.d);
}

// Tree model: Rz(q0), q1 along bz; S = [(bz; 0) (0; bz)], constant (R^T bz = bz).
namespace {
void cylindricalCalc(const JointParams&, const double* q, const double*, Matrix3d& R, Vector3d& t, MotionSubspace& S,
                     Vector6d&) {
  R = rotZ(q[0]);
  t.z() = q[1];
  S(2, 0) = 1;
  S(5, 1) = 1;
}
}  // namespace

TreeJointModel CylindricalJoint::treeModel() {
  TreeJointModel m;
  m.kind = TreeJointKind::kCylindrical;
  m.nq = m.nv = 2;
  m.lengths = 2;
  m.calc = &cylindricalCalc;
  return m;
}

}  // namespace mechanism_sim
