#pragma once
#include "mechanism_sim/core/model/joint.h"

namespace mechanism_sim {

// Cylindrical joint (seed table A8.1 (a)): bz_i || bz_j and bz_i || d_ij (2 + 2
// equations). Coordinates: "rotation" (as the revolute) and "translation" bz_i^T d_ij.
class CylindricalJoint : public Joint {
 public:
  using Joint::Joint;
  static std::unique_ptr<Joint> make(const std::string& name, int bi, const JointFrame& fi,
                                     int bj, const JointFrame& fj, const JointParams& params);
  static Eigen::Isometry3d relativePose(const double* q, const JointParams& params);
  static TreeJointModel treeModel();  // its joint-space tree calculation
  static constexpr const char* kType = "cylindrical";
  static constexpr std::array<const char*, 2> kDofNames{{"rotation", "translation"}};
  std::string type() const override { return kType; }
  int size() const override { return 4; }
  unsigned equationAxes() const override { return kBxI | kByI | kBzJ | kGap; }
  int trackedSlot(int k) const override { return k == 0 ? 0 : -1; }
  int dof() const override { return static_cast<int>(kDofNames.size()); }
  bool holdsAxesParallel() const override { return true; }
  void coordinates(const BodyKin& ki, const BodyKin& kj, const Tracked& t, Row* out) const override;

 protected:
  void equations(const JointGeometry& g, const BodyKin& ki, const BodyKin& kj,
                 const Tracked& t, RowWriter& out) const override;

};

}  // namespace mechanism_sim
