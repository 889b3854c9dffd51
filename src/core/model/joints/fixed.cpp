#include "mechanism_sim/core/model/joints/fixed.h"

namespace mechanism_sim {

// Pose of frame j in frame i: identity.
Eigen::Isometry3d FixedJoint::relativePose(const double* , const JointParams&) {
  return Eigen::Isometry3d::Identity();
}

std::unique_ptr<Joint> FixedJoint::make(const std::string& name, int bi, const JointFrame& fi,
                                        int bj, const JointFrame& fj, const JointParams&) {
  return std::make_unique<FixedJoint>(name, bi, fi, bj, fj);
}

void FixedJoint::equations(const JointGeometry& g, const BodyKin&, const BodyKin&,
                           const Tracked&, RowWriter& out) const {
  putPoint(g, out);              // d_ij = 0                          (3)
  putParallelAxes(g, out);       // C(p1)(bz_i, bz_j) = 0 (A8.1)      (2)
  out.put(Cn1(g.by_i, g.bx_j));  // C(n1)(by_i, bx_j) = 0, as (A8.5)  (1)
}

// Tree model: no coordinate; the tree welds the two bodies (frames coincident).
namespace {
void fixedCalc(const JointParams&, const double*, const double*, Matrix3d&, Vector3d&, MotionSubspace&, Vector6d&) {}
}  // namespace

TreeJointModel FixedJoint::treeModel() {
  TreeJointModel m;
  m.kind = TreeJointKind::kFixed;
  m.calc = &fixedCalc;
  return m;
}

}  // namespace mechanism_sim
