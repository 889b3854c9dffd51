#include "mechanism_sim/core/joints/cylindrical.h"

namespace mechanism_sim {

std::unique_ptr<Joint> CylindricalJoint::make(const std::string& name, int bi,
                                              const JointFrame& fi, int bj,
                                              const JointFrame& fj, const JointParams&) {
  return std::make_unique<CylindricalJoint>(name, bi, fi, bj, fj);
}

// Seed table A8.1 (a).
void CylindricalJoint::equations(const JointGeometry& g, const BodyKin&, const BodyKin&,
                                 RowWriter& out) const {
  putParallelAxes(g, out);  // C(p1)(bz_i, bz_j)   = 0 (A8.1)  (2)
  putOnAxis(g, out);        // C(p2)(bz_i, d_ij)   = 0 (A8.2)  (2)
}

void CylindricalJoint::coordinates(const BodyKin& ki, const BodyKin& kj, Row* out) const {
  const JointGeometry g = geometry(ki, kj);
  out[0] = relativeAngle(g.bx_i, g.by_i, g.bx_j, tracked_[0]);
  out[1] = Cn2(g.bz_i, g.d);
}

void CylindricalJoint::acceptAngles(const BodyKin& ki, const BodyKin& kj) {
  const JointGeometry g = geometry(ki, kj);
  tracked_[0] = relativeAngle(g.bx_i, g.by_i, g.bx_j, tracked_[0]).Phi;
}

}  // namespace mechanism_sim
