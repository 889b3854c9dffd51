#include "mechanism_sim/core/model/coupling.h"

#include <algorithm>

namespace mechanism_sim {
namespace {

std::vector<int> unionOfBodies(const std::vector<CouplingTerm>& terms) {
  std::vector<int> bodies;
  for (const CouplingTerm& t : terms)
    for (int x : {t.joint->bodyI(), t.joint->bodyJ()})
      if (std::find(bodies.begin(), bodies.end(), x) == bodies.end()) bodies.push_back(x);
  return bodies;
}

int slotOf(const std::vector<int>& bodies, int b) {
  return static_cast<int>(std::find(bodies.begin(), bodies.end(), b) - bodies.begin());
}

}  // namespace

LinearCoupling::LinearCoupling(const std::string& name, std::vector<CouplingTerm> terms, double c0)
    : Constraint(name, unionOfBodies(terms)), terms_(std::move(terms)), c0_(c0) {
  for (const CouplingTerm& t : terms_)
    slots_.push_back({slotOf(bodies(), t.joint->bodyI()), slotOf(bodies(), t.joint->bodyJ())});
}

void LinearCoupling::evaluate(const BodyKin* const* kin, const EvalContext& ctx, Eigen::Ref<Eigen::VectorXd> Phi,
                              Eigen::Ref<Eigen::MatrixXd> J, Eigen::Ref<Eigen::VectorXd> gamma) const {
  // Phi = sum c_i q_i - c_0, Phi_q = sum c_i q_x,i, gamma = sum c_i gamma_i
  J.setZero();
  double phi = -c0_, g = 0.0;
  std::array<Row, kMaxJointDofs> rows;
  for (size_t i = 0; i < terms_.size(); ++i) {
    const CouplingTerm& t = terms_[i];
    t.joint->coordinates(*kin[slots_[i][0]], *kin[slots_[i][1]], ctx.tracked[t.joint->id()], rows.data());
    const Row& q = rows[t.k];
    phi += t.c * q.Phi;
    g += t.c * q.gamma;
    for (int s = 0; s < 2; ++s) J.block<1, 6>(0, 6 * slots_[i][s]) += t.c * q.J.segment<6>(6 * s);
  }
  Phi(0) = phi;
  gamma(0) = g;
}

}  // namespace mechanism_sim
