#include "core/linalg/block_cholesky.h"

#include <algorithm>
#include <cmath>
#include <set>
#include <stdexcept>

#include "mechanism_sim/core/model/errors.h"

namespace mechanism_sim {

// Symbolic phase.
//  1. Order: minimum degree on the body graph, ties to the lower index (deterministic);
//     leaves of a tree go first, so a tree has no fill.
//  2. Pattern of L: eliminating pivot k joins its later neighbours into a clique.
//  3. Schedule: for each column k, the blocks below the diagonal and the updates
//     L_ij -= L_ik L_jk^T they make (i >= j > k).
void BlockCholesky::analyze(int nb, const std::vector<std::pair<int, int>>& edges) {
  analyze(nb, edges, {}, {});
}

void BlockCholesky::analyze(int nb, const std::vector<std::pair<int, int>>& edges, const std::vector<int>& given,
                            const std::vector<signed char>& signs) {
  nb_ = nb;
  if ((!given.empty() && static_cast<int>(given.size()) != nb) || (!signs.empty() && static_cast<int>(signs.size()) != nb))
    throw InternalError("the block factorization was given an order or signs of the wrong size");
  std::vector<std::set<int>> adj(nb);
  for (const auto& e : edges) {
    if (e.first < 0 || e.second < 0 || e.first >= nb || e.second >= nb)
      throw InternalError("the block factorization was given a coupling of a body it does not have");
    if (e.first == e.second) continue;
    adj[e.first].insert(e.second);
    adj[e.second].insert(e.first);
  }
  // 1. minimum degree (or the given order)
  order_.clear();
  position_.assign(nb, -1);
  if (!given.empty()) {
    order_ = given;
    for (int k = 0; k < nb; ++k) {
      if (given[k] < 0 || given[k] >= nb || position_[given[k]] >= 0)
        throw InternalError("the block factorization was given an elimination order that is not a permutation");
      position_[given[k]] = k;
    }
  } else {
    std::vector<std::set<int>> g = adj;
    std::vector<char> done(nb, 0);
    for (int step = 0; step < nb; ++step) {
      int best = -1;
      for (int b = 0; b < nb; ++b)
        if (!done[b] && (best < 0 || g[b].size() < g[best].size())) best = b;
      done[best] = 1;
      position_[best] = step;
      order_.push_back(best);
      for (int a : g[best])
        for (int c : g[best])
          if (a != c) g[a].insert(c);
      for (int a : g[best]) g[a].erase(best);
      g[best].clear();
    }
  }
  // 2. pattern of L in pivot order
  std::vector<std::set<int>> below(nb);  // column k: rows i > k
  for (int b = 0; b < nb; ++b)
    for (int c : adj[b]) {
      const int i = position_[b], j = position_[c];
      if (i > j) below[j].insert(i);
    }
  for (int k = 0; k < nb; ++k)
    for (int i : below[k])
      for (int j : below[k])
        if (i > j) below[j].insert(i);
  // 3. storage and schedule
  blocks_.assign(nb, Block::Zero());
  lookup_.assign(nb, {});
  col_start_.assign(nb + 1, 0);
  col_row_.clear();
  col_block_.clear();
  for (int k = 0; k < nb; ++k) {
    for (int i : below[k]) {
      col_row_.push_back(i);
      col_block_.push_back(static_cast<int>(blocks_.size()));
      lookup_[k].push_back({i, static_cast<int>(blocks_.size())});
      blocks_.push_back(Block::Zero());
    }
    col_start_[k + 1] = static_cast<int>(col_row_.size());
  }
  auto find = [&](int i, int j) {  // block of L(i, j), i > j
    for (const auto& e : lookup_[j])
      if (e.first == i) return e.second;
    throw InternalError("the block factorization misses a fill block");
  };
  updates_.clear();
  update_start_.assign(nb + 1, 0);
  for (int k = 0; k < nb; ++k) {
    for (int p = col_start_[k]; p < col_start_[k + 1]; ++p)
      for (int q = col_start_[k]; q <= p; ++q) {
        const int i = col_row_[p], j = col_row_[q];  // i >= j (rows sorted ascending)
        const int target = i == j ? i : find(i, j);
        updates_.push_back({target, col_block_[p], col_block_[q]});
      }
    update_start_[k + 1] = static_cast<int>(updates_.size());
  }
  sign_.assign(nb, 1.0);
  if (!signs.empty())
    for (int k = 0; k < nb; ++k) sign_[k] = signs[order_[k]] < 0 ? -1.0 : 1.0;
  zero_.assign(6 * nb, 0);
  has_zero_ = false;
  y_.assign(nb, Vec6::Zero());
  start_.assign(nb, Vec6::Zero());
  dinv_.assign(nb, Vec6::Zero());
}

int BlockCholesky::address(int i, int j, bool* transposed) const {
  const int pi = position_.at(i), pj = position_.at(j);
  *transposed = false;
  if (pi == pj) return pi;
  const int row = std::max(pi, pj), col = std::min(pi, pj);
  *transposed = pi < pj;
  for (const auto& e : lookup_[col])
    if (e.first == row) return e.second;
  throw InternalError("the block factorization was asked for a block between two bodies no constraint couples");
}

std::vector<std::array<int, 3>> BlockCholesky::storedBlocks() const {
  std::vector<std::array<int, 3>> out;
  for (int k = 0; k < nb_; ++k) {
    out.push_back({order_[k], order_[k], k});
    for (int p = col_start_[k]; p < col_start_[k + 1]; ++p) out.push_back({order_[col_row_[p]], order_[k], col_block_[p]});
  }
  return out;
}

void BlockCholesky::setZero() {
  for (Block& b : blocks_) b.setZero();
}

// In-place lower Cholesky factor of one diagonal block, column by column, with the
// pivot test relative to the entry's own starting |value| (start_). A zero pivot stops
// the factorization, or with skip_zero drops its entry (noted in zero_).
bool BlockCholesky::factorDiagonal(Block& D, double pivot_tol, bool skip_zero, int k, int* zeros) {
  const Vec6& start = start_[k];
  double* d = D.data();  // column-major: D(r, c) = d[r + 6 c]
#pragma GCC unroll 6
  for (int c = 0; c < 6; ++c) {
    double s = d[c + 6 * c];
#pragma GCC unroll 6
    for (int p = 0; p < c; ++p) s -= d[c + 6 * p] * d[c + 6 * p];
    if (!(s > pivot_tol * start(c)) || !(s < HUGE_VAL)) {
      ++*zeros;
      zero_[6 * order_[k] + c] = 1;
      has_zero_ = true;
      if (!skip_zero) return false;
      d[c + 6 * c] = 1.0;
      for (int r = c + 1; r < 6; ++r) d[r + 6 * c] = 0.0;
      continue;
    }
    const double l = std::sqrt(s);
    d[c + 6 * c] = l;
#pragma GCC unroll 6
    for (int r = c + 1; r < 6; ++r) {
      double t = d[r + 6 * c];
#pragma GCC unroll 6
      for (int p = 0; p < c; ++p) t -= d[r + 6 * p] * d[c + 6 * p];
      d[r + 6 * c] = t / l;
    }
  }
#pragma GCC unroll 6
  for (int c = 1; c < 6; ++c)
#pragma GCC unroll 6
    for (int r = 0; r < c; ++r) d[r + 6 * c] = 0.0;  // upper triangle: zero, so L_kk is the block
  return true;
}

namespace {

// B <- B L^-T for lower-triangular L with inverse diagonal dinv: each row b of B solves
// L x = b^T by forward substitution.
inline void solveRightLT(const BlockCholesky::Block& L, const BlockCholesky::Vec6& dinv, BlockCholesky::Block& B) {
#pragma GCC unroll 6
  for (int c = 0; c < 6; ++c) {
    BlockCholesky::Vec6 col = B.col(c);
#pragma GCC unroll 6
    for (int p = 0; p < c; ++p) col -= L(c, p) * B.col(p);
    B.col(c) = col * dinv[c];
  }
}

// y <- L^-1 y and y <- L^-T y for one diagonal block.
inline void forwardL(const BlockCholesky::Block& L, const BlockCholesky::Vec6& dinv, BlockCholesky::Vec6& y) {
#pragma GCC unroll 6
  for (int c = 0; c < 6; ++c) {
    double v = y[c];
#pragma GCC unroll 6
    for (int p = 0; p < c; ++p) v -= L(c, p) * y[p];
    y[c] = v * dinv[c];
  }
}
inline void backwardLT(const BlockCholesky::Block& L, const BlockCholesky::Vec6& dinv, BlockCholesky::Vec6& y) {
#pragma GCC unroll 6
  for (int c = 5; c >= 0; --c) {
    double v = y[c];
#pragma GCC unroll 6
    for (int r = c + 1; r < 6; ++r) v -= L(r, c) * y[r];
    y[c] = v * dinv[c];
  }
}

// T <- T - s A A^T on the lower triangle only (T a diagonal block: factorDiagonal reads
// nothing above it): 126 multiply-adds where the full product takes 216.
inline void lowerUpdate(BlockCholesky::Block& T, const BlockCholesky::Block& A, double s) {
  forEachColumn6([&](auto column) {
    constexpr int c = decltype(column)::value;
    T.col(c).template tail<6 - c>().noalias() -= s * (A.template bottomRows<6 - c>() * A.row(c).transpose());
  });
}

}  // namespace

int BlockCholesky::factorize(double pivot_tol, bool skip_zero) {
  int zeros = 0;
  if (has_zero_) std::fill(zero_.begin(), zero_.end(), 0), has_zero_ = false;
  for (int k = 0; k < nb_; ++k) start_[k] = blocks_[k].diagonal().cwiseAbs();
  for (int k = 0; k < nb_; ++k) {
    Block& D = blocks_[k];
    const double s = sign_[k];
    if (s < 0) D = -D;
    if (!factorDiagonal(D, pivot_tol, skip_zero, k, &zeros)) return zeros;
    dinv_[k] = D.diagonal().cwiseInverse();
    for (int p = col_start_[k]; p < col_start_[k + 1]; ++p) {
      Block& B = blocks_[col_block_[p]];
      solveRightLT(D, dinv_[k], B);  // L_ik = s_k H_ik L_kk^{-T}
      if (s < 0) B = -B;
      if (has_zero_)
        for (int c = 0; c < 6; ++c)
          if (zero_[6 * order_[k] + c]) B.col(c).setZero();
    }
    for (int u = update_start_[k]; u < update_start_[k + 1]; ++u) {  // H_ij -= L_ik s_k L_jk^T
      const Update& up = updates_[u];
      if (up.target < nb_) lowerUpdate(blocks_[up.target], blocks_[up.a], s);  // a diagonal block: up.a == up.b
      else if (s > 0) blocks_[up.target].noalias() -= blocks_[up.a] * blocks_[up.b].transpose();
      else blocks_[up.target].noalias() += blocks_[up.a] * blocks_[up.b].transpose();
    }
  }
  return zeros;
}

void BlockCholesky::solve(double* x) const {
  for (int k = 0; k < nb_; ++k) y_[k] = Eigen::Map<const Vec6>(x + 6 * order_[k]);
  for (int k = 0; k < nb_; ++k) {  // L y = b
    forwardL(blocks_[k], dinv_[k], y_[k]);
    for (int p = col_start_[k]; p < col_start_[k + 1]; ++p)
      y_[col_row_[p]].noalias() -= blocks_[col_block_[p]] * y_[k];
  }
  for (int k = nb_ - 1; k >= 0; --k) {  // L^T x = S y
    if (sign_[k] < 0) y_[k] = -y_[k];
    for (int p = col_start_[k]; p < col_start_[k + 1]; ++p)
      y_[k].noalias() -= blocks_[col_block_[p]].transpose() * y_[col_row_[p]];
    backwardLT(blocks_[k], dinv_[k], y_[k]);
  }
  for (int k = 0; k < nb_; ++k) {
    Vec6 v = y_[k];
    if (has_zero_)
      for (int c = 0; c < 6; ++c)
        if (zero_[6 * order_[k] + c]) v(c) = 0.0;
    Eigen::Map<Vec6>(x + 6 * order_[k]) = v;
  }
}

}  // namespace mechanism_sim
