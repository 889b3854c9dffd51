// Branch passages of loop closures in joint coordinates (loop_closure.h, "branch
// passages").
//
// Why. A parallelogram four-bar passing flat is where its branch (the parallelogram)
// crosses another (the folded anti-parallelogram). With x the coordinate along the motion
// and y the one across it, the loop's equation there is locally Phi = x y (the seed's point
// coincidence C(p) between coupler and rocker, expanded at the flat pose: (b^2 - a^2 - c^2)/2
// with the cranks at pi/2 + a, pi/2 + b and the coupler at c, on the other row c = a - b),
// and its row of G = Phi_x J(q) is (y, x): it vanishes at the crossing. Evaluated in floating
// point Phi carries a round-off of eps times its terms, so at a distance x the equations
// determine y only to eps / x, y_dot (velocity projection, G q_dot = 0) to eps / x^2 and
// y_ddot (the acceleration solve, y_ddot = -(x_ddot y + 2 x_dot y_dot) / x) to eps / x^3.
// An RK stage that lands near the crossing turns that into motion, and smaller steps land
// closer: the error at 0.1 ms was larger than at 1 ms.
//
// What. The branch is smooth through the crossing, and so is the motion across it: near
// the crossing y is carried by the integration, not by the equations. The rows of G are
// normalized by the size of their terms, with rates as speeds (W = D_r G C, D_r = 1/|row of
// Gbound C| (norms of the entries' parts, which do not vanish with the geometry), C = diag(1/unit): a singular value of W is a relative measure, the same in
// millimetres as in metres), and decomposed W = U S V^T. A direction i is
//   regular    s_i >= kPassageBand:   v_i^T C a = u_i^T D_r gamma_q / s_i (the equations),
//   in passage kPassageDependent <= s_i < kPassageBand:
//                                     v_i^T C a = v_i^T C a_ref (held: the acceleration across
//                                     the branch at the step's start, continuous along it),
//   dependent  s_i < kPassageDependent: dropped (a planar loop's out-of-plane rows).
// With R the rows v_i^T C of the kept directions, a = a_free - M^-1 R^T mu,
// (R M^-1 R^T) mu = R a_free - g (RBDA 8.3 on the reduced rows). The constraint force stays
// along G^T (R^T = C V, G^T = C V S U^T D_r^-1), and lambda = D_r U S^-1 mu per closure row.
// The projections keep the regular directions' equations and leave the held ones as the
// integration carried them (rows with zero right-hand side). Once out of the passage
// (s >= kPassageBand, about 1e-2 rad from the crossing) the ordinary solves and projections
// take over; their round-off error there is eps / 1e-6 in rate, and what the passage left
// across the branch is projected away, M-orthogonally, as the constraint force would have.
#include <algorithm>
#include <cmath>

#include <Eigen/Eigenvalues>

#include "mechanism_sim/core/evaluation.h"
#include "mechanism_sim/core/loop_closure.h"

