#include "core/linalg/scaled_least_norm.h"

#include <algorithm>

namespace mechanism_sim {

ScaledLeastNorm::ScaledLeastNorm(int n)
    : d_(Eigen::VectorXd::Zero(n)), c_(Eigen::VectorXd::Zero(n)), y_(Eigen::VectorXd::Zero(n)),
      work_(Eigen::VectorXd::Zero(std::max(n, 1))), work2_(Eigen::VectorXd::Zero(n)), sub_(Eigen::MatrixXd::Zero(n, n)),
      cod_(n, n) {
  cod_.setThreshold(kClosureRankThreshold);
  compact_cod_.setThreshold(kClosureRankThreshold);
  small_cod_.setThreshold(kClosureRankThreshold);
  kept_all_.reserve(n);
}

int ScaledLeastNorm::factor(Eigen::MatrixXd& A, const Eigen::VectorXd* keep) {
  const Eigen::Index n = d_.size();
  int kept = 0;
  kept_all_.clear();
  for (Eigen::Index e = 0; e < n; ++e) {
    d_(e) = ((!keep || (*keep)(e) > 0) && A(e, e) > 0) ? 1.0 / std::sqrt(A(e, e)) : 0.0;
    if (d_(e) != 0.0) {
      if (kept < kSmall) kept_rows_[kept] = static_cast<int>(e);
      kept_all_.push_back(static_cast<int>(e));
      ++kept;
    }
  }
  small_ = kept <= kSmall;  // (every row kept too: fixed-capacity storage, no dynamic-size overhead)
  compact_ = !small_ && kept < n;
  kept_ = kept;
  if (small_) {  // the kept rows alone (dropped ones: x_e = 0, each counted with rank 1 as below)
    SmallMatrix S(kept, kept);
    for (int i = 0; i < kept; ++i)
      for (int j = 0; j < kept; ++j)
        S(i, j) = A(kept_rows_[i], kept_rows_[j]) * d_(kept_rows_[i]) * d_(kept_rows_[j]);
    if (kept > 0) small_cod_.compute(S);
    return static_cast<int>(n - kept) + (kept > 0 ? static_cast<int>(small_cod_.rank()) : 0);
  }
  if (compact_) {  // more kept rows, still not all (a planar loop's zero rows): those alone
    for (int i = 0; i < kept; ++i)
      for (int j = 0; j < kept; ++j)
        sub_(i, j) = A(kept_all_[i], kept_all_[j]) * d_(kept_all_[i]) * d_(kept_all_[j]);
    compact_cod_.compute(sub_.topLeftCorner(kept, kept));
    return static_cast<int>(n - kept) + static_cast<int>(compact_cod_.rank());
  }
  for (Eigen::Index i = 0; i < n; ++i)
    for (Eigen::Index j = 0; j < n; ++j) A(i, j) *= d_(i) * d_(j);
  cod_.compute(A);
  return static_cast<int>(cod_.rank());
}

// The least-norm solution of the scaled system by the complete orthogonal decomposition
// A P = Q [T 0; 0 0] Z: x = P Z^T [T^-1 (Q^T b)_1..r; 0], written out on the decomposition's
// factors (as Eigen's CompleteOrthogonalDecomposition::solve does, whose temporaries
// allocate: 5 heap allocations a call) with preallocated vectors: no allocation. c (size
// nn, overwritten) holds the scaled right-hand side, y is scratch, out gets y permuted.
void ScaledLeastNorm::codSolve(const Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd>& cod,
                               Eigen::Ref<Eigen::VectorXd> c, Eigen::Ref<Eigen::VectorXd> y,
                               Eigen::Ref<Eigen::VectorXd> out) const {
  const Eigen::Index n = c.size();
  double* work = work_.data();
  const Eigen::Index r = cod.rank();
  const Eigen::MatrixXd& QTZ = cod.matrixQTZ();
  if (r == 0) {
    out.setZero();
    return;
  }
  // c = Q^T c: the first r reflectors H_0 ... H_{r-1} (H_k = I - h_k v_k v_k^T, v_k = (1, QTZ(k+1:, k)))
  for (Eigen::Index k = 0; k < r; ++k)
    c.tail(n - k).applyHouseholderOnTheLeft(QTZ.col(k).tail(n - k - 1), cod.hCoeffs().coeff(k), work);
  // T z = c(0:r)
  y.head(r) = c.head(r);
  QTZ.topLeftCorner(r, r).triangularView<Eigen::Upper>().solveInPlace(y.head(r));
  if (r < n) {  // y = Z^T [z; 0]
    y.tail(n - r).setZero();
    for (Eigen::Index k = 0; k < r; ++k) {
      if (k != r - 1) std::swap(y(k), y(r - 1));
      y.segment(r - 1, n - r + 1)
          .applyHouseholderOnTheLeft(QTZ.row(k).tail(n - r).transpose(), cod.zCoeffs().coeff(k), work);
      if (k != r - 1) std::swap(y(k), y(r - 1));
    }
  }
  const auto& P = cod.colsPermutation().indices();
  for (Eigen::Index e = 0; e < n; ++e) out(P(e)) = y(e);
}

void ScaledLeastNorm::solve(const Eigen::VectorXd& b, Eigen::VectorXd& x) const {
  const Eigen::Index n = d_.size();
  if (n == 0) return;
  if (small_) {
    SmallVector c(kept_);
    for (int i = 0; i < kept_; ++i) c(i) = d_(kept_rows_[i]) * b(kept_rows_[i]);
    SmallVector y(kept_);
    if (kept_ > 0) y = small_cod_.solve(c);
    x.setZero();
    for (int i = 0; i < kept_; ++i) x(kept_rows_[i]) = d_(kept_rows_[i]) * y(i);
    return;
  }
  if (compact_) {
    for (int i = 0; i < kept_; ++i) c_(i) = d_(kept_all_[i]) * b(kept_all_[i]);
    codSolve(compact_cod_, c_.head(kept_), y_.head(kept_), work2_.head(kept_));
    x.setZero();
    for (int i = 0; i < kept_; ++i) x(kept_all_[i]) = d_(kept_all_[i]) * work2_(i);
    return;
  }
  c_ = d_.cwiseProduct(b);
  codSolve(cod_, c_, y_, x);
  x = d_.cwiseProduct(x);
}

}  // namespace mechanism_sim
