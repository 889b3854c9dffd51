#include "mechanism_sim/core/model/joints/prismatic.h"

namespace mechanism_sim {

// Pose of frame j in frame i: translation q0 along bz_i.
Eigen::Isometry3d PrismaticJoint::relativePose(const double* q, const JointParams&) {
  return pose(Matrix3d::Identity(), Vector3d(0, 0, q[0]));
}

std::unique_ptr<Joint> PrismaticJoint::make(const std::string& name, int bi,
                                            const JointFrame& fi, int bj, const JointFrame& fj,
                                            const JointParams&) {
  return std::make_unique<PrismaticJoint>(name, bi, fi, bj, fj);
}

// Seed table A8.1 (b).
void PrismaticJoint::equations(const JointGeometry& g, const BodyKin&, const BodyKin&,
                               const Tracked&, RowWriter& out) const {
  putParallelAxes(g, out);        // C(p1)(bz_i, bz_j) = 0 (A8.3)  (2)
  putOnAxis(g, out);              // C(p2)(bz_i, d_ij) = 0 (A8.4)  (2)
  // (A8.5) prints C(n1)(bx_i, bx_j) = 0. A dot product pins the rotation only between
  // vectors that are perpendicular when assembled; with the frames aligned at zero
  // those are by_i and bx_j, so this is C(n1)(by_i, bx_j) = 0 (sin of the twist).  (1)
  out.put(Cn1(g.by_i, g.bx_j));
}

void PrismaticJoint::coordinates(const BodyKin& ki, const BodyKin& kj, const Tracked&, Row* out) const {
  const JointGeometry g = geometry(ki, kj, kBzI | kGap);
  out[0] = Cn2(g.bz_i, g.d);
}

// Tree model: q0 along bz; S = (0; bz), constant.
namespace {
void prismaticCalc(const JointParams&, const double* q, const double*, Matrix3d&, Vector3d& t, MotionSubspace& S,
                   Vector6d&) {
  t.z() = q[0];
  S(5, 0) = 1;
}
}  // namespace

TreeJointModel PrismaticJoint::treeModel() {
  TreeJointModel m;
  m.kind = TreeJointKind::kPrismatic;
  m.nq = m.nv = 1;
  m.axis = AxisMotion::kSlide;
  m.lengths = 1;
  m.calc = &prismaticCalc;
  return m;
}

}  // namespace mechanism_sim