namespace mechanism_sim {

int LoopClosures::findPassage() {
  p_band_ = 0;
  p_near_ = false;
  if (m == 0) return 0;
  if (p_W_.rows() != m || p_W_.cols() != nv) {
    p_row_.assign(m, 0);
    p_dr_.setZero(m), p_b_.setZero(m), p_scale_.setZero(m);
    p_W_.setZero(m, nv);
  }
  p_kept_ = 0;
  for (int e = 0; e < m; ++e) {
    bool zero = true;
    double n2 = 0.0;
    for (int k = 0; k < nv; ++k) {
      if (std::fabs(G(e, k)) > kClosureZeroEntry * Gabs(e, k)) zero = false;
      const double t = Gbound(e, k) / unit_(k);
      n2 += t * t;
    }
    if (zero || !(n2 > 0.0)) continue;
    const double dr = 1.0 / std::sqrt(n2);
    p_row_[p_kept_] = e;
    p_dr_(p_kept_) = dr;
    for (int k = 0; k < nv; ++k) p_W_(p_kept_, k) = G(e, k) / unit_(k) * dr;
    ++p_kept_;
  }
  if (p_kept_ == 0) return 0;
  if (!passageNearAnyClosure()) return 0;
  p_svd_.compute(p_W_.topRows(p_kept_), Eigen::ComputeThinU | Eigen::ComputeThinV);
  p_sigma_ = p_svd_.singularValues();  // descending
  p_U_ = p_svd_.matrixU();
  p_V_ = p_svd_.matrixV();
  p_regular_ = 0;
  for (Eigen::Index i = 0; i < p_sigma_.size(); ++i) {
    if (p_sigma_(i) >= kPassageBand) ++p_regular_;
    else if (p_sigma_(i) >= kPassageDependent) ++p_band_;
    if (p_sigma_(i) >= kPassageDependent && p_sigma_(i) < kPassageNear) p_near_ = true;
  }
  if (p_band_ > 0) ++p_met_;
  return p_band_;
}

// The gate: the decomposition of W is dense (kept rows x nv), so it is taken only where some
// closure's own rows are near a loss of rank. Each closure's normalized rows give a small Gram
// matrix W_c W_c^T (at most 6 x 6); its smallest eigenvalue is s_c^2 to round-off eps, so
// s_c is resolved only down to about 1e-8, and a stage can land closer than that to the
// crossing: any s_c below kGate opens the gate (a closure with structurally dependent rows
// that are not zero, then, always does). A passage where rows of different
// closures become dependent on each other, each closure's rows staying independent, does
// not open it (the ordinary least-norm solve takes it, as before passages were handled).
bool LoopClosures::passageNearAnyClosure() {
  constexpr double kGate = 3 * kPassageNear;
  for (size_t c = 0; c < constraints.size(); ++c) {
    const int n = sys_->constraints[constraints[c]]->size();
    if (n < 2 || direct_[c].n > 0) continue;  // one row has no rank to lose to another
    int k = 0;
    for (int e = row[c]; e < row[c] + n && k < 6; ++e) {
      int j = -1;
      for (int i = 0; i < p_kept_; ++i)
        if (p_row_[i] == e) j = i;
      if (j >= 0) p_gate_rows_[k++] = j;
    }
    if (k < 2) continue;
    Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, 6, 6> K(k, k);
    for (int a = 0; a < k; ++a)
      for (int b = 0; b <= a; ++b) K(a, b) = K(b, a) = p_W_.row(p_gate_rows_[a]).dot(p_W_.row(p_gate_rows_[b]));
    Eigen::SelfAdjointEigenSolver<decltype(K)> eig(K, Eigen::EigenvaluesOnly);
    for (int i = 0; i < k; ++i) {
      const double s = std::sqrt(std::max(0.0, eig.eigenvalues()(i)));
      if (s < kGate) return true;
    }
  }
  return false;
}

void LoopClosures::passageFactor(const TreeModel& model, const TreeWorkspace& ws) {
  const int r = p_regular_ + p_band_;
  p_R_.resize(r, nv);
  for (int i = 0; i < r; ++i) p_R_.row(i) = p_V_.col(i).cwiseProduct(unit_).transpose();
  p_Y_.resize(nv, r);
  for (int i = 0; i < r; ++i) {
    tau_ = p_R_.row(i).transpose();
    applyInverseMass(model, ws, tau_.data(), p_Y_.col(i).data());
  }
  p_A_.noalias() = p_R_ * p_Y_;
  p_ldlt_.compute(p_A_);
}

void LoopClosures::passageRhs(const Eigen::VectorXd& b, Eigen::VectorXd& rhs) const {
  const int r = p_regular_ + p_band_;
  rhs.setZero(r);
  for (int i = 0; i < p_regular_; ++i) {
    double s = 0.0;
    for (int j = 0; j < p_kept_; ++j) s += p_U_(j, i) * p_dr_(j) * b(p_row_[j]);
    rhs(i) = s / p_sigma_(i);
  }
}

double LoopClosures::passageResidual(const Eigen::VectorXd& b, const Eigen::VectorXd& scale_e) {
  // b' = b - D_r^-1 U_band U_band^T D_r b on the kept rows (dropped rows are round-off)
  Eigen::VectorXd& bp = p_b_;
  bp = b;
  for (int i = p_regular_; i < p_regular_ + p_band_; ++i) {
    double c = 0.0;
    for (int j = 0; j < p_kept_; ++j) c += p_U_(j, i) * p_dr_(j) * b(p_row_[j]);
    for (int j = 0; j < p_kept_; ++j) bp(p_row_[j]) -= p_U_(j, i) * c / p_dr_(j);
  }
  double worst = 0.0;
  for (int e = 0; e < m; ++e) worst = std::max(worst, relative(bp(e), scale_e(e)));
  return worst;
}

}  // namespace mechanism_sim
