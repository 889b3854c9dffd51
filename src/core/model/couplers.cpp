#include "mechanism_sim/core/model/couplers.h"

#include <algorithm>

namespace mechanism_sim {
namespace {

std::vector<int> unionOfBodies(const Joint& a, const Joint& b) {
  std::vector<int> bodies;
  for (int x : {a.bodyI(), a.bodyJ(), b.bodyI(), b.bodyJ()})
    if (std::find(bodies.begin(), bodies.end(), x) == bodies.end()) bodies.push_back(x);
  return bodies;
}

int slotOf(const std::vector<int>& bodies, int b) {
  return static_cast<int>(std::find(bodies.begin(), bodies.end(), b) - bodies.begin());
}

}  // namespace

CoordinateCoupler::CoordinateCoupler(const std::string& name, const Joint& a, int k_a,
                                     const Joint& b, int k_b, double multiplier, double offset)
    : Constraint(name, unionOfBodies(a, b)),
      a_(a), b_(b), k_a_(k_a), k_b_(k_b), multiplier_(multiplier), offset_(offset) {
  slot_a_ = {slotOf(bodies(), a.bodyI()), slotOf(bodies(), a.bodyJ())};
  slot_b_ = {slotOf(bodies(), b.bodyI()), slotOf(bodies(), b.bodyJ())};
}

void CoordinateCoupler::evaluate(const BodyKin* const* kin, const EvalContext& ctx,
                                 Eigen::Ref<Eigen::VectorXd> Phi,
                                 Eigen::Ref<Eigen::MatrixXd> J,
                                 Eigen::Ref<Eigen::VectorXd> gamma) const {
  std::array<Row, kMaxJointDofs> ra, rb;
  a_.coordinates(*kin[slot_a_[0]], *kin[slot_a_[1]], ctx.tracked[a_.id()], ra.data());
  b_.coordinates(*kin[slot_b_[0]], *kin[slot_b_[1]], ctx.tracked[b_.id()], rb.data());
  const Row& qa = ra[k_a_];
  const Row& qb = rb[k_b_];
  Phi(0) = qa.Phi - multiplier_ * qb.Phi - offset_;
  gamma(0) = qa.gamma - multiplier_ * qb.gamma;
  J.setZero();
  for (int s = 0; s < 2; ++s) {
    J.block<1, 6>(0, 6 * slot_a_[s]) += qa.J.segment<6>(6 * s);
    J.block<1, 6>(0, 6 * slot_b_[s]) -= multiplier_ * qb.J.segment<6>(6 * s);
  }
}

LimitConstraint::LimitConstraint(const std::string& name, std::vector<CouplingTerm> terms, int limit, double lower,
                                 double upper)
    : Constraint(name, bodiesOfTerms(terms)),
      terms_(std::move(terms)),
      slots_(termSlots(terms_, bodies())),
      limit_(limit),
      lower_(lower),
      upper_(upper) {}

void LimitConstraint::evaluate(const BodyKin* const* kin, const EvalContext& ctx,
                               Eigen::Ref<Eigen::VectorXd> Phi, Eigen::Ref<Eigen::MatrixXd> J,
                               Eigen::Ref<Eigen::VectorXd> gamma) const {
  J.setZero();
  const int side = ctx.limit_side[limit_];
  if (side == 0) {
    Phi(0) = 0.0;
    gamma(0) = 0.0;
    return;
  }
  // Phi = sum c_i q_i - the bound on the active side
  coordinateSum(terms_, slots_, kin, ctx, side < 0 ? lower_ : upper_, Phi(0), J, gamma(0));
}

}  // namespace mechanism_sim
