// Constraints on joint coordinates: a linear coupling of two joints (URDF <mimic>) and a
// position limit (unilateral, active only while the joint presses on it).
#pragma once
#include <array>

#include "mechanism_sim/core/joint.h"

namespace mechanism_sim {

// q_a = multiplier * q_b + offset: Phi = q_a - multiplier q_b - offset, with
// Phi_q = G_a - multiplier G_b and gamma = gamma_a - multiplier gamma_b from the joints'
// coordinate rows (Joint::coordinates).
class CoordinateCoupler : public Constraint {
 public:
  CoordinateCoupler(const std::string& name, const Joint& a, int k_a, const Joint& b, int k_b,
                    double multiplier, double offset);
  std::string type() const override { return "coupler"; }
  int size() const override { return 1; }
  void evaluate(const BodyKin* const* kin, Eigen::Ref<Eigen::VectorXd> Phi,
                Eigen::Ref<Eigen::MatrixXd> J, Eigen::Ref<Eigen::VectorXd> gamma) const override;

 private:
  const Joint& a_;
  const Joint& b_;
  int k_a_, k_b_;
  double multiplier_, offset_;
  std::array<int, 2> slot_a_{}, slot_b_{};  // positions of each joint's bodies in bodies()
};

// While active: Phi = q - bound (one row); while inactive the row is zero.
class LimitConstraint : public Constraint {
 public:
  LimitConstraint(const Joint& joint, int k)
      : Constraint(joint.name() + " limit", {joint.bodyI(), joint.bodyJ()}), joint_(joint), k_(k) {}
  std::string type() const override { return "limit"; }
  int size() const override { return 1; }
  void setActive(bool active, double bound) { active_ = active, bound_ = bound; }
  bool active() const { return active_; }
  void evaluate(const BodyKin* const* kin, Eigen::Ref<Eigen::VectorXd> Phi,
                Eigen::Ref<Eigen::MatrixXd> J, Eigen::Ref<Eigen::VectorXd> gamma) const override;

 private:
  const Joint& joint_;
  int k_;
  bool active_ = false;
  double bound_ = 0.0;
};

}  // namespace mechanism_sim
