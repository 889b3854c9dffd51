#include "mechanism_sim/core/model/joints/planar.h"

#include <cmath>

namespace mechanism_sim {

// Pose of frame j in frame i: translation (x, y) in the plane, then Rz(rotation).
Eigen::Isometry3d PlanarJoint::relativePose(const double* q, const JointParams&) {
  return pose(rotZ(q[2]), Vector3d(q[0], q[1], 0));
}

std::unique_ptr<Joint> PlanarJoint::make(const std::string& name, int bi, const JointFrame& fi,
                                         int bj, const JointFrame& fj, const JointParams&) {
  return std::make_unique<PlanarJoint>(name, bi, fi, bj, fj);
}

void PlanarJoint::equations(const JointGeometry& g, const BodyKin&, const BodyKin&,
                            const Tracked&, RowWriter& out) const {
  out.put(Cn2(g.bz_i, g.d));  // C(n2)(bz_i, d_ij) = 0 (8.13)        (1)
  putParallelAxes(g, out);    // C(p1)(bz_i, bz_j) = 0 (A8.1)        (2)
}

void PlanarJoint::coordinates(const BodyKin& ki, const BodyKin& kj, const Tracked& t, Row* out) const {
  const JointGeometry g = geometry(ki, kj, kBxI | kByI | kBxJ | kGap);
  out[0] = Cn2(g.bx_i, g.d);
  out[1] = Cn2(g.by_i, g.d);
  out[2] = relativeAngle(g.bx_i, g.by_i, g.bx_j, t[0]);
}

// Tree model: Rz(q2), t = (q0, q1, 0). The origin's velocity in frame j is
// Rz^T (q0_dot, q1_dot, 0), turning with q2: c = -q2_dot bz x (Rz^T (q0_dot, q1_dot, 0)).
namespace {
void planarCalc(const JointParams&, const double* q, const double* qd, Matrix3d& R, Vector3d& t, MotionSubspace& S,
                Vector6d& c) {
  const double c2 = std::cos(q[2]), s2 = std::sin(q[2]);
  R = rotZ(q[2]);
  t << q[0], q[1], 0;
  S(3, 0) = c2, S(4, 0) = -s2;
  S(3, 1) = s2, S(4, 1) = c2;
  S(2, 2) = 1;
  const double vx = c2 * qd[0] + s2 * qd[1], vy = -s2 * qd[0] + c2 * qd[1];
  c(3) = qd[2] * vy;
  c(4) = -qd[2] * vx;
}
}  // namespace

TreeJointModel PlanarJoint::treeModel() {
  TreeJointModel m;
  m.kind = TreeJointKind::kPlanar;
  m.nq = m.nv = 3;
  m.lengths = 3;
  m.calc = &planarCalc;
  return m;
}

}  // namespace mechanism_sim
