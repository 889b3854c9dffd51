// Mechanism: initial assembly, the mass check and the dependent-equation analysis.
#include <algorithm>
#include <cmath>
#include <map>
#include <sstream>

#include "mechanism_sim/core/mechanism.h"

namespace mechanism_sim {
namespace {

std::string fmt(double x) {
  std::ostringstream os;
  os.precision(3);
  os << x;
  return os.str();
}

}  // namespace

AssemblyReport Mechanism::assemble(const std::vector<CoordinateTarget>& positions,
                                   const std::vector<CoordinateTarget>& velocities) {
  if (!built_) build();
  auto checkTarget = [&](const CoordinateTarget& t, const char* what) {
    if (t.joint < 0 || t.joint >= numJoints() || t.k < 0 || t.k >= joints_[t.joint]->dof())
      throw ModelError(std::string("assembly: ") + what + " target names no joint coordinate");
    if (!std::isfinite(t.value))
      throw ModelError("joint '" + joints_[t.joint]->name() + "': initial " + what + " not finite");
  };
  for (const auto& t : positions) {
    checkTarget(t, "position");
    if (!joints_[t.joint]->holonomicCoordinates())
      throw ModelError("joint '" + joints_[t.joint]->name() + "': no position coordinate to set");
    const int slot = joints_[t.joint]->trackedSlot(t.k);
    Constraint& c = *constraints_[joint_constraint_[t.joint]];
    if (slot >= 0) {
      auto tr = c.tracked();
      tr[slot] = t.value;
      c.setTracked(tr);
    }
  }
  for (const auto& t : velocities) checkTarget(t, "velocity");
  for (size_t ci = 0; ci < constraints_.size(); ++ci) {
    bool seeded = false;
    for (const auto& t : positions) seeded = seeded || joint_constraint_[t.joint] == static_cast<int>(ci);
    if (!seeded) constraints_[ci]->accept(cdata_[ci].kin.data());
  }

  // A target row: coordinate k of a joint, placed in the joint's two body blocks.
  auto targetRow = [&](const CoordinateTarget& t) {
    std::array<Row, 3> rows;
    jointRows(t.joint, rows);
    return rows[t.k];
  };
  auto addRowToH = [&](const CoordinateTarget& t, const Row& row, double weight) {
    const Eigen::MatrixXd J = row.J;  // a joint coordinate's row spans the joint's two bodies
    addJtJ(cdata_[joint_constraint_[t.joint]], J, weight);
  };
  auto addRowT = [&](const CoordinateTarget& t, const Row& row, double x, double* out) {
    const int bs[2] = {joints_[t.joint]->bodyI(), joints_[t.joint]->bodyJ()};
    for (int s = 0; s < 2; ++s)
      if (bs[s] != kGround)
        for (int c = 0; c < 6; ++c) out[6 * (bs[s] - 1) + c] += row.J(6 * s + c) * x;
  };

  // ---- positions: Levenberg-Marquardt on [Phi; q_k - target]
  auto residual = [&](double* cost) {
    evaluateConstraints();
    double worst = maxAbs(Phi_, m_), sum = Phi_.head(m_).squaredNorm();
    for (const auto& t : positions) {
      const double r = targetRow(t).Phi - t.value;
      worst = std::max(worst, std::fabs(r));
      sum += r * r;
    }
    *cost = sum;
    return worst;
  };
  AssemblyReport report;
  double cost = 0, mu = 1e-6;
  double worst = residual(&cost);
  const double tol = options_.position_tol;
  Eigen::VectorXd saved;
  for (int it = 0; it < 300 && worst > tol; ++it) {
    report.iterations = it + 1;
    assembleH(1.0, mu, false);
    work_n_.setZero();
    for (int e = 0; e < m_; ++e) work_m_[e] = -Phi_[e];
    addJtx(work_m_.data(), work_n_.data());
    for (const auto& t : positions) {
      const Row row = targetRow(t);
      addRowToH(t, row, 1.0);
      addRowT(t, row, -(row.Phi - t.value), work_n_.data());
    }
    if (ldlt_.factorize(Hx_.data(), 1e-15, true) != 0) {
      mu *= 10;
      continue;
    }
    ldlt_.solve(work_n_.data());
    saved = x_;
    const auto tracked = snapshot().tracked;
    applyDisplacement(work_n_.data());
    for (size_t ci = 0; ci < constraints_.size(); ++ci) constraints_[ci]->accept(cdata_[ci].kin.data());
    double trial_cost = 0;
    const double trial_worst = residual(&trial_cost);
    if (trial_cost < cost) {
      cost = trial_cost;
      worst = trial_worst;
      mu = std::max(mu / 3.0, 1e-14);
    } else {
      x_ = saved;
      for (size_t ci = 0; ci < constraints_.size(); ++ci) constraints_[ci]->setTracked(tracked[ci]);
      loadKinematics(x_.data(), u_.data());
      worst = residual(&cost);
      mu *= 4.0;
      if (mu > 1e12) break;
    }
  }
  report.position_residual = worst;
  if (worst > std::max(tol, 1e-10)) {
    std::ostringstream os;
    os << "the mechanism does not close (largest residual " << fmt(worst) << "):";
    for (size_t ci = 0; ci < constraints_.size(); ++ci) {
      const ConstraintData& cd = cdata_[ci];
      const double r = maxAbs(Phi_.segment(cd.row, cd.size), cd.size);
      if (r > 1e-8) os << " '" << constraints_[ci]->name() << "' (" << fmt(r) << ")";
    }
    for (const auto& t : positions) {
      const double r = targetRow(t).Phi - t.value;
      if (std::fabs(r) > 1e-8)
        os << " initial position of '" << joints_[t.joint]->name() << "' (off by " << fmt(r) << ")";
    }
    throw ModelError(os.str());
  }

  checkMassRank();
  analyzeDependencies();

  // ---- velocities: mass-orthogonal projection onto Phi_q v = 0 and G_k v = target,
  // by the augmented Lagrangian, starting from the bodies' own velocities.
  evaluateConstraints();
  assembleH(alpha_, 0.0, true);
  std::vector<Row> rows;
  for (const auto& t : velocities) {
    rows.push_back(targetRow(t));
    addRowToH(t, rows.back(), alpha_);
  }
  factorH("assembly");
  Eigen::VectorXd Mu(n_), mu_c = Eigen::VectorXd::Zero(m_), Ju(m_);
  std::vector<double> mu_t(velocities.size(), 0.0);
  mulM(u_.data(), Mu.data());
  double vres = 0;
  for (int it = 0; it < 60; ++it) {
    mulJ(u_.data(), Ju.data());
    vres = maxAbs(Ju, m_);
    for (size_t t = 0; t < velocities.size(); ++t)
      vres = std::max(vres, std::fabs(rows[t].J.dot(rowVelocity(velocities[t])) - velocities[t].value));
    if (vres <= options_.velocity_tol) break;
    u_ = Mu;
    for (int e = 0; e < m_; ++e) work_m_[e] = -mu_c[e];
    addJtx(work_m_.data(), u_.data());
    for (size_t t = 0; t < velocities.size(); ++t)
      addRowT(velocities[t], rows[t], alpha_ * velocities[t].value - mu_t[t], u_.data());
    ldlt_.solve(u_.data());
    mulJ(u_.data(), Ju.data());
    for (int e = 0; e < m_; ++e) mu_c[e] += alpha_ * Ju[e];
    for (size_t t = 0; t < velocities.size(); ++t)
      mu_t[t] += alpha_ * (rows[t].J.dot(rowVelocity(velocities[t])) - velocities[t].value);
  }
  report.velocity_residual = vres;
  if (vres > 1e-9) {
    std::ostringstream os;
    os << "initial velocities cannot be met (largest residual " << fmt(vres) << ")";
    for (const auto& t : velocities) os << " '" << joints_[t.joint]->name() << "'";
    throw ModelError(os.str());
  }
  loadKinematics(x_.data(), u_.data());
  finishStep(false);
  return report;
}

// Twelve velocities of a target joint's two bodies, for G_k v.
Eigen::Matrix<double, 12, 1> Mechanism::rowVelocity(const CoordinateTarget& t) const {
  Eigen::Matrix<double, 12, 1> v = Eigen::Matrix<double, 12, 1>::Zero();
  const int bs[2] = {joints_[t.joint]->bodyI(), joints_[t.joint]->bodyJ()};
  for (int s = 0; s < 2; ++s)
    if (bs[s] != kGround) v.segment<6>(6 * s) = u_.segment<6>(6 * (bs[s] - 1));
  return v;
}

// M + alpha Phi_q^T Phi_q must be positive definite: every motion the joints allow moves
// some mass. A zero pivot names a body that can move without moving mass. The check uses
// alpha = the mean mass (well conditioned), so that a tiny but real inertia (1e-8 of the
// others) stays far above round-off (1e-16) and is not mistaken for none.
void Mechanism::checkMassRank() {
  evaluateConstraints();
  assembleH(alpha_ * 1e-6, 0.0, true);
  if (ldlt_.factorize(Hx_.data(), 1e-12, true) == 0) return;
  std::ostringstream os;
  os << "bodies that can move without moving any mass:";
  for (int b = 1; b < numBodies(); ++b) {
    bool zero = false;
    for (int r = 0; r < 6; ++r) zero = zero || ldlt_.zeroPivot(6 * (b - 1) + r);
    if (zero) os << " '" << bodies_[b].name << "'";
  }
  os << " (give them mass and inertia, or joints that fix every direction they can move in)";
  throw ModelError(os.str());
}

// Rank of Phi_q by LDL^T of the Gram matrix of its normalized rows, in constraint order,
// skipping zero pivots: row e is dependent when less than 1e-9 of its squared norm lies
// outside the span of the rows before it.
void Mechanism::analyzeDependencies() {
  evaluateConstraints();
  const int m = m_eq_;
  std::vector<std::vector<std::pair<int, int>>> at_body(numBodies());  // (constraint, slot)
  int nc = 0;
  for (size_t ci = 0; ci < constraints_.size(); ++ci) {
    if (cdata_[ci].row >= m) break;
    nc = static_cast<int>(ci) + 1;
    const auto& bs = constraints_[ci]->bodies();
    for (size_t k = 0; k < bs.size(); ++k)
      if (bs[k] != kGround) at_body[bs[k]].push_back({static_cast<int>(ci), static_cast<int>(k)});
  }
  std::vector<Eigen::MatrixXd> Jn(nc);
  for (int ci = 0; ci < nc; ++ci) {
    Jn[ci] = cdata_[ci].J;
    for (int e = 0; e < Jn[ci].rows(); ++e) {
      const double norm = Jn[ci].row(e).norm();
      if (norm > 1e-14) Jn[ci].row(e) /= norm; else Jn[ci].row(e).setZero();
    }
  }
  std::map<std::pair<int, int>, Eigen::MatrixXd> blocks;  // (c1, c2) -> Jn1 Jn2^T
  for (int b = 1; b < numBodies(); ++b)
    for (const auto& a : at_body[b])
      for (const auto& c : at_body[b]) {
        const Eigen::MatrixXd prod = Jn[a.first].middleCols<6>(6 * a.second) *
                                     Jn[c.first].middleCols<6>(6 * c.second).transpose();
        auto it = blocks.find({a.first, c.first});
        if (it == blocks.end()) blocks.emplace(std::make_pair(a.first, c.first), prod);
        else it->second += prod;
      }
  std::vector<std::vector<std::pair<int, double>>> cols(m);
  for (const auto& entry : blocks) {
    const int r0 = cdata_[entry.first.first].row, c0 = cdata_[entry.first.second].row;
    for (int i = 0; i < entry.second.rows(); ++i)
      for (int j = 0; j < entry.second.cols(); ++j) cols[c0 + j].push_back({r0 + i, entry.second(i, j)});
  }
  std::vector<int> Gp(m + 1, 0), Gi;
  std::vector<double> Gx;
  for (int j = 0; j < m; ++j) {
    std::sort(cols[j].begin(), cols[j].end());
    for (const auto& e : cols[j]) Gi.push_back(e.first), Gx.push_back(e.second);
    Gp[j + 1] = static_cast<int>(Gi.size());
  }
  SparseLDLT gram;
  gram.analyze(m, Gp, Gi, {});
  gram.factorize(Gx.data(), 1e-9, true);
  dependencies_ = DependencyReport();
  dependencies_.equations = m;
  for (int ci = 0; ci < nc; ++ci) {
    int count = 0;
    for (int e = 0; e < cdata_[ci].size; ++e) count += gram.zeroPivot(cdata_[ci].row + e);
    if (count) dependencies_.by_constraint.push_back({constraints_[ci]->name(), count});
    dependencies_.dependent += count;
  }
}

}  // namespace mechanism_sim
