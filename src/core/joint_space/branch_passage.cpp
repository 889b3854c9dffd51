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
// closer, so a smaller step does not help.
//
// What. The branch is smooth through the crossing, and so is the motion across it: near
// the crossing y is carried by the integration, not by the equations. Each closure's rows
// (a cut joint's 1 to 6, those that are not round-off) are normalized by the size of their
// terms, with rates as speeds, over the columns that move its bodies relative to each
// other: W = D_r G C^-1 with D_r = 1 / |row of Gbound C^-1| (norms of the entries' parts,
// which do not vanish with the geometry) and C = diag(unit) (a singular value of W is a
// relative measure, the same in millimetres as in metres). Decomposed W = U S V^T, a
// direction i is
//   regular    s_i >= kPassageBand:   v_i^T C a = u_i^T D_r gamma_q / s_i (the equations),
//   in passage kPassageDependent <= s_i < kPassageBand:
//                                     v_i^T C a = v_i^T C a_ref (held: the acceleration across
//                                     the branch at the step's start, continuous along it),
//   dependent  s_i < kPassageDependent: dropped (rows dependent without being zero).
// With R the rows (v_i o unit)^T = (1/s_i) u_i^T D_r G of every closure's kept directions
// (R = P G), a = a_free - M^-1 R^T mu, (R M^-1 R^T) mu = R a_free - g (RBDA 8.3 on the
// reduced rows, least norm: rows of different closures may depend on each other). The
// constraint force stays along G^T (R^T mu = G^T P^T mu): lambda = P^T mu per closure row.
// The projections keep the regular directions' equations and leave the held ones as the
// integration carried them (rows with zero right-hand side). Once out of the passage
// (s >= kPassageBand, about 1e-2 rad from the crossing) the equations take over; their
// round-off error there is eps / 1e-6 in rate, and what the passage left across the branch
// is projected away, M-orthogonally, as the constraint force would have.
//
// Across the motion. v_i is the normal of the level set of Phi through the current point,
// (y, x) / |(x, y)| locally: where the integration has carried y off the branch (by the
// round-off it entered with, eps / kPassageBand), v_i leans into the motion by y / x. The
// held row's reaction R_i^T mu_i then does work on the motion at the rate
// mu_i (v_i o unit)^T q_dot ~ mu_i x_dot y / x, which grows without bound as a stage lands
// near the crossing (x -> 0): each passage would give the motion an energy error of that
// size, at random with where the stages fall. An ideal constraint does no work on the
// motion it allows (d'Alembert: the motion along the branch is then the branch's own
// dynamics), so in an acceleration solve (findPassage's rate: its q_dot) a held direction is taken
// across the motion: v_i less its component along m = C q_dot over the closure's columns,
// normalized, the unit vector nearest v_i with (v_i o unit)^T q_dot = 0. The regular
// directions' equations give v_k^T m = 0, so m, and with it the held direction, stays in
// the span of v_i and the closure's null space: the held row is still independent of the
// regular ones. At rest (m = 0), or with the motion along v_i itself (nothing of v_i left),
// v_i as it is. (The multipliers lambda = P^T mu stay those of v_i's row: they differ from
// the force applied by the lean, y / x, on the held rows' mu. The projections, which hold no
// acceleration, keep v_i.)
#include <algorithm>
#include <cmath>

#include "core/absolute/evaluation.h"
#include "core/joint_space/loop_closure.h"

