// The closures' linear algebra on the joint-space tree (closure_solver.h).
#include "core/joint_space/closure_solver.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <utility>

#include <Eigen/OrderingMethods>
#include <Eigen/SparseCore>

#include "core/joint_space/loop_closure.h"

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
  H_.setZero(model.nv, model.nv);
  Ic_.assign(model.nb, Matrix6d::Zero());
}

// LTDL, RBDA 6.5 table 6.3: for k from the leaves up, H_kk is D_k; each ancestor i of k
// gets a = H_ki / H_kk, H_ij -= a H_kj over i and its ancestors j, and H_ki = a (L_ki).
void TreeMassFactor::compute(const TreeModel& model, const TreeWorkspace& ws) {
  jointSpaceInertia(model, ws, Ic_, H_);
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
  const int nblocks = static_cast<int>(block_cols.size());
  std::vector<int> order, parent;
  coordinateTree(model, order, parent);
  std::vector<int> pos(model.nv, 0);
  for (int i = 0; i < model.nv; ++i) pos[order[i]] = i;
  std::vector<int> opos(model.nb, 0), link_of(model.nv, 0);  // links' places in model.order
  for (int n = 0; n < model.nb; ++n) opos[model.order[n] - 1] = n;
  for (int k = 0; k < model.nb; ++k)
    for (int i = 0; i < model.links[k].nv; ++i) link_of[model.links[k].iv + i] = k;
  first_.assign(block_first.begin(), block_first.end());
  block_.assign(m_, 0);
  cols_.assign(nblocks, {});
  links_.assign(nblocks, {});
  std::vector<std::vector<int>> at(model.nb);  // per link with coordinates: the blocks through it
  std::vector<char> mark(model.nb, 0);
  for (int b = 0; b < nblocks; ++b) {
    for (int e = first_[b]; e < first_[b + 1]; ++e) block_[e] = b;
    // the links on the paths of the block's coordinates to the root (fixed ones too: they
    // carry the inward pass's force), and their coordinates
    std::fill(mark.begin(), mark.end(), 0);
    for (int v : block_cols[b])
      for (int k = link_of[v]; k >= 0 && !mark[k]; k = model.links[k].parent - 1) mark[k] = 1;
    for (int k = 0; k < model.nb; ++k) {
      if (!mark[k]) continue;
      links_[b].push_back(k);
      for (int i = 0; i < model.links[k].nv; ++i) cols_[b].push_back(model.links[k].iv + i);
      // (a tied coordinate eliminated here: its entry starts at the row's value too)
      if (model.links[k].pivot >= 0) cols_[b].push_back(model.links[k].pivot);
      if (model.links[k].nv > 0) at[k].push_back(b);
    }
    std::sort(cols_[b].begin(), cols_[b].end());
    cols_[b].erase(std::unique(cols_[b].begin(), cols_[b].end()), cols_[b].end());
    std::sort(links_[b].begin(), links_[b].end(), [&](int x, int y) { return opos[x] > opos[y]; });
    std::sort(cols_[b].begin(), cols_[b].end(), [&](int x, int y) { return pos[x] < pos[y]; });
  }
  std::map<std::pair<int, int>, std::vector<int>> shared;
  for (int b = 0; b < nblocks; ++b) shared[{b, b}];  // (every row has its diagonal)
  for (int k = 0; k < model.nb; ++k)
    for (size_t i = 0; i < at[k].size(); ++i)
      for (size_t j = i; j < at[k].size(); ++j) shared[{at[k][i], at[k][j]}].push_back(k);
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
  for (int f = 0; f < m_; ++f) {
    std::sort(colrows[f].begin(), colrows[f].end());
    colrows[f].erase(std::unique(colrows[f].begin(), colrows[f].end()), colrows[f].end());
    for (int e : colrows[f]) Ai_.push_back(e);
    Ap_[f + 1] = static_cast<int>(Ai_.size());
  }
  // fill-reducing order, once (Eigen's AMD on the whole pattern; a subset of the rows is
  // factored in the same order)
  if (m_ > 0) {
    Eigen::SparseMatrix<double, Eigen::ColMajor, int> P(m_, m_);
    std::vector<Eigen::Triplet<double, int>> t;
    for (int f = 0; f < m_; ++f)
      for (int p = Ap_[f]; p < Ap_[f + 1]; ++p) t.emplace_back(Ai_[p], f, 1.0);
    P.setFromTriplets(t.begin(), t.end());
    Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> Pinv;
    Eigen::AMDOrdering<int>()(P, Pinv);
    perm_.assign(Pinv.indices().data(), Pinv.indices().data() + m_);
  }
  // storage for the largest pattern (every row kept), analysed once so that a later
  // analysis of fewer rows (whose fill is a subset) allocates nothing
  analyzed_.assign(m_, 1);
  index_.assign(m_, 0);
  cAp_.reserve(m_ + 1), cAi_.reserve(Ai_.size()), cperm_.reserve(m_);
  pos_.assign(static_cast<size_t>(m_) * m_, -1);
  Ax_.assign(Ai_.size(), 0.0);
  x_.assign(m_, 0.0);
  analyzeKept();
  Z_.setZero(model.nv, m_);
  d_.setZero(m_);
  work_.setZero(m_);
  pa_.assign(model.nb, Vector6d::Zero());
  pb_ = pa_;
  // product()'s lists as coordinates where every link on them has one (or none)
  auto coords = [&](const std::vector<int>& links, std::vector<int>& out) {
    out.clear();
    for (int k : links) {
      const TreeLink& L = model.links[k];
      if (L.nv > 1) return false;
      if (L.pivot >= 0) out.push_back(L.pivot);          // (its D^-1: dinv_, factor())
      if (L.nv == 1 && L.tie < 0) out.push_back(L.iv);  // (a tied link has no pivot of its own)
    }
    return true;
  };
  block_coords_.assign(nblocks, {}), block_simple_.assign(nblocks, 0);
  block_kept_.assign(nblocks, 0);
  for (int b = 0; b < nblocks; ++b) block_simple_[b] = coords(links_[b], block_coords_[b]);
  pair_coords_.assign(pairs_.size(), {}), pair_simple_.assign(pairs_.size(), 0);
  for (size_t p = 0; p < pairs_.size(); ++p) pair_simple_[p] = coords(shared_[p], pair_coords_[p]);
  dinv_.setZero(model.nv);
}

