// Constraints on joint coordinates: a linear coupling of two joints (URDF <mimic>) and a
// position limit (unilateral, active only while the joint presses on it).
#pragma once
#include <array>

#include "mechanism_sim/core/model/joint.h"

namespace mechanism_sim {

// q_a = multiplier * q_b + offset: Phi = q_a - multiplier q_b - offset, with
// Phi_q = q_x,a - multiplier q_x,b and gamma = gamma_a - multiplier gamma_b from the joints'
// coordinate rows (Joint::coordinates).
class CoordinateCoupler : public Constraint {
 public:
  CoordinateCoupler(const std::string& name, const Joint& a, int k_a, const Joint& b, int k_b,
                    double multiplier, double offset);
  std::string type() const override { return "coupler"; }
  int size() const override { return 1; }
  void evaluate(const BodyKin* const* kin, const EvalContext& ctx, Eigen::Ref<Eigen::VectorXd> Phi,
                Eigen::Ref<Eigen::MatrixXd> J, Eigen::Ref<Eigen::VectorXd> gamma) const override;
  const Joint& jointA() const { return a_; }
  const Joint& jointB() const { return b_; }
  int coordinateA() const { return k_a_; }
  int coordinateB() const { return k_b_; }
  double multiplier() const { return multiplier_; }
  double offset() const { return offset_; }
  // the joint (of the two) whose body j is b
  const Joint* jointOn(int b) const override {
    const Joint& on = b_.bodyJ() == b ? b_ : a_;
    return on.bodyJ() == b ? &on : nullptr;
  }
  // Phi = q_a - m q_b: efforts -lambda along q_a and m lambda along q_b
  int coordinateEfforts(const EvalContext& /*ctx*/, CoordinateEffort* out) const override {
    out[0] = {&a_, k_a_, -1.0};
    out[1] = {&b_, k_b_, multiplier_};
    return 2;
  }

 private:
  const Joint& a_;
  const Joint& b_;
  int k_a_, k_b_;
  double multiplier_, offset_;
  std::array<int, 2> slot_a_{}, slot_b_{};  // positions of each joint's bodies in bodies()
};

// Position limit lower <= q_k <= upper of a joint coordinate. Its side (State::limit_side,
// entry `limit`: -1 pressing on lower, +1 on upper, 0 free) decides the row: while active
// Phi = q_k - bound (one row), while free the row is zero.
class LimitConstraint : public Constraint {
 public:
  LimitConstraint(const Joint& joint, int k, int limit, double lower, double upper)
      : Constraint(joint.name() + " limit", {joint.bodyI(), joint.bodyJ()}),
        joint_(joint), k_(k), limit_(limit), lower_(lower), upper_(upper) {}
  std::string type() const override { return "limit"; }
  int size() const override { return 1; }
  int limit() const override { return limit_; }
  const Joint& joint() const { return joint_; }
  const Joint* jointOn(int b) const override { return joint_.jointOn(b); }
  // while active, -lambda along q_k
  int coordinateEfforts(const EvalContext& ctx, CoordinateEffort* out) const override {
    if (!ctx.limit_side[limit_]) return 0;
    out[0] = {&joint_, k_, -1.0};
    return 1;
  }
  void evaluate(const BodyKin* const* kin, const EvalContext& ctx, Eigen::Ref<Eigen::VectorXd> Phi,
                Eigen::Ref<Eigen::MatrixXd> J, Eigen::Ref<Eigen::VectorXd> gamma) const override;

 private:
  const Joint& joint_;
  int k_, limit_;
  double lower_, upper_;
};

}  // namespace mechanism_sim