namespace mechanism_sim {

// Closure c's rows that are not round-off (passage_.rows), the columns that move its bodies
// relative to each other (passage_.cols), and its term-normalized rows W (passage_.W, scales passage_.dr).
// false: no such rows or columns.
bool LoopClosures::closureRows(size_t c) {
  const int n = nrows_[c], r0 = row[c];
  passage_.rows.clear();
  passage_.cols.clear();
  // An entry is used where it is not round-off against its terms (roundoffRow's test). The
  // closure's rows are those with a used entry; its columns, those that move its bodies
  // relative to each other, are those with a used entry in one of those rows, i.e. in any
  // row (a round-off row has none): not the columns of a link that carries the whole loop
  // (an arm holding a gripper's four-bar), where G is round-off but Gbound is not (it would
  // shrink every singular value by the loop's size over the distance to that link). One
  // test per entry, the columns' entries read where they lie (G is column-major, a
  // closure's rows adjacent).
  if (n > 32) {  // (more rows than the mask holds: row by row)
    for (int e = r0; e < r0 + n; ++e)
      if (!roundoffRow(e)) passage_.rows.push_back(e);
    for (int k : ccols_[c]) {
      bool used = false;
      for (int e : passage_.rows) used = used || std::fabs(G(e, k)) > kClosureZeroEntry * Gabs(e, k);
      if (used) passage_.cols.push_back(k);
    }
  } else if (n == 2) {  // (a planar loop's two rows: both tests of a column at once)
    const Eigen::Index ld = G.rows();
    const double* g = G.data() + r0;
    const double* a = Gabs.data() + r0;
    unsigned rows_used = 0;
    for (int k : ccols_[c]) {
      const unsigned used = (std::fabs(g[k * ld]) > kClosureZeroEntry * a[k * ld] ? 1u : 0u) |
                            (std::fabs(g[k * ld + 1]) > kClosureZeroEntry * a[k * ld + 1] ? 2u : 0u);
      if (used) passage_.cols.push_back(k);
      rows_used |= used;
    }
    if (rows_used & 1u) passage_.rows.push_back(r0);
    if (rows_used & 2u) passage_.rows.push_back(r0 + 1);
  } else {
    const Eigen::Index ld = G.rows();
    unsigned rows_used = 0;
    for (int k : ccols_[c]) {
      const double* g = G.data() + k * ld + r0;
      const double* a = Gabs.data() + k * ld + r0;
      unsigned used = 0;
      for (int e = 0; e < n; ++e) used |= std::fabs(g[e]) > kClosureZeroEntry * a[e] ? 1u << e : 0u;
      if (used) passage_.cols.push_back(k);
      rows_used |= used;
    }
    for (int e = 0; e < n; ++e)
      if (rows_used >> e & 1u) passage_.rows.push_back(r0 + e);
  }
  const int kr = static_cast<int>(passage_.rows.size()), kc = static_cast<int>(passage_.cols.size());
  if (kr == 0 || kc == 0) return false;
  passage_.W.resize(kr, kc);
  passage_.dr.resize(kr);
  const Eigen::Index ld = G.rows();
  const int* cols = passage_.cols.data();
  const double* unit = unit_.data();
  double* W = passage_.W.data();  // (column-major, kr rows)
  for (int i = 0; i < kr; ++i) {
    const int e = passage_.rows[i];
    const double* gb = Gbound.data() + e;
    const double* g = G.data() + e;
    double n2 = 0.0;
    for (int j = 0; j < kc; ++j) {
      const double b = gb[cols[j] * ld] / unit[cols[j]];
      n2 += b * b;
    }
    const double dr = 1.0 / std::sqrt(n2);
    passage_.dr(i) = dr;
    for (int j = 0; j < kc; ++j) W[j * kr + i] = g[cols[j] * ld] / unit[cols[j]] * dr;
  }
  return true;
}

// The gate's test for two rows W (2 x kc, kc >= 2): whether the Cholesky factorization of
// W W^T - shift I runs to completion, with the operations of Eigen's (the product's entries
// summed over the columns in order, LLT's unblocked steps: pivot 0 not positive, or pivot
// 1 after the elimination not positive, fails; a NaN passes, as there), so it decides as
// the general path does.
bool passageGateTwoRows(const Eigen::Ref<const Eigen::MatrixXd>& W, double shift) {
  double g00 = W(0, 0) * W(0, 0), g10 = W(1, 0) * W(0, 0), g11 = W(1, 0) * W(1, 0);
  for (Eigen::Index k = 1; k < W.cols(); ++k) g00 += W(0, k) * W(0, k), g10 += W(1, k) * W(0, k), g11 += W(1, k) * W(1, k);
  g00 -= shift, g11 -= shift;
  if (g00 <= 0.0) return false;
  const double l10 = g10 / std::sqrt(g00);
  return !(g11 - l10 * l10 <= 0.0);
}

bool LoopClosures::findPassage(bool hold, const Eigen::VectorXd* rate) {
  // (G, Gabs, Gbound and hold as at the last call: its results stand)
  // (the rates matter to the held directions only: where none was held, any rates' results)
  const bool same_rate = passage_.band == 0 || (rate ? passage_.rate_set && passage_.rate == *rate : !passage_.rate_set);
  if (passage_.at_g == reuse_.g_gen && passage_.at_hold == hold && same_rate) {
    if (passage_.band > 0) ++passage_.met;
    return passage_.reduce;
  }
  passage_.at_g = reuse_.g_gen, passage_.at_hold = hold;
  passage_.rate_set = rate != nullptr;
  if (passage_.rate_set) passage_.rate = *rate;
  ++passage_.gen;
  return findPassageNow();
}

bool LoopClosures::findPassageNow() {
  passage_.band = passage_.excl = 0;
  passage_.near = false;
  passage_.r = 0;
  bool& reduce = passage_.reduce;
  reduce = false;
  if (m == 0) return false;
  if (passage_.P.rows() != m || passage_.P.cols() != m) {
    passage_.P.setZero(m, m), passage_.R.setZero(m, nv), passage_.w.setZero(m, m), passage_.z.setZero(m, m);
    passage_.held.assign(m, 0);
    passage_.excl_held.assign(m, 0);
    passage_.b.setZero(m), passage_.g.setZero(m), passage_.mu.setZero(m);
    passage_.A.setZero(m, m);
    passage_.least_norm = ScaledLeastNorm(m);
    passage_.rows.reserve(m), passage_.cols.reserve(nv);
    passage_.m.setZero(nv), passage_.h.setZero(nv);  // (passage_.rate: findPassage() sets it)
  }
  // Each closure's rows decomposed on their own (a cut joint's 1 to 6 rows over the columns
  // they touch): the crossing of a loop's branches takes a rank from that loop's rows. (Rows
  // of different closures that become dependent on each other are not a passage here: the
  // least-norm solve takes them, as outside a passage.)
  // slot j of closure c: its entries are in c's rows (P) and coordinates (R) only
  auto clearSlot = [&](int j, size_t c, int n) {
    for (int e = row[c]; e < row[c] + n; ++e) passage_.P(j, e) = 0.0;
    for (int k : ccols_[c]) passage_.R(j, k) = 0.0;
  };
  // Away from every passage nothing reduces: each closure's smallest singular value is
  // above kPassageGate and it has no dependent rows, i.e. W W^T - kPassageGate^2 I (at most
  // 6 x 6) is positive definite, which its Cholesky factorization decides without the
  // decomposition (Golub & Van Loan, "Matrix Computations", 4.2: it runs to completion iff
  // the matrix is positive definite). Its error, eps |W|^2, is far below kPassageGate^2, and
  // kGateMargin more keeps a pivot at that round-off on the full path, which decides it by
  // the singular values themselves. (Where some closure is near a passage, every closure is
  // decomposed below: the reduced solve takes all of them.)
  {
    constexpr double kGateMargin = numerics::joint_space::kPassageGateMargin;
    bool clear = true;
    for (size_t c = 0; c < constraints.size() && clear; ++c) {
      if (!closureRows(c)) continue;
      if (passage_.W.rows() > passage_.W.cols() || passage_.W.rows() > 6) {
        clear = false;
        break;
      }
      if (passage_.W.rows() == 2) {  // (a planar loop's two rows: the same test written out)
        clear = passageGateTwoRows(passage_.W, kPassageGate * kPassageGate + kGateMargin);
        continue;
      }
      passage_.gram.noalias() = passage_.W * passage_.W.transpose();
      passage_.gram.diagonal().array() -= kPassageGate * kPassageGate + kGateMargin;
      passage_.llt.compute(passage_.gram);
      clear = passage_.llt.info() == Eigen::Success;
    }
    if (clear) {
      for (size_t c = 0; c < constraints.size(); ++c) {
        const int n = nrows_[c];
        for (int j = row[c]; j < row[c] + passage_.used[c]; ++j) clearSlot(j, c, n);
        for (int e = row[c]; e < row[c] + n; ++e) passage_.keep(e) = 0.0, passage_.held[e] = 0;
        passage_.used[c] = 0;
        passage_.in_band[c] = 0;
      }
      return false;
    }
  }
  // (R's rows sit in slots: closure c's directions at rows row[c], row[c] + 1, ... of R, so
  // that R has G's block structure for the sparse solve; unused slots are zero, not kept)
  for (size_t c = 0; c < constraints.size(); ++c) {
    const int n = nrows_[c];
    const int used_before = passage_.used[c];
    passage_.used[c] = 0;
    for (int e = row[c]; e < row[c] + n; ++e) passage_.keep(e) = 0.0, passage_.held[e] = 0;
    if (!closureRows(c)) {
      for (int j = row[c]; j < row[c] + used_before; ++j) clearSlot(j, c, n);
      continue;
    }
    const int kr = static_cast<int>(passage_.rows.size()), kc = static_cast<int>(passage_.cols.size());
    const Eigen::VectorXd& dr = passage_.dr;
    bool in_band = false;  // a direction of c below kPassageBand (held or released)
    // the directions of the decomposition svd of W
    auto directions = [&](const auto& svd) {
      const auto& sigma = svd.singularValues();
      const auto& U = svd.matrixU();
      const auto& V = svd.matrixV();
      int rank = 0;
      for (Eigen::Index d = 0; d < sigma.size(); ++d) rank += sigma(d) >= kPassageDependent;
      if (rank < kr) reduce = true;  // rows dependent without being zero
      // A dependent direction is dropped, and its component of a residual is not judged: the
      // rows' own terms can be round-off there while their normalization (Gbound) is not, so
      // the component is round-off of the normalized rows, not of the row (onshape's planar
      // 2-dof closes its loop by a ball: the out-of-plane row is round-off, 1 of 3 rows over
      // 2 columns, and the velocity projection stalled at 0.06 judging it).
      auto exclude = [&](Eigen::Index d, bool held_dir = false) {
        passage_.excl_held[passage_.excl] = held_dir;
        passage_.w.row(passage_.excl).setZero();
        passage_.z.row(passage_.excl).setZero();
        for (int i = 0; i < kr; ++i) {
          passage_.w(passage_.excl, passage_.rows[i]) = dr(i) * U(i, d);
          passage_.z(passage_.excl, passage_.rows[i]) = U(i, d) / dr(i);
        }
        ++passage_.excl;
      };
      for (Eigen::Index d = sigma.size(); d < kr; ++d) exclude(d);
      for (Eigen::Index d = 0; d < sigma.size(); ++d) {
        const double s = sigma(d);
        if (!(s >= kPassageDependent)) {  // dependent: dropped
          exclude(d);
          continue;
        }
        if (s < kPassageGate) reduce = true;
        const int j = row[c] + passage_.used[c]++;
        ++passage_.r;
        passage_.keep(j) = 1.0;
        const bool held = passage_.at_hold && s < kPassageBand && !passage_.release[c];
        in_band = in_band || s < kPassageBand;
        passage_.near = passage_.near || s < kPassageNear;
        passage_.held[j] = held;
        // R_j = (1/s) u^T D_r G = (v o unit)^T, P(j, e) = D_r(e) u_e / s
        clearSlot(j, c, n);
        for (int i = 0; i < kr; ++i) passage_.P(j, passage_.rows[i]) = dr(i) * U(i, d) / s;
        for (int q = 0; q < kc; ++q) passage_.R(j, passage_.cols[q]) = V(q, d) * unit_(passage_.cols[q]);
        if (held && passage_.rate_set) {  // across the motion (the header comment)
          auto mv = passage_.m.head(kc);
          auto hv = passage_.h.head(kc);
          for (int q = 0; q < kc; ++q) mv(q) = passage_.rate(passage_.cols[q]) * unit_(passage_.cols[q]), hv(q) = V(q, d);
          const double mn = mv.norm();
          if (mn > 0.0) {
            mv /= mn;
            hv -= mv.dot(hv) * mv;
            const double hn = hv.norm();
            if (hn > 0.0)
              for (int q = 0; q < kc; ++q) passage_.R(j, passage_.cols[q]) = hv(q) / hn * unit_(passage_.cols[q]);
          }
        }
        if (held) {
          exclude(d, true);
          ++passage_.band;
        }
      }
    };
    // (U in full: with more rows than columns the rows' left null space is dependent too.
    // Up to 6 x 6, as a cut joint's rows over a planar loop's or a short spatial loop's
    // columns, in fixed-capacity storage: no dynamic-size overhead.)
    if (kr == 2 && kc == 3) {
      const Eigen::Matrix<double, 2, 3> W = passage_.W;
      passage_.svd23.compute(W, Eigen::ComputeFullU | Eigen::ComputeFullV);
      directions(passage_.svd23);
    } else if (kr <= 6 && kc <= 6) {
      passage_.svd6.compute(passage_.W, Eigen::ComputeFullU | Eigen::ComputeThinV);
      directions(passage_.svd6);
    } else {
      passage_.svd.compute(passage_.W, Eigen::ComputeFullU | Eigen::ComputeThinV);
      directions(passage_.svd);
    }
    for (int j = row[c] + passage_.used[c]; j < row[c] + used_before; ++j) clearSlot(j, c, n);
    passage_.in_band[c] = in_band;
  }
  if (passage_.band > 0) ++passage_.met;
  return reduce;
}

void LoopClosures::passageFactor(const TreeModel& model, const TreeWorkspace& ws) {
  // (R and the articulated factors as at the last call: its factorization stands)
  const long ws_gen = massFactorsGeneration(ws);
  if (passage_.fac_at_p == passage_.gen && passage_.fac_at_ws == ws_gen) return;
  // R M^-1 R^T over the kept slots (closure_solver.h); the others are held at mu = 0
  passage_.solver.factor(model, ws, passage_.R, passage_.keep, passage_.least_norm, passage_.A);
  passage_.fac_at_p = passage_.gen, passage_.fac_at_ws = ws_gen;
}

void LoopClosures::passageRhs(const Eigen::VectorXd& b, Eigen::VectorXd& g, const Eigen::VectorXd* accel) const {
  g.setZero();
  for (int j = 0; j < m; ++j) {
    if (passage_.keep(j) == 0.0) continue;
    const int c = cl_of_[j];
    double s = 0.0;
    if (!passage_.held[j]) {
      for (int e = row[c]; e < row[c] + nrows_[c]; ++e) s += passage_.P(j, e) * b(e);
    } else if (accel) {
      for (int k : ccols_[c]) s += passage_.R(j, k) * (*accel)(k);
    }
    g(j) = s;
  }
}

void LoopClosures::passageMultipliers(const Eigen::VectorXd& mu) {
  lambda.setZero();
  for (int j = 0; j < m; ++j) {
    if (mu(j) == 0.0) continue;
    const int c = cl_of_[j];
    for (int e = row[c]; e < row[c] + nrows_[c]; ++e) lambda(e) += passage_.P(j, e) * mu(j);
  }
}

double LoopClosures::passageResidual(const Eigen::VectorXd& b, const Eigen::VectorXd& scale_e) {
  passage_.b = b;
  for (int h = 0; h < passage_.excl; ++h) passage_.b -= passage_.z.row(h).transpose() * passage_.w.row(h).dot(b);
  double worst = 0.0;
  for (int e = 0; e < m; ++e) worst = std::max(worst, relative(passage_.b(e), scale_e(e)));
  return worst;
}

// Spells without a crossing. At a crossing the integration carries a held direction on its
// branch: its residual is Phi = x y with y the round-off it entered with, eps times the
// terms. Where the singular value dips into the band and comes back up without a crossing
// (a near change point: the branches pass close and the motion turns from one onto the
// other), the acceleration held across them is wrong and the residual along the held
// direction grows; there the equations themselves determine the motion well (eps / s^3 of
// the acceleration at s of 1e-3). The position projection at the end of a step releases
// the closures whose held residual exceeds its tolerance (releaseHeld): their directions are
// held by their equations until an accepted state finds them out of the band
// (endPassageSpells).
double LoopClosures::heldResidual(const Eigen::VectorXd& b, const Eigen::VectorXd& scale_e) {
  passage_.b.setZero();
  bool any = false;
  for (int h = 0; h < passage_.excl; ++h)
    if (passage_.excl_held[h]) passage_.b += passage_.z.row(h).transpose() * passage_.w.row(h).dot(b), any = true;
  if (!any) return 0.0;
  double worst = 0.0;
  for (int e = 0; e < m; ++e) worst = std::max(worst, relative(passage_.b(e), scale_e(e)));
  return worst;
}

bool LoopClosures::releaseHeld() {
  bool any = false;
  for (size_t c = 0; c < constraints.size(); ++c)
    for (int j = row[c]; j < row[c] + passage_.used[c]; ++j)
      if (passage_.held[j]) passage_.release[c] = 1, any = true;
  if (any) passage_.at_g = -1;  // (findPassage() decides again)
  return any;
}

void LoopClosures::endPassageSpells() {
  for (size_t c = 0; c < constraints.size(); ++c)
    if (!passage_.in_band[c]) passage_.release[c] = 0;
}

}  // namespace mechanism_sim
