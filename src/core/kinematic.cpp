#include "mechanism_sim/core/kinematic.h"

#include <Eigen/Core>

#include "core/absolute/evaluation.h"

namespace mechanism_sim {

std::vector<char> independentCoordinates(const System& described, const std::vector<std::pair<int, int>>& candidates) {
  System sys = described;
  sys.finalize();
  const State s = initialState(sys);
  Evaluation ev(sys);
  evaluateAt(sys, s, ev, false);
  const int n = sys.n;
  const double L = sys.length_scale;
  auto scaled = [&](Eigen::VectorXd r) {
    for (int b = 0; b < sys.nb; ++b) r.segment<3>(BodyCoordinates::u(b) + 3) /= L;
    return r;
  };
  std::vector<Eigen::VectorXd> basis;
  auto join = [&](const Eigen::VectorXd& v, double tol) {
    Eigen::VectorXd w = v;
    for (int pass = 0; pass < 2; ++pass)
      for (const Eigen::VectorXd& q : basis) w -= q.dot(w) * q;
    if (!(w.norm() > tol * v.norm())) return false;
    basis.push_back(w.normalized());
    return true;
  };
  // the equality equations' rows (Phi_q^T e for each row e)
  Eigen::VectorXd y = Eigen::VectorXd::Zero(sys.m), r(n);
  for (int c = 0; c < sys.numConstraints(); ++c) {
    if (sys.constraints[c]->limit() >= 0) continue;
    const ConstraintLayout& lay = sys.layout[c];
    for (int e = 0; e < lay.size; ++e) {
      y[lay.row + e] = 1.0;
      r.setZero();
      addJt(sys, ev, {c}, y.data(), r.data());
      y[lay.row + e] = 0.0;
      if (r.norm() > 0) join(scaled(r), 1e-10);
    }
  }
  std::vector<char> out(candidates.size(), 0);
  Row rows[kMaxJointDofs];
  for (size_t i = 0; i < candidates.size(); ++i) {
    const auto [joint, k] = candidates[i];
    if (joint < 0 || joint >= sys.numJoints() || k < 0 || k >= sys.joints[joint]->dof() ||
        !sys.joints[joint]->holonomicCoordinates())
      continue;
    jointRows(sys, ev, s, joint, rows);
    r.setZero();
    scatterRow(sys, joint, rows[k], 1.0, r.data());
    out[i] = r.norm() > 0 && join(scaled(r), 1e-8);
  }
  return out;
}

}  // namespace mechanism_sim
