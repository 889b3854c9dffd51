// The closures' linear algebra on the joint-space tree (closure_solver.h).
#include "mechanism_sim/core/closure_solver.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <utility>

#include <Eigen/OrderingMethods>
#include <Eigen/SparseCore>

#include "mechanism_sim/core/loop_closure.h"

namespace mechanism_sim {
namespace {

// The velocity coordinates in the tree's order (each after its parent), and per
// coordinate its parent coordinate: the previous one of its own link, or the last one of
// the nearest ancestor link that has coordinates (RBDA 6.5's lambda(i) over coordinates).
void coordinateTree(const TreeModel& model, std::vector<int>& order, std::vector<int>& parent) {
  order.clear();
  parent.assign(model.nv, -1);
  std::vector<int> last(model.nb, -1);  // per link: its last coordinate, or its ancestors'
  for (int b : model.order) {
    const int k = b - 1;
    const TreeLink& L = model.links[k];
    const int up = L.parent != 0 ? last[L.parent - 1] : -1;
    for (int i = 0; i < L.nv; ++i) {
      parent[L.iv + i] = i == 0 ? up : L.iv + i - 1;
      order.push_back(L.iv + i);
    }
    last[k] = L.nv > 0 ? L.iv + L.nv - 1 : up;
  }
}

}  // namespace

TreeMassFactor::TreeMassFactor(const TreeModel& model) {
  coordinateTree(model, vorder_, vparent_);
  vpos_.assign(model.nv, 0);
  for (int i = 0; i < model.nv; ++i) vpos_[vorder_[i]] = i;
  H_.setZero(model.nv, model.nv);
  Ic_.assign(model.nb, Matrix6d::Zero());
}

// LTDL, RBDA 6.5 table 6.3: for k from the leaves up, H_kk is D_k; each ancestor i of k
// gets a = H_ki / H_kk, H_ij -= a H_kj over i and its ancestors j, and H_ki = a (L_ki).
void TreeMassFactor::compute(const TreeModel& model, const System& sys, const TreeWorkspace& ws) {
  jointSpaceInertia(model, sys, ws, Ic_, H_);
  for (int n = static_cast<int>(vorder_.size()) - 1; n >= 0; --n) {
    const int k = vorder_[n];
    for (int i = vparent_[k]; i >= 0; i = vparent_[i]) {
      const double a = H_(k, i) / H_(k, k);
      for (int j = i; j >= 0; j = vparent_[j]) H_(i, j) -= a * H_(k, j);
      H_(k, i) = a;
    }
  }
}

// L^T w = b: row j reads w_j + sum_i L_ij w_i = b_j over the descendants i of j, so each
// w_i, final once its descendants are done, is pushed to its ancestors.
void TreeMassFactor::solveLT(double* z, const std::vector<int>& set) const {
  for (auto it = set.rbegin(); it != set.rend(); ++it) {
    const int i = *it;
    const double zi = z[i];
    if (zi == 0.0) continue;
    for (int j = vparent_[i]; j >= 0; j = vparent_[j]) z[j] -= H_(i, j) * zi;
  }
}

void TreeMassFactor::finish(const double* z, double* x) const {
  for (int i : vorder_) {
    double s = z[i] / H_(i, i);
    for (int j = vparent_[i]; j >= 0; j = vparent_[j]) s -= H_(i, j) * x[j];
    x[i] = s;
  }
}

ClosureSolver::ClosureSolver(const TreeModel& model, const std::vector<int>& block_first,
                             const std::vector<std::vector<int>>& block_cols) {
  m_ = block_first.empty() ? 0 : block_first.back();
  nv_ = model.nv;
  const int nblocks = static_cast<int>(block_cols.size());
  std::vector<int> order, parent;
  coordinateTree(model, order, parent);
  std::vector<int> pos(model.nv, 0);
  for (int i = 0; i < model.nv; ++i) pos[order[i]] = i;
  first_.assign(block_first.begin(), block_first.end());
  block_.assign(m_, 0);
  cols_.assign(nblocks, {});
  std::vector<std::vector<int>> at(model.nv);  // per coordinate: the blocks touching it
  for (int b = 0; b < nblocks; ++b) {
    for (int e = first_[b]; e < first_[b + 1]; ++e) block_[e] = b;
    cols_[b] = block_cols[b];
    std::sort(cols_[b].begin(), cols_[b].end(), [&](int x, int y) { return pos[x] < pos[y]; });
    cols_[b].erase(std::unique(cols_[b].begin(), cols_[b].end()), cols_[b].end());
    for (int v : cols_[b]) at[v].push_back(b);
  }
  std::map<std::pair<int, int>, std::vector<int>> shared;
  for (int b = 0; b < nblocks; ++b) shared[{b, b}];  // (every row has its diagonal)
  for (int v : order)
    for (size_t i = 0; i < at[v].size(); ++i)
      for (size_t j = i; j < at[v].size(); ++j) shared[{at[v][i], at[v][j]}].push_back(v);
  for (auto& s : shared) {
    pairs_.push_back(s.first);
    shared_.push_back(std::move(s.second));
  }
  // A's pattern, both triangles, in columns
  std::vector<std::vector<int>> colrows(m_);
  for (const auto& p : pairs_)
    for (int e = first_[p.first]; e < first_[p.first + 1]; ++e)
      for (int f = first_[p.second]; f < first_[p.second + 1]; ++f) {
        colrows[f].push_back(e);
        if (e != f) colrows[e].push_back(f);
      }
  Ap_.assign(m_ + 1, 0);
  Ai_.clear();
  pos_.assign(static_cast<size_t>(m_) * m_, -1);
  for (int f = 0; f < m_; ++f) {
    std::sort(colrows[f].begin(), colrows[f].end());
    colrows[f].erase(std::unique(colrows[f].begin(), colrows[f].end()), colrows[f].end());
    for (int e : colrows[f]) {
      pos_[static_cast<size_t>(f) * m_ + e] = static_cast<int>(Ai_.size());
      Ai_.push_back(e);
    }
    Ap_[f + 1] = static_cast<int>(Ai_.size());
  }
  Ax_.assign(Ai_.size(), 0.0);
  // fill-reducing order, once (Eigen's AMD on the pattern)
  std::vector<int> perm;
  if (m_ > 0) {
    Eigen::SparseMatrix<double, Eigen::ColMajor, int> P(m_, m_);
    std::vector<Eigen::Triplet<double, int>> t;
    for (int f = 0; f < m_; ++f)
      for (int p = Ap_[f]; p < Ap_[f + 1]; ++p) t.emplace_back(Ai_[p], f, 1.0);
    P.setFromTriplets(t.begin(), t.end());
    Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> Pinv;
    Eigen::AMDOrdering<int>()(P, Pinv);
    perm.assign(Pinv.indices().data(), Pinv.indices().data() + m_);
  }
  ldlt_.analyze(m_, Ap_, Ai_, perm);
  Z_.setZero(model.nv, m_);
  d_.setZero(m_);
  work_.setZero(m_);
  kept_rows_.setZero(m_);
}

void ClosureSolver::formY(const TreeMassFactor& mass, Eigen::MatrixXd& Y) const {
  for (int e = 0; e < m_; ++e) {
    double* y = Y.col(e).data();
    for (int k = 0; k < nv_; ++k) y[k] = 0.0;
    if (kept_rows_(e) == 0.0) continue;
    // H^-1 R_e^T = L^-1 D^-1 z (z zero off the row's coordinates)
    const double* z = Z_.col(e).data();
    for (int v : cols_[block_[e]]) y[v] = z[v];
    mass.finish(y, y);
  }
}

int ClosureSolver::factor(const TreeMassFactor& mass, const Eigen::MatrixXd& R, const Eigen::VectorXd& keep,
                          ScaledLeastNorm& dense, Eigen::MatrixXd& A_dense) {
  // Z = L^-T R^T on each kept row's coordinates, and the diagonal of A
  kept_ = 0;
  for (int e = 0; e < m_; ++e) {
    d_(e) = 0.0;
    kept_rows_(e) = keep(e);
    if (keep(e) == 0.0) continue;
    const std::vector<int>& cols = cols_[block_[e]];
    double* z = Z_.col(e).data();
    for (int v : cols) z[v] = R(e, v);
    mass.solveLT(z, cols);
    double a = 0.0;
    for (int v : cols) a += z[v] * z[v] / mass.D(v);
    if (a > 0.0) {
      d_(e) = 1.0 / std::sqrt(a);
      ++kept_;
    }
  }
  auto entry = [&](size_t p, int e, int f) {
    double s = 0.0;
    const double* ze = Z_.col(e).data();
    const double* zf = Z_.col(f).data();
    for (int v : shared_[p]) s += ze[v] * zf[v] / mass.D(v);
    return s;
  };
  sparse_ = kept_ > ScaledLeastNorm::kSmall;
  if (sparse_) {
    std::fill(Ax_.begin(), Ax_.end(), 0.0);
    for (int e = 0; e < m_; ++e)
      if (d_(e) == 0.0) Ax_[pos_[static_cast<size_t>(e) * m_ + e]] = 1.0;  // dropped: unit diagonal
    for (size_t p = 0; p < pairs_.size(); ++p) {
      const int a = pairs_[p].first, b = pairs_[p].second;
      for (int e = first_[a]; e < first_[a + 1]; ++e) {
        if (d_(e) == 0.0) continue;
        for (int f = a == b ? e : first_[b]; f < first_[b + 1]; ++f) {
          if (d_(f) == 0.0) continue;
          const double s = entry(p, e, f) * d_(e) * d_(f);
          Ax_[pos_[static_cast<size_t>(f) * m_ + e]] = s;
          Ax_[pos_[static_cast<size_t>(e) * m_ + f]] = s;
        }
      }
    }
    if (ldlt_.factorize(Ax_.data(), kClosureSparsePivot, false) == 0) return m_;
    sparse_ = false;  // a pivot at round-off: the rows depend on each other (or nearly)
  }
  // the rank-revealing dense solve, on A itself (unscaled: it scales)
  for (int e = 0; e < m_; ++e)
    if (d_(e) != 0.0)
      for (int f = 0; f < m_; ++f) A_dense(e, f) = 0.0;
  for (size_t p = 0; p < pairs_.size(); ++p) {
    const int a = pairs_[p].first, b = pairs_[p].second;
    for (int e = first_[a]; e < first_[a + 1]; ++e) {
      if (d_(e) == 0.0) continue;
      for (int f = first_[b]; f < first_[b + 1]; ++f) {
        if (d_(f) == 0.0) continue;
        A_dense(e, f) = A_dense(f, e) = entry(p, e, f);
      }
    }
  }
  for (int e = 0; e < m_; ++e) work_(e) = d_(e) != 0.0 ? 1.0 : 0.0;
  return dense.factor(A_dense, &work_);
}

void ClosureSolver::solve(const ScaledLeastNorm& dense, const Eigen::VectorXd& b, Eigen::VectorXd& x) const {
  if (!sparse_) {
    dense.solve(b, x);
    return;
  }
  for (int e = 0; e < m_; ++e) x(e) = d_(e) * b(e);
  ldlt_.solve(x.data());
  for (int e = 0; e < m_; ++e) x(e) *= d_(e);
}

}  // namespace mechanism_sim
