#include "mechanism_sim/core/model/coupling.h"

#include <algorithm>

namespace mechanism_sim {
std::vector<int> bodiesOfTerms(const std::vector<CouplingTerm>& terms) {
  std::vector<int> bodies;
  for (const CouplingTerm& t : terms)
    for (int x : {t.joint->bodyI(), t.joint->bodyJ()})
      if (std::find(bodies.begin(), bodies.end(), x) == bodies.end()) bodies.push_back(x);
  return bodies;
}

std::vector<std::array<int, 2>> termSlots(const std::vector<CouplingTerm>& terms, const std::vector<int>& bodies) {
  auto slotOf = [&](int b) { return static_cast<int>(std::find(bodies.begin(), bodies.end(), b) - bodies.begin()); };
  std::vector<std::array<int, 2>> slots;
  for (const CouplingTerm& t : terms) slots.push_back({slotOf(t.joint->bodyI()), slotOf(t.joint->bodyJ())});
  return slots;
}

void coordinateSum(const std::vector<CouplingTerm>& terms, const std::vector<std::array<int, 2>>& slots,
                   const BodyKin* const* kin, const EvalContext& ctx, double offset, double& Phi,
                   Eigen::Ref<Eigen::MatrixXd> J, double& gamma) {
  double phi = -offset, g = 0.0;
  std::array<Row, kMaxJointDofs> rows;
  for (size_t i = 0; i < terms.size(); ++i) {
    const CouplingTerm& t = terms[i];
    t.joint->coordinates(*kin[slots[i][0]], *kin[slots[i][1]], ctx.tracked[t.joint->id()], rows.data());
    const Row& q = rows[t.k];
    phi += t.c * q.Phi;
    g += t.c * q.gamma;
    for (int s = 0; s < 2; ++s) J.block<1, 6>(0, 6 * slots[i][s]) += t.c * q.J.segment<6>(6 * s);
  }
  Phi = phi;
  gamma = g;
}

LinearCoupling::LinearCoupling(const std::string& name, std::vector<CouplingTerm> terms, double c0)
    : Constraint(name, bodiesOfTerms(terms)), terms_(std::move(terms)), c0_(c0), slots_(termSlots(terms_, bodies())) {}

void LinearCoupling::evaluate(const BodyKin* const* kin, const EvalContext& ctx, Eigen::Ref<Eigen::VectorXd> Phi,
                              Eigen::Ref<Eigen::MatrixXd> J, Eigen::Ref<Eigen::VectorXd> gamma) const {
  J.setZero();
  coordinateSum(terms_, slots_, kin, ctx, c0_, Phi(0), J, gamma(0));
}

}  // namespace mechanism_sim
