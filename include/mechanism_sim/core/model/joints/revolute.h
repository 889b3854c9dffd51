#pragma once
#include "mechanism_sim/core/model/joint.h"

namespace mechanism_sim {

// Revolute joint: B_i = B_j and bz_i || bz_j (3 + 2 equations); coordinate: the angle
// of bx_j from bx_i about bz_i, counted through any number of turns.
class RevoluteJoint : public Joint {
 public:
  using Joint::Joint;
  static std::unique_ptr<Joint> make(const std::string& name, int bi, const JointFrame& fi,
                                     int bj, const JointFrame& fj, const JointParams& params);
  static Eigen::Isometry3d relativePose(const double* q, const JointParams& params);
  static TreeJointModel treeModel();  // its joint-space tree calculation
  static constexpr const char* kType = "revolute";
  static constexpr std::array<const char*, 1> kDofNames{{""}};
  std::string type() const override { return kType; }
  int size() const override { return 5; }
  unsigned equationAxes() const override { return kBxI | kByI | kBzJ | kGap; }
  // rows 0-2 the point (d), 3-4 the parallel axes (bx_i, by_i, bz_j)
  unsigned equationAxesFor(unsigned rows) const override {
    return ((rows & 0x7u) ? kGap : 0u) | ((rows & 0x18u) ? (kBxI | kByI | kBzJ) : 0u);
  }
  int trackedSlot(int k) const override { return k == 0 ? 0 : -1; }
  int dof() const override { return static_cast<int>(kDofNames.size()); }
  bool holdsAxesParallel() const override { return true; }
  void coordinates(const BodyKin& ki, const BodyKin& kj, const Tracked& t, Row* out) const override;
  void coordinateValues(const BodyKin& ki, const BodyKin& kj, const Tracked& t, double* q) const override {
    q[0] = relativeAngleValueOf(ki, kj, t[0]);  // (coordinates()' relativeAngle, its value alone)
  }

 protected:
  void equations(const JointGeometry& g, const BodyKin& ki, const BodyKin& kj,
                 const Tracked& t, RowWriter& out) const override;

};

}  // namespace mechanism_sim
