#pragma once
#include "mechanism_sim/core/model/joint.h"

namespace mechanism_sim {

// Planar joint: B_j stays in the plane through B_i normal to bz_i, C(n2)(bz_i, d_ij) = 0,
// and bz_i || bz_j (1 + 2 equations). Coordinates "x" = bx_i^T d_ij, "y" = by_i^T d_ij and
// "rotation" about bz_i.
class PlanarJoint : public Joint {
 public:
  using Joint::Joint;
  static std::unique_ptr<Joint> make(const std::string& name, int bi, const JointFrame& fi,
                                     int bj, const JointFrame& fj, const JointParams& params);
  static Eigen::Isometry3d relativePose(const double* q, const JointParams& params);
  static TreeJointModel treeModel();  // its joint-space tree calculation
  static constexpr const char* kType = "planar";
  static constexpr std::array<const char*, 3> kDofNames{{"x", "y", "rotation"}};
  std::string type() const override { return kType; }
  bool planarTranslation() const override { return true; }
  int size() const override { return 3; }
  unsigned equationAxes() const override { return kBxI | kByI | kBzI | kBzJ | kGap; }
  int trackedSlot(int k) const override { return k == 2 ? 0 : -1; }
  int dof() const override { return static_cast<int>(kDofNames.size()); }
  bool holdsAxesParallel() const override { return true; }
  void coordinates(const BodyKin& ki, const BodyKin& kj, const Tracked& t, Row* out) const override;

 protected:
  void equations(const JointGeometry& g, const BodyKin& ki, const BodyKin& kj,
                 const Tracked& t, RowWriter& out) const override;

};

}  // namespace mechanism_sim
