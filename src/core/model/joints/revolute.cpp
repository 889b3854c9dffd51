#include "mechanism_sim/core/model/joints/revolute.h"

namespace mechanism_sim {

// Pose of frame j in frame i: Rz(q0).
Eigen::Isometry3d RevoluteJoint::relativePose(const double* q, const JointParams&) {
  return pose(rotZ(q[0]), Vector3d::Zero());
}

std::unique_ptr<Joint> RevoluteJoint::make(const std::string& name, int bi, const JointFrame& fi,
                                           int bj, const JointFrame& fj, const JointParams&) {
  return std::make_unique<RevoluteJoint>(name, bi, fi, bj, fj);
}

void RevoluteJoint::equations(const JointGeometry& g, const BodyKin&, const BodyKin&,
                              const Tracked&, RowWriter& out) const {
  putPoint(g, out);          // d_ij = 0                      (3)
  putParallelAxes(g, out);   // C(p1)(bz_i, bz_j) = 0 (A8.1)  (2)
}

void RevoluteJoint::coordinates(const BodyKin& ki, const BodyKin& kj, const Tracked& t, Row* out) const {
  const JointGeometry g = geometry(ki, kj, kBxI | kByI | kBxJ);
  out[0] = relativeAngle(g.bx_i, g.by_i, g.bx_j, t[0]);
}

// Tree model: Rz(q0); S = (bz; 0), constant.
namespace {
void revoluteCalc(const JointParams&, const double* q, const double*, Matrix3d& R, Vector3d&, MotionSubspace& S,
                  Vector6d&) {
  R = rotZ(q[0]);
  S(2, 0) = 1;
}
}  // namespace

TreeJointModel RevoluteJoint::treeModel() {
  TreeJointModel m;
  m.kind = TreeJointKind::kRevolute;
  m.nq = m.nv = 1;
  m.axis = AxisMotion::kTurn;
  m.free_turns = 1;
  m.calc = &revoluteCalc;
  return m;
}

}  // namespace mechanism_sim