void ClosureSolver::analyzeKept() {
  int k = 0;
  for (int e = 0; e < m_; ++e) index_[e] = analyzed_[e] ? k++ : -1;
  cAp_.assign(1, 0);
  cAi_.clear();
  for (int f = 0; f < m_; ++f) {
    if (index_[f] < 0) continue;
    for (int p = Ap_[f]; p < Ap_[f + 1]; ++p) {
      const int e = Ai_[p];
      if (index_[e] < 0) continue;
      pos_[static_cast<size_t>(f) * m_ + e] = static_cast<int>(cAi_.size());
      cAi_.push_back(index_[e]);
    }
    cAp_.push_back(static_cast<int>(cAi_.size()));
  }
  cperm_.clear();
  for (int e : perm_)
    if (index_[e] >= 0) cperm_.push_back(index_[e]);
  ldlt_.analyze(k, cAp_, cAi_, cperm_);
  kc_ = k;
}

double ClosureSolver::product(const TreeModel& model, const TreeWorkspace& ws, const std::vector<int>& links, int e,
                              int f) const {
  const double* ze = Z_.col(e).data();
  const double* zf = Z_.col(f).data();
  double s = 0.0;
  for (int k : links) {
    const TreeLink& L = model.links[k];
    if (L.pivot >= 0) s += ze[L.pivot] * ws.tie_Dinv[k] * zf[L.pivot];
    if (L.tie >= 0) continue;  // (no pivot of its own: D^-1 0)
    if (L.nv == 1) {
      s += ze[L.iv] * ws.Dinv[k](0, 0) * zf[L.iv];
    } else {
      for (int i = 0; i < L.nv; ++i)
        for (int j = 0; j < L.nv; ++j) s += ze[L.iv + i] * ws.Dinv[k](i, j) * zf[L.iv + j];
    }
  }
  return s;
}

