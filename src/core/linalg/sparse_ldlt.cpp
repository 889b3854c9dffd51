#include "core/linalg/sparse_ldlt.h"

#include <algorithm>
#include <cmath>

namespace mechanism_sim {

void SparseLDLT::analyze(int n, const std::vector<int>& Ap, const std::vector<int>& Ai,
                         const std::vector<int>& perm) {
  n_ = n;
  Ap_ = Ap;
  Ai_ = Ai;
  P_.resize(n);
  pinv_.resize(n);
  for (int k = 0; k < n; ++k) P_[k] = perm.empty() ? k : perm[k];
  for (int k = 0; k < n; ++k) pinv_[P_[k]] = k;
  Lp_.assign(n + 1, 0);
  parent_.assign(n, -1);
  Lnz_.assign(n, 0);
  flag_.assign(n, 0);
  // Elimination tree and column counts of L (ldl_symbolic).
  for (int k = 0; k < n; ++k) {
    parent_[k] = -1;
    flag_[k] = k;
    const int kk = P_[k];
    for (int p = Ap_[kk]; p < Ap_[kk + 1]; ++p) {
      for (int i = pinv_[Ai_[p]]; i < k && flag_[i] != k; i = parent_[i]) {
        if (parent_[i] == -1) parent_[i] = k;
        ++Lnz_[i];
        flag_[i] = k;
      }
    }
  }
  for (int k = 0; k < n; ++k) Lp_[k + 1] = Lp_[k] + Lnz_[k];
  Li_.assign(Lp_[n], 0);
  Lx_.assign(Lp_[n], 0.0);
  D_.assign(n, 0.0);
  Y_.assign(n, 0.0);
  pattern_.assign(n, 0);
  zero_.assign(n, 0);
  // Per row k of L, what factorize() reads of the pattern, found here once (it depends on
  // the pattern alone): the entries of A's column P_k on or above the diagonal (their
  // places in Ax and their rows), and the nonzero pattern of row k of L in the order the
  // sparse triangular solve takes it (ldl_numeric's reach along the elimination tree: the
  // same walk from the same entries, so factorize() does ldl_numeric's operations on the
  // values in ldl_numeric's order).
  Sp_.assign(n + 1, 0), Sx_.clear(), Si_.clear();
  Rp_.assign(n + 1, 0), Ri_.assign(Lp_[n], 0);
  std::fill(flag_.begin(), flag_.end(), -1);
  int r = 0;
  for (int k = 0; k < n; ++k) {
    int top = n;
    flag_[k] = k;
    const int kk = P_[k];
    for (int p = Ap_[kk]; p < Ap_[kk + 1]; ++p) {
      int i = pinv_[Ai_[p]];
      if (i > k) continue;
      Sx_.push_back(p), Si_.push_back(i);
      int len = 0;
      for (; flag_[i] != k; i = parent_[i]) {
        pattern_[len++] = i;
        flag_[i] = k;
      }
      while (len > 0) pattern_[--top] = pattern_[--len];
    }
    Sp_[k + 1] = static_cast<int>(Sx_.size());
    for (; top < n; ++top) Ri_[r++] = pattern_[top];
    Rp_[k + 1] = r;
  }
}

int SparseLDLT::factorize(const double* Ax, double pivot_tol, bool skip_zero_pivots) {
  int zeros = 0;
  for (int k = 0; k < n_; ++k) {
    // Row k of L by a sparse triangular solve (ldl_numeric), on the pattern analyze() found.
    Y_[k] = 0.0;
    Lnz_[k] = 0;
    zero_[k] = 0;
    double akk = 0.0;
    for (int s = Sp_[k]; s < Sp_[k + 1]; ++s) {
      const int i = Si_[s];
      Y_[i] += Ax[Sx_[s]];
      if (i == k) akk += Ax[Sx_[s]];
    }
    D_[k] = Y_[k];
    Y_[k] = 0.0;
    for (int t = Rp_[k]; t < Rp_[k + 1]; ++t) {
      const int i = Ri_[t];
      const double yi = Y_[i];
      Y_[i] = 0.0;
      const int p2 = Lp_[i] + Lnz_[i];
      for (int p = Lp_[i]; p < p2; ++p) Y_[Li_[p]] -= Lx_[p] * yi;
      const double l_ki = zero_[i] ? 0.0 : yi / D_[i];
      D_[k] -= l_ki * yi;
      Li_[p2] = k;
      Lx_[p2] = l_ki;
      ++Lnz_[i];
    }
    // Both matrices factored here are positive (semi-)definite: a pivot that is not
    // clearly positive is zero (or round-off of zero).
    if (!(D_[k] > pivot_tol * std::fabs(akk))) {
      ++zeros;
      zero_[k] = 1;
      D_[k] = 0.0;
      if (!skip_zero_pivots) return zeros;
    }
  }
  return zeros;
}

void SparseLDLT::schurBlock(int first, int size, double* S, int ld) const {
  // L restricted to the block: unit diagonal, column i's entries at rows inside it
  double L[36] = {0.0};
  for (int i = 0; i < size; ++i) {
    L[i * 6 + i] = 1.0;
    for (int p = Lp_[first + i]; p < Lp_[first + i] + Lnz_[first + i]; ++p)
      if (Li_[p] >= first && Li_[p] < first + size) L[(Li_[p] - first) * 6 + i] = Lx_[p];
  }
  for (int a = 0; a < size; ++a)
    for (int b = 0; b < size; ++b) {
      double s = 0.0;
      for (int i = 0; i <= std::min(a, b); ++i) s += L[a * 6 + i] * D_[first + i] * L[b * 6 + i];
      S[b * ld + a] = s;
    }
}

void SparseLDLT::solve(double* x) const {
  double* y = Y_.data();
  for (int k = 0; k < n_; ++k) y[k] = x[P_[k]];
  for (int j = 0; j < n_; ++j)
    for (int p = Lp_[j]; p < Lp_[j] + Lnz_[j]; ++p) y[Li_[p]] -= Lx_[p] * y[j];
  for (int j = 0; j < n_; ++j) y[j] = zero_[j] ? 0.0 : y[j] / D_[j];
  for (int j = n_ - 1; j >= 0; --j)
    for (int p = Lp_[j]; p < Lp_[j] + Lnz_[j]; ++p) y[j] -= Lx_[p] * y[Li_[p]];
  for (int k = 0; k < n_; ++k) x[P_[k]] = y[k];
  for (int k = 0; k < n_; ++k) y[k] = 0.0;
}

}  // namespace mechanism_sim
