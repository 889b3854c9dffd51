#include "mechanism_sim/core/model/joints/screw.h"

#include <cmath>

#include "mechanism_sim/core/model/errors.h"

namespace mechanism_sim {

// Pose of frame j in frame i: Rz(phi), translation alpha (phi - phi0) along bz_i (A8.8).
Eigen::Isometry3d ScrewJoint::relativePose(const double* q, const JointParams& p) {
  return pose(rotZ(q[0]), Vector3d(0, 0, p.alpha * (q[0] - p.phi0)));
}

std::unique_ptr<Joint> ScrewJoint::make(const std::string& name, int bi, const JointFrame& fi,
                                        int bj, const JointFrame& fj, const JointParams& params) {
  // alpha = 0 is a revolute joint written as a screw (allowed here; the URDF loader
  // rejects a zero lead as a likely mistake).
  if (!std::isfinite(params.alpha) || !std::isfinite(params.phi0))
    throw ModelError("screw joint '" + name + "': lead must be finite");
  return std::make_unique<ScrewJoint>(name, bi, fi, bj, fj, params.alpha, params.phi0);
}

// Seed table A8.1 (c).
void ScrewJoint::equations(const JointGeometry& g, const BodyKin&, const BodyKin&,
                           const Tracked& t, RowWriter& out) const {
  putParallelAxes(g, out);  // C(p1)(bz_i, bz_j) = 0 (A8.6)  (2)
  putOnAxis(g, out);        // C(p2)(bz_i, d_ij) = 0 (A8.7)  (2)
  // C(sc) = bz_i^T d_ij - alpha (phi - phi0) = 0 (A8.8), phi counted through turns,
  // variation (A8.10) (with (7.38) for delta phi).                                   (1)
  out.put(Csc(g.bz_i, g.d, relativeAngle(g.bx_i, g.by_i, g.bx_j, t[0]), alpha_, phi0_));
}

void ScrewJoint::coordinates(const BodyKin& ki, const BodyKin& kj, const Tracked& t, Row* out) const {
  const JointGeometry g = geometry(ki, kj, kBxI | kByI | kBxJ);
  out[0] = relativeAngle(g.bx_i, g.by_i, g.bx_j, t[0]);
}

// Tree model: Rz(phi), alpha (phi - phi0) along bz (A8.8); S = (bz; alpha bz), constant.
namespace {
void screwCalc(const JointParams& params, const double* q, const double*, Matrix3d& R, Vector3d& t,
               MotionSubspace& S, Vector6d&) {
  R = rotZ(q[0]);
  t.z() = params.alpha * (q[0] - params.phi0);
  S(2, 0) = 1;
  S(5, 0) = params.alpha;
}
}  // namespace

TreeJointModel ScrewJoint::treeModel() {
  TreeJointModel m;
  m.kind = TreeJointKind::kScrew;
  m.nq = m.nv = 1;
  m.axis = AxisMotion::kHelix;
  m.calc = &screwCalc;
  return m;
}

}  // namespace mechanism_sim
