#include "mechanism_sim/core/model/joints/planar.h"

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


}  // namespace mechanism_sim
