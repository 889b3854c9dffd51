#pragma once
#include "mechanism_sim/core/model/joint.h"

namespace mechanism_sim {

// Screw joint (seed table A8.1 (c)): the cylindrical equations and
// C(sc) = bz_i^T d_ij - alpha (phi - phi0) = 0 (A8.8), 5 equations. alpha is the lead per
// radian; phi is tracked through any number of turns. Coordinate: phi.
class ScrewJoint : public Joint {
 public:
  ScrewJoint(const std::string& name, int bi, const JointFrame& fi, int bj,
             const JointFrame& fj, double alpha, double phi0)
      : Joint(name, bi, fi, bj, fj), alpha_(alpha), phi0_(phi0) {}
  Tracked initialTracked() const override { return Tracked{phi0_, 0.0}; }
  static std::unique_ptr<Joint> make(const std::string& name, int bi, const JointFrame& fi,
                                     int bj, const JointFrame& fj, const JointParams& params);
  static Eigen::Isometry3d relativePose(const double* q, const JointParams& params);
  static TreeJointModel treeModel();  // its joint-space tree calculation
  static constexpr const char* kType = "screw";
  static constexpr std::array<const char*, 1> kDofNames{{""}};
  std::string type() const override { return kType; }
  int size() const override { return 5; }
  unsigned equationAxes() const override { return kBxI | kByI | kBzI | kBxJ | kBzJ | kGap; }
  int trackedSlot(int k) const override { return k == 0 ? 0 : -1; }
  int dof() const override { return static_cast<int>(kDofNames.size()); }
  bool holdsAxesParallel() const override { return true; }
  bool locksTwist() const override { return true; }
  double alpha() const { return alpha_; }
  JointParams params() const override { return JointParams{alpha_, phi0_}; }
  void coordinates(const BodyKin& ki, const BodyKin& kj, const Tracked& t, Row* out) const override;
  void coordinateValues(const BodyKin& ki, const BodyKin& kj, const Tracked& t, double* q) const override {
    q[0] = relativeAngleValueOf(ki, kj, t[0]);  // (coordinates()' relativeAngle, its value alone)
  }

 protected:
  void equations(const JointGeometry& g, const BodyKin& ki, const BodyKin& kj,
                 const Tracked& t, RowWriter& out) const override;

 private:
  double alpha_, phi0_;
};

}  // namespace mechanism_sim
