// The least-norm solve of a symmetric positive semi-definite system with dependent rows
// (scaled_least_norm.cpp): the closures' G M^-1 G^T when the sparse solve cannot take it.
#pragma once
#include <vector>

#include <Eigen/Core>
#include <Eigen/QR>

#include "core/numerics.h"

namespace mechanism_sim {

using numerics::joint_space::kClosureRankThreshold;

// The least-norm solution of a symmetric positive semi-definite system A x = b (a
// G M^-1 G^T): rows not kept, or with a zero diagonal, held at x = 0; the rest
// Jacobi-scaled (row e by 1/sqrt(A_ee), unit diagonal) and solved by a complete
// orthogonal decomposition with relative threshold kClosureRankThreshold. Sized once;
// factor() and solve() allocate nothing.
class ScaledLeastNorm {
 public:
  ScaledLeastNorm() = default;
  explicit ScaledLeastNorm(int n);
  // Factors D A D, scaling A in place (a dropped row gets a unit diagonal). keep: per row,
  // 0 drops it (nullptr: every row with a positive diagonal is kept). Returns the rank of
  // the scaled matrix (dropped rows included, each with its unit diagonal).
  int factor(Eigen::MatrixXd& A, const Eigen::VectorXd* keep = nullptr);
  // x = D (D A D)^+ D b; x may be b.
  void solve(const Eigen::VectorXd& b, Eigen::VectorXd& x) const;
  // At most this many kept rows (of more) are factored on their own, in fixed-capacity
  // storage: a tree arm's active limit or its gripper's mimic coupler among many free
  // limits costs a k x k decomposition, not an n x n one. Only the kept rows of A are read.
  static constexpr int kSmall = 8;

 private:
  using SmallMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kSmall, kSmall>;
  using SmallVector = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kSmall, 1>;
  Eigen::VectorXd d_;  // the Jacobi scale per row (0: dropped)
  mutable Eigen::VectorXd c_, y_, work_, work2_;
  Eigen::MatrixXd sub_;  // the kept rows' block (compact path)
  Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd> cod_, compact_cod_;
  bool compact_ = false;  // more than kSmall rows kept, not all: those factored alone
  std::vector<int> kept_all_;
  void codSolve(const Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd>& cod, Eigen::Ref<Eigen::VectorXd> c,
                Eigen::Ref<Eigen::VectorXd> y, Eigen::Ref<Eigen::VectorXd> out) const;
  // the small path: kept rows (their indices) factored alone
  bool small_ = false;
  int kept_ = 0;
  int kept_rows_[kSmall] = {};
  Eigen::CompleteOrthogonalDecomposition<SmallMatrix> small_cod_;
};

}  // namespace mechanism_sim
