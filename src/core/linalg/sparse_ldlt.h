// Sparse LDL^T of a symmetric matrix with a pattern fixed at analysis time: the
// up-looking algorithm with an elimination tree (T. A. Davis, "Algorithm 849: a
// concise sparse Cholesky factorization package", ACM TOMS 31(4), 2005). Every array is
// sized in analyze(), so factorize() and solve() allocate nothing.
#pragma once
#include <vector>

namespace mechanism_sim {

class SparseLDLT {
 public:
  // Pattern of an n x n symmetric matrix in compressed columns (both triangles or one;
  // entries below the diagonal after permutation are ignored). perm[k] is the original
  // index of the k-th pivot (empty: natural order).
  void analyze(int n, const std::vector<int>& Ap, const std::vector<int>& Ai,
               const std::vector<int>& perm);
  // Numeric factorization of values Ax (aligned with Ai), for positive (semi-)definite
  // matrices. A pivot with D_k <= pivot_tol * |A_kk| is zero: with skip_zero_pivots its row and column are
  // dropped (a dependent row of a semi-definite matrix), otherwise factorization stops.
  // Returns the number of zero pivots met (0 on success).
  int factorize(const double* Ax, double pivot_tol, bool skip_zero_pivots);
  // Solves A x = b in place (zero pivots give x_k = 0).
  void solve(double* x) const;
  // Whether original index i had a zero pivot in the last factorize().
  bool zeroPivot(int i) const { return zero_[pinv_[i]] != 0; }
  // The Schur complement of pivots first..first+size-1 given the pivots before them,
  // L_bb D_b L_bb^T, into S (column-major, leading dimension ld): what is left of that
  // diagonal block once the earlier pivots are eliminated. Pivot indices (as factored).
  void schurBlock(int first, int size, double* S, int ld) const;
  int size() const { return n_; }

 private:
  int n_ = 0;
  std::vector<int> Ap_, Ai_, P_, pinv_, Lp_, parent_, Lnz_, Li_, flag_, pattern_;
  // per row k (analyze()): A's entries on or above the diagonal, Ax places Sx_ and rows
  // Si_ from Sp_[k]; row k's pattern in L, Ri_ from Rp_[k]
  std::vector<int> Sp_, Sx_, Si_, Rp_, Ri_;
  std::vector<double> Lx_, D_;
  mutable std::vector<double> Y_;
  std::vector<char> zero_;
};

}  // namespace mechanism_sim
