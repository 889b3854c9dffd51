// The closures' linear algebra on the joint-space tree, sparse where the tree and the
// closures are (loop_closure.h uses it for G and for the branch passages' reduced rows R).
//
//   TreeMassFactor  (M^-1 of many vectors at one state: the damping's and friction's
//                   columns) the joint-space inertia matrix M (RBDA's H; jointSpaceInertia:
//                   CRBA) factored as M = L^T D L in the order of the tree (Featherstone, "Rigid Body Dynamics
//                   Algorithms" (RBDA), 2008, 6.5, table 6.3, "LTDL"): L has the branch-induced
//                   sparsity of H (L_ij != 0 only for j an ancestor coordinate of i), so the
//                   factorization costs O(n d^2) and L^-T g touches only g's ancestors (d the
//                   depth of the tree).
//   ClosureSolver   for rows R (m x nv) grouped in blocks (a closure's rows), each block
//                   touching only an ancestor-closed set of coordinates (the paths of its
//                   bodies to the root): the multipliers' matrix A = R M^-1 R^T = Z^T D^-1 Z
//                   (RBDA 8.5, "sparse factorization" for closed loops), with M = L^T D L the
//                   factorization the articulated-body algorithm carries out (D_k =
//                   S_k^T I^A_k S_k, ws.Dinv): Z = L^-T R^T is its inward pass with zero
//                   velocity (applyInverseMass's first half) on the row alone, which touches
//                   only the links on the row's paths (O(depth) a row, no mass matrix).
//                   A is sparse where blocks share no
//                   coordinate: a chain of four-bars gives a block-tridiagonal A, a humanoid's
//                   mimic couplers small blocks. The Jacobi-scaled A (unit diagonal) is
//                   factored by a sparse LDL^T (sparse_ldlt.h) with a fill-reducing order
//                   (AMD, Eigen's AMDOrdering) found once; if a pivot falls below
//                   kClosureSparsePivot (rows dependent, or nearly), the rank-revealing dense
//                   solve (ScaledLeastNorm) takes over, so dependent rows get the least-norm
//                   multipliers. However few the kept rows (a four-bar's 2, an arm's active
//                   limit), the sparse LDL^T comes first: a rank-revealing decomposition
//                   costs more than the LDL^T even of a 2 x 2 (bench/RESULTS.md).
#pragma once
#include <vector>

#include <Eigen/Core>

#include "core/joint_space/tree.h"
#include "core/linalg/sparse_ldlt.h"
#include "core/numerics.h"

namespace mechanism_sim {

class ScaledLeastNorm;

using numerics::joint_space::kClosureSparsePivot;  // (numerics.h)

class TreeMassFactor {
 public:
  TreeMassFactor() = default;
  explicit TreeMassFactor(const TreeModel& model);
  // H at ws's kinematics (forwardKinematics or forwardDynamics), factored.
  void compute(const TreeModel& model, const TreeWorkspace& ws);
  // z = L^-T z in place, over z's entries (velocity coordinates); only the coordinates in
  // `set` (ancestor-closed, in the tree's order) are read and written.
  void solveLT(double* z, const std::vector<int>& set) const;
  // x = H^-1 b from z = L^-T b (D^-1, then L^-1): every coordinate written.
  void finish(const double* z, double* x) const;
  // x = H^-1 x (every coordinate).
  void solve(double* x) const {
    solveLT(x, vorder_);
    finish(x, x);
  }
  // per velocity coordinate: the parent coordinate (-1 at a root), and the coordinates
  // in the tree's order (each after its parent)
  const std::vector<int>& parent() const { return vparent_; }
  const std::vector<int>& order() const { return vorder_; }

