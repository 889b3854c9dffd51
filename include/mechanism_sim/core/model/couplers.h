// Constraints on joint coordinates: a linear coupling of two joints (URDF <mimic>) and a
// position limit (unilateral, active only while the joint presses on it).
#pragma once
#include <array>

#include <vector>

#include "mechanism_sim/core/model/coupling.h"
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

// Position limit lower <= s <= upper on s = sum_i c_i q_i, a linear combination of joint
// coordinates (one coordinate q_k with c = 1: a joint's limit; a coupling's terms: its
// backlash, coupling.h). Its side (State::limit_side, entry `limit`: -1 pressing on lower,
// +1 on upper, 0 free) decides the row: while active Phi = s - bound with Phi_q =
// sum_i c_i q_x,i and gamma = sum_i c_i gamma_i (one row, as LinearCoupling's), while free
// the row is zero. Its bodies are the union of the joints'.
class LimitConstraint : public Constraint {
 public:
  LimitConstraint(const std::string& name, std::vector<CouplingTerm> terms, int limit, double lower, double upper);
  LimitConstraint(const Joint& joint, int k, int limit, double lower, double upper)
      : LimitConstraint(joint.name() + " limit", {{&joint, k, 1.0}}, limit, lower, upper) {}
  std::string type() const override { return "limit"; }
  int size() const override { return 1; }
  int limit() const override { return limit_; }
  // the (first) limited joint
  const Joint& joint() const { return *terms_[0].joint; }
  const std::vector<CouplingTerm>& terms() const { return terms_; }
  const Joint* jointOn(int b) const override {
    for (const CouplingTerm& t : terms_)
      if (const Joint* on = t.joint->jointOn(b)) return on;
    return nullptr;
  }
  // while active, -c_i lambda along each q_i
  int coordinateEfforts(const EvalContext& ctx, CoordinateEffort* out) const override {
    if (!ctx.limit_side[limit_]) return 0;
    for (size_t i = 0; i < terms_.size(); ++i) out[i] = {terms_[i].joint, terms_[i].k, -terms_[i].c};
    return static_cast<int>(terms_.size());
  }
  void evaluate(const BodyKin* const* kin, const EvalContext& ctx, Eigen::Ref<Eigen::VectorXd> Phi,
                Eigen::Ref<Eigen::MatrixXd> J, Eigen::Ref<Eigen::VectorXd> gamma) const override;

 private:
  std::vector<CouplingTerm> terms_;
  std::vector<std::array<int, 2>> slots_;  // per term: its joint's bodies i and j in bodies()
  int limit_;
  double lower_, upper_;
};

}  // namespace mechanism_sim
