#pragma once
#include "mechanism_sim/core/model/joint.h"

namespace mechanism_sim {

// Prismatic (translational) joint (seed table A8.1 (b)): the cylindrical equations and
// C(n1)(by_i, bx_j) = 0 (5 equations). Coordinate: bz_i^T d_ij.
class PrismaticJoint : public Joint {
 public:
  using Joint::Joint;
  static std::unique_ptr<Joint> make(const std::string& name, int bi, const JointFrame& fi,
                                     int bj, const JointFrame& fj, const JointParams& params);
  static Eigen::Isometry3d relativePose(const double* q, const JointParams& params);
  static TreeJointModel treeModel();  // its joint-space tree calculation
  static constexpr const char* kType = "prismatic";
  static constexpr std::array<const char*, 1> kDofNames{{""}};
  std::string type() const override { return kType; }
  int size() const override { return 5; }
  unsigned equationAxes() const override { return kBxI | kByI | kBzJ | kBxJ | kGap; }
  int dof() const override { return static_cast<int>(kDofNames.size()); }
  bool holdsAxesParallel() const override { return true; }
  bool locksTwist() const override { return true; }
  void coordinates(const BodyKin& ki, const BodyKin& kj, const Tracked& t, Row* out) const override;

 protected:
  void equations(const JointGeometry& g, const BodyKin& ki, const BodyKin& kj,
                 const Tracked& t, RowWriter& out) const override;
};

}  // namespace mechanism_sim
