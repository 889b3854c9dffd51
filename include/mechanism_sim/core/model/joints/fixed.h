#pragma once
#include "mechanism_sim/core/model/joint.h"

namespace mechanism_sim {

// Fixed joint: B_i = B_j, bz_i || bz_j and C(n1)(by_i, bx_j) = 0 (3 + 2 + 1 equations).
class FixedJoint : public Joint {
 public:
  using Joint::Joint;
  static std::unique_ptr<Joint> make(const std::string& name, int bi, const JointFrame& fi,
                                     int bj, const JointFrame& fj, const JointParams& params);
  static Eigen::Isometry3d relativePose(const double* q, const JointParams& params);
  static TreeJointModel treeModel();  // its joint-space tree calculation
  static constexpr const char* kType = "fixed";
  static constexpr std::array<const char*, 0> kDofNames{{}};
  std::string type() const override { return kType; }
  int size() const override { return 6; }
  unsigned equationAxes() const override { return kBxI | kByI | kBzJ | kBxJ | kGap; }
  int dof() const override { return static_cast<int>(kDofNames.size()); }
  bool holdsAxesParallel() const override { return true; }
  bool locksTwist() const override { return true; }
  void coordinates(const BodyKin&, const BodyKin&, const Tracked&, Row*) const override {}

 protected:
  void equations(const JointGeometry& g, const BodyKin& ki, const BodyKin& kj,
                 const Tracked& t, RowWriter& out) const override;
};

}  // namespace mechanism_sim
