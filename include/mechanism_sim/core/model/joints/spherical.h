#pragma once
#include "mechanism_sim/core/model/joint.h"

namespace mechanism_sim {

// Spherical joint: B_i and B_j coincide (3 equations). Its three rates are the
// relative angular velocity of j in frame i; its positions the rotation vector of frame j
// relative to frame i.
class SphericalJoint : public Joint {
 public:
  using Joint::Joint;
  static std::unique_ptr<Joint> make(const std::string& name, int bi, const JointFrame& fi,
                                     int bj, const JointFrame& fj, const JointParams& params);
  static Eigen::Isometry3d relativePose(const double* q, const JointParams& params);
  static TreeJointModel treeModel();  // its joint-space tree calculation
  static constexpr const char* kType = "spherical";
  static constexpr std::array<const char*, 3> kDofNames{{"x", "y", "z"}};
  std::string type() const override { return kType; }
  int size() const override { return 3; }
  unsigned equationAxes() const override { return kGap; }
  int dof() const override { return static_cast<int>(kDofNames.size()); }
  bool holonomicCoordinates() const override { return false; }
  void coordinates(const BodyKin& ki, const BodyKin& kj, const Tracked& t, Row* out) const override;
  void treePositions(const BodyKin& ki, const BodyKin& kj, const Tracked& t, double* q) const override;

 protected:
  void equations(const JointGeometry& g, const BodyKin& ki, const BodyKin& kj,
                 const Tracked& t, RowWriter& out) const override;
};

}  // namespace mechanism_sim