// Z's column of row e: the articulated-body algorithm's inward pass with zero velocity on
// tau = R_e^T (RBDA table 7.1, applyInverseMass): u_k = tau_k - S_k^T p_k, then
// p_parent += X^T (p_k + U_k D_k^-1 u_k). It is L^-T tau for M = L^T D L with D_k =
// S_k^T I^A_k S_k; p_k is zero off the row's paths, so only those links are visited.
int ClosureSolver::factor(const TreeModel& model, const TreeWorkspace& ws, const Eigen::MatrixXd& R,
                          const Eigen::VectorXd& keep, ScaledLeastNorm& dense, Eigen::MatrixXd& A_dense) {
  kept_ = 0;
  for (int k = 0; k < model.nb; ++k)  // (D^-1 of the one-coordinate links, by coordinate)
    if (model.links[k].nv == 1) dinv_(model.links[k].iv) = ws.Dinv[k](0, 0);
  for (int k = 0; k < model.nb; ++k)  // (then the tied coordinates' at their pivots)
    if (model.links[k].pivot >= 0) dinv_(model.links[k].pivot) = ws.tie_Dinv[k];
  auto scale = [&](int e) {  // the Jacobi scale of a kept row from its diagonal entry z_e^T D^-1 z_e
    const int b = block_[e];
    const double a = block_simple_[b] ? product(block_coords_[b], e, e) : product(model, ws, links_[b], e, e);
    if (a > 0.0) {
      d_(e) = 1.0 / std::sqrt(a);
      ++kept_;
    }
  };
  for (int e = 0; e < m_; ++e) {
    d_(e) = 0.0;
    if (keep(e) == 0.0) continue;
    const int b = block_[e];
    const std::vector<int>& links = links_[b];
    double* z = Z_.col(e).data();
    if (e + 1 < m_ && block_[e + 1] == b && keep(e + 1) != 0.0) {  // (two rows of a block: one pass over its links)
      d_(e + 1) = 0.0;
      double* z1 = Z_.col(e + 1).data();
      for (int v : cols_[b]) z[v] = R(e, v), z1[v] = R(e + 1, v);
      for (int k : links) pa_[k].setZero(), pb_[k].setZero();
      double* const zs[2] = {z, z1};
      AlignedVector<Vector6d>* const ps[2] = {&pa_, &pb_};
      for (int k : links) inverseMassInwardColumns<2>(model, ws, k, zs, zs, ps);
      scale(e), scale(e + 1);
      ++e;
      continue;
    }
    for (int v : cols_[b]) z[v] = R(e, v);  // (tau = R_e^T, then u in place)
    for (int k : links) pa_[k].setZero();
    for (int k : links) inverseMassInward(model, ws, k, z, z, pa_);
    scale(e);
  }
  sparse_ = kept_ > 0;  // (few rows too: the pivots decide, as for many; closure_solver.h)
  if (sparse_) {
    bool same = kept_ == kc_;
    for (int e = 0; e < m_ && same; ++e) same = analyzed_[e] == (d_(e) != 0.0);
    if (!same) {
      for (int e = 0; e < m_; ++e) analyzed_[e] = d_(e) != 0.0;
      analyzeKept();
    }
    std::fill(Ax_.begin(), Ax_.begin() + cAp_[kc_], 0.0);
    // (blocks with no row kept add nothing: free limits are blocks of one zero row)
    const int nblocks = static_cast<int>(first_.size()) - 1;
    for (int a = 0; a < nblocks; ++a) {
      block_kept_[a] = 0;
      for (int e = first_[a]; e < first_[a + 1] && !block_kept_[a]; ++e) block_kept_[a] = d_(e) != 0.0;
    }
    const double* d = d_.data();
    const int* pos = pos_.data();
    double* Ax = Ax_.data();
    for (size_t p = 0; p < pairs_.size(); ++p) {
      const int a = pairs_[p].first, b = pairs_[p].second;
      if (!block_kept_[a] || !block_kept_[b]) continue;
      const int a_end = first_[a + 1], b_first = first_[b], b_end = first_[b + 1];
      const bool simple = pair_simple_[p];
      for (int e = first_[a]; e < a_end; ++e) {
        if (d[e] == 0.0) continue;
        for (int f = a == b ? e : b_first; f < b_end; ++f) {
          if (d[f] == 0.0) continue;
          const double s = (simple ? product(pair_coords_[p], e, f) : product(model, ws, shared_[p], e, f)) * d[e] * d[f];
          Ax[pos[static_cast<size_t>(f) * m_ + e]] = s;
          Ax[pos[static_cast<size_t>(e) * m_ + f]] = s;
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
        A_dense(e, f) = A_dense(f, e) = product(model, ws, shared_[p], e, f);
      }
    }
  }
  for (int e = 0; e < m_; ++e) work_(e) = d_(e) != 0.0 ? 1.0 : 0.0;
  return dense.factor(A_dense, &work_);
}

bool ClosureSolver::inwardOfRowsT(const Eigen::VectorXd& x, double* u) const {
  for (int e = 0; e < m_; ++e)
    if (x(e) != 0.0 && d_(e) == 0.0) return false;
  std::fill(u, u + Z_.rows(), 0.0);
  for (int e = 0; e < m_; ++e) {
    const double xe = x(e);
    if (xe == 0.0) continue;
    const double* z = Z_.col(e).data();
    for (int v : cols_[block_[e]]) u[v] += z[v] * xe;
  }
  return true;
}

void ClosureSolver::solve(const ScaledLeastNorm& dense, const Eigen::VectorXd& b, Eigen::VectorXd& x) const {
  if (!sparse_) {
    dense.solve(b, x);
    return;
  }
  double* y = x_.data();
  for (int e = 0; e < m_; ++e)
    if (index_[e] >= 0) y[index_[e]] = d_(e) * b(e);
  ldlt_.solve(y);
  for (int e = 0; e < m_; ++e) x(e) = index_[e] >= 0 ? d_(e) * y[index_[e]] : 0.0;
}

}  // namespace mechanism_sim
