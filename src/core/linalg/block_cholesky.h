// Cholesky factorization H = L L^T of a symmetric positive definite matrix made of 6x6
// blocks, one block row per moving body, with the block pattern of the body graph (two
// bodies are adjacent when a constraint couples them). The symbolic phase runs once: a
// fill-reducing order of the body graph (AMD; a tree then factors with no fill, as in
// Featherstone, "Efficient factorization of the joint-space inertia matrix for branched
// kinematic trees", IJRR 2005), the block pattern of L and a fixed schedule of block
// updates. The numeric phase is right-looking over fixed-size 6x6 kernels and allocates
// nothing. H is assembled straight into the block storage (block()).
//
// With a sign per block row and a given order it factors a quasi-definite matrix as
// L S L^T, S = diag(s_k I): the KKT matrix [M J^T; J 0] with the bodies and the equations
// of a spanning tree of joints as block rows (s = +1, -1), eliminated leaves first so
// that every pivot is definite (Baraff, "Linear-time dynamics using Lagrange
// multipliers", SIGGRAPH 1996): a body before the joint that ties it to its parent, that
// joint before the parent.
#pragma once
#include <array>
#include <type_traits>
#include <utility>
#include <vector>

#include <Eigen/Core>

namespace mechanism_sim {

// Calls f(std::integral_constant<int, c>{}) for c = 0, ..., 5: the columns of a 6x6 block as
// compile-time indices, so that a column's part on and below the diagonal is a fixed-size
// tail (the kernels that form only the lower triangle of a symmetric block).
template <class F, int... C>
inline void forEachColumn6(F&& f, std::integer_sequence<int, C...>) {
  (f(std::integral_constant<int, C>{}), ...);
}
template <class F>
inline void forEachColumn6(F&& f) {
  forEachColumn6(f, std::make_integer_sequence<int, 6>{});
}

class BlockCholesky {
 public:
  using Block = Eigen::Matrix<double, 6, 6>;
  using Vec6 = Eigen::Matrix<double, 6, 1>;

  // nb block rows; edges (i, j), i != j, of the block pattern (either order, repeats fine).
  void analyze(int nb, const std::vector<std::pair<int, int>>& edges);
  // The same with the pivot order given (order[k]: the block row eliminated k-th) and a
  // sign per block row (+1: s_k H_kk after the updates is positive definite; -1: negative).
  void analyze(int nb, const std::vector<std::pair<int, int>>& edges, const std::vector<int>& order,
               const std::vector<signed char>& signs);
  int size() const { return nb_; }

  // Storage of block (i, j) of H (original body indices, adjacent or i == j): *transposed
  // tells whether the stored block is H(j, i) (then add the transpose).
  int address(int i, int j, bool* transposed) const;
  Block& block(int address) { return blocks_[address]; }
  void setZero();

  // Factors in place (H = L S L^T). A pivot d of s_k H_kk with d <= pivot_tol * |the
  // diagonal entry it started from|
  // is zero: with skip_zero its row and column are dropped (noted in zeroPivot),
  // otherwise factorization stops. Returns the number of zero pivots met.
  int factorize(double pivot_tol, bool skip_zero);
  // Solves H x = b in place (6 entries per body, original order). After a factorization
  // that met zero pivots (skip_zero) the factor is only good for zeroPivot(): the rows of
  // L left of a skipped pivot are not cleared, so a solve would spread them.
  void solve(double* x) const;
  // Whether entry r of body b had a zero pivot in the last factorize().
  bool zeroPivot(int b, int r) const { return zero_[6 * b + r] != 0; }
  // Number of stored off-diagonal blocks of L (fill included): the cost of a factorization.
  int offDiagonalBlocks() const { return static_cast<int>(blocks_.size()) - nb_; }
  // The block row eliminated k-th.
  int pivot(int k) const { return order_[k]; }
  // Every stored block as (i, j, address): before factorization the block is H(i, j).
  std::vector<std::array<int, 3>> storedBlocks() const;

 private:
  struct Update {
    int target, a, b;  // blocks_[target] -= blocks_[a] * blocks_[b]^T
  };
  bool factorDiagonal(Block& D, double pivot_tol, bool skip_zero, int body, int* zeros);

  int nb_ = 0;
  std::vector<int> order_, position_;           // k-th pivot body, body -> k
  std::vector<double> sign_;                    // s_k in pivot order
  std::vector<int> col_start_, col_row_, col_block_;  // column k: rows (k order) and blocks
  std::vector<Update> updates_;
  std::vector<int> update_start_;               // updates of column k
  std::vector<std::vector<std::pair<int, int>>> lookup_;  // per column k: (row k', block)
  std::vector<Block> blocks_;                   // [0, nb): diagonal of body order_[k]
  std::vector<char> zero_;
  bool has_zero_ = false;                       // some entry of zero_ is set
  std::vector<Vec6> start_, dinv_;                     // diagonal of H before factorization
  mutable std::vector<Vec6> y_;
};

}  // namespace mechanism_sim
