// A linear coupling among any number of joint coordinates (gear pairs, rack and pinion,
// belts, differentials, planetary trains): sum_i c_i q_i = c_0, one holonomic equation whose
// multiplier is the effort the mesh carries (doc/model_format.md, <mechanism_sim:coupling>).
#pragma once
#include <array>
#include <vector>

#include "mechanism_sim/core/model/joint.h"

namespace mechanism_sim {

// One term c q_k of a coupling: coordinate k of a joint, its coefficient c.
struct CouplingTerm {
  const Joint* joint = nullptr;
  int k = 0;
  double c = 0.0;
};

// A sum of joint coordinates, sum_i c_i q_i, as a constraint over the terms' bodies reads it
// (LinearCoupling's equation, LimitConstraint's on a sum):
// the terms' joints' bodies, each once, in the terms' order;
std::vector<int> bodiesOfTerms(const std::vector<CouplingTerm>& terms);
// per term, its joint's bodies i and j as places in `bodies`;
std::vector<std::array<int, 2>> termSlots(const std::vector<CouplingTerm>& terms, const std::vector<int>& bodies);
// Phi = sum_i c_i q_i - offset with each q_i a joint's coordinate row (Joint::coordinates at
// kin[slots]), its Jacobian row added to J (sum_i c_i q_x,i) and gamma = sum_i c_i gamma_i.
void coordinateSum(const std::vector<CouplingTerm>& terms, const std::vector<std::array<int, 2>>& slots,
                   const BodyKin* const* kin, const EvalContext& ctx, double offset, double& Phi,
                   Eigen::Ref<Eigen::MatrixXd> J, double& gamma);

// Phi = sum_i c_i q_i - c_0, with each q_i a joint's coordinate row (Joint::coordinates):
//   Phi_q = sum_i c_i q_x,i   (each on its joint's bodies i and j)
//   gamma = sum_i c_i gamma_i
// as CoordinateCoupler writes it for two terms. The multiplier lambda stands for an effort
// -c_i lambda along each q_i (coordinateEfforts): their power sum_i -c_i lambda q_dot_i =
// -lambda Phi_dot vanishes on the constraint, so the coupling neither makes nor takes
// energy. Its bodies are the union of the joints' (at most kMaxConstraintBodies).
class LinearCoupling : public Constraint {
 public:
  LinearCoupling(const std::string& name, std::vector<CouplingTerm> terms, double c0);
  std::string type() const override { return "coupling"; }
  int size() const override { return 1; }
  void evaluate(const BodyKin* const* kin, const EvalContext& ctx, Eigen::Ref<Eigen::VectorXd> Phi,
                Eigen::Ref<Eigen::MatrixXd> J, Eigen::Ref<Eigen::VectorXd> gamma) const override;
  const std::vector<CouplingTerm>& terms() const { return terms_; }
  double constant() const { return c0_; }
  // the joint among the terms whose body j is b
  const Joint* jointOn(int b) const override {
    for (const CouplingTerm& t : terms_)
      if (t.joint->bodyJ() == b) return t.joint;
    return nullptr;
  }
  // -c_i lambda along each q_i: the constraint force -Phi_q^T lambda
  int coordinateEfforts(const EvalContext& /*ctx*/, CoordinateEffort* out) const override {
    for (size_t i = 0; i < terms_.size(); ++i) out[i] = {terms_[i].joint, terms_[i].k, -terms_[i].c};
    return static_cast<int>(terms_.size());
  }

 private:
  std::vector<CouplingTerm> terms_;
  double c0_;
  std::vector<std::array<int, 2>> slots_;  // per term: its joint's bodies i and j in bodies()
};

}  // namespace mechanism_sim
