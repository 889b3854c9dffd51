#pragma once
#include "mechanism_sim/core/model/joint.h"

namespace mechanism_sim {

// Universal (Cardan) joint: B_i = B_j and bx_i perpendicular to by_j (3 + 1 equations).
// Coordinates: "axis1", rotation about bx_i; "axis2", rotation about by_j; so that the
// relative orientation of the frames is Rx(axis1) Ry(axis2).
class UniversalJoint : public Joint {
 public:
  using Joint::Joint;
  static std::unique_ptr<Joint> make(const std::string& name, int bi, const JointFrame& fi,
                                     int bj, const JointFrame& fj, const JointParams& params);
  static Eigen::Isometry3d relativePose(const double* q, const JointParams& params);
  static TreeJointModel treeModel();  // its joint-space tree calculation
  static constexpr const char* kType = "universal";
  static constexpr std::array<const char*, 2> kDofNames{{"axis1", "axis2"}};
  std::string type() const override { return kType; }
  int size() const override { return 4; }
  unsigned equationAxes() const override { return kBxI | kByJ | kGap; }
  int trackedSlot(int k) const override { return k; }
  int dof() const override { return static_cast<int>(kDofNames.size()); }
  void coordinates(const BodyKin& ki, const BodyKin& kj, const Tracked& t, Row* out) const override;

 protected:
  void equations(const JointGeometry& g, const BodyKin& ki, const BodyKin& kj,
                 const Tracked& t, RowWriter& out) const override;

};

}  // namespace mechanism_sim