 private:
  Eigen::MatrixXd H_;  // H, then L (entries (i, j), j an ancestor of i) and D (diagonal)
  AlignedVector<Matrix6d> Ic_;
  std::vector<int> vparent_, vorder_;
};

class ClosureSolver {
 public:
  ClosureSolver() = default;
  // block_first: the first row of each block and m at the end; block_cols: per block the
  // coordinates its rows can touch (their links' paths to the root are taken). Finds the
  // pattern of A and its ordering.
  ClosureSolver(const TreeModel& model, const std::vector<int>& block_first,
                const std::vector<std::vector<int>>& block_cols);
  // The factorization of R M^-1 R^T over the kept rows (keep(e) != 0), at the articulated
  // factors in ws (forwardDynamics at the same q). Returns the rank as
  // ScaledLeastNorm::factor counts it (dropped rows included).
  int factor(const TreeModel& model, const TreeWorkspace& ws, const Eigen::MatrixXd& R, const Eigen::VectorXd& keep,
             ScaledLeastNorm& dense, Eigen::MatrixXd& A_dense);
  // x = A^+ b (dropped rows: x = 0); x may be b. No allocation.
  void solve(const ScaledLeastNorm& dense, const Eigen::VectorXd& b, Eigen::VectorXd& x) const;
  // Whether the last factor() kept row e.
  bool kept(int e) const { return d_(e) != 0.0; }
  // u = L^-T R^T x (nv entries) from the last factor()'s passes on the rows themselves: the
  // inward pass is linear in its input, so the pass on R^T x is Z x (RBDA 8.5's Z), summed
  // over the rows' own coordinates. false, u untouched, where a row the factorization did
  // not keep has x != 0 (its column of Z was not formed).
  bool inwardOfRowsT(const Eigen::VectorXd& x, double* u) const;
  // Per block, its coordinates in the tree's order (R's entries elsewhere are zero).
  const std::vector<int>& blockCols(int b) const { return cols_[b]; }

 private:
  int m_ = 0;
  std::vector<int> block_, first_;            // per row its block; per block its first row
  std::vector<std::vector<int>> cols_;        // per block: coordinates, in the tree's order
  std::vector<std::vector<int>> links_;       // per block: links (body - 1) on its paths, leaves first
  std::vector<std::pair<int, int>> pairs_;    // blocks sharing a link with coordinates (a <= b)
  std::vector<std::vector<int>> shared_;      // per pair: those links
  std::vector<int> Ap_, Ai_, perm_;           // A's pattern (both triangles, columns), its order
  // The factored pattern: the kept rows' (analysed again when they change: a limit that
  // becomes active, a planar loop's rows that are zero), compact indices; pos_ (m x m):
  // where entry (e, f) of two kept rows sits in Ax_.
  std::vector<char> analyzed_;                // per row: kept at the last analysis
  std::vector<int> index_, cAp_, cAi_, cperm_, pos_;
  std::vector<double> Ax_;
  mutable std::vector<double> x_;
  int kc_ = -1;                               // kept rows at the last analysis (-1: none yet)
  void analyzeKept();
  Eigen::MatrixXd Z_;                         // L^-T R^T (nv x m): the inward pass's u
  Eigen::VectorXd d_, work_;                  // Jacobi scale (0: dropped); scratch
  AlignedVector<Vector6d> pa_, pb_;           // the inward pass's forces (pb_: a second row's)
  SparseLDLT ldlt_;
  bool sparse_ = false;
  int kept_ = 0;
  // z_e^T D^-1 z_f over the links of a list (D_k = S_k^T I^A_k S_k, ws.Dinv)
  double product(const TreeModel& model, const TreeWorkspace& ws, const std::vector<int>& links, int e, int f) const;
  // The same over lists of links that have one coordinate each (or none: left out), as
  // their coordinates, with D^-1 by coordinate (dinv_, set by factor()): the same terms in
  // the same order
  double product(const std::vector<int>& coords, int e, int f) const {
    const double* ze = Z_.col(e).data();
    const double* zf = Z_.col(f).data();
    const double* dinv = dinv_.data();
    double s = 0.0;
    for (int v : coords) s += ze[v] * dinv[v] * zf[v];
    return s;
  }
  std::vector<std::vector<int>> block_coords_, pair_coords_;  // per block (links_), per pair (shared_)
  std::vector<char> block_simple_, pair_simple_;              // whether those lists apply
  std::vector<char> block_kept_;                              // per block: a row kept (factor)
  Eigen::VectorXd dinv_;
};

}  // namespace mechanism_sim
