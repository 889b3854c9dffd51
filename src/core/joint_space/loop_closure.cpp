// Loop closures on the joint-space tree (loop_closure.h): the workspace's layout, the
// evaluation (G, gamma_q at the tree's kinematics), residuals, limits' activation and
// tracked angles. What the closures are is closure_rows.cpp's, the solves are in
// closure_dynamics.cpp, the projections in closure_projection.cpp.
//
// References: Featherstone, "Rigid Body Dynamics Algorithms" (RBDA), Springer 2008,
// chapter 8 "Closed Loop Systems": 8.1 (equations of motion with loop constraints, the
// multipliers), 8.2 (the constraint equations of a cut joint, here the seed lecture's
// Phi(x) with Jacobian Phi_x over [delta r (global), delta theta' (body)] and gamma with
// Phi_x a = gamma), 8.3 (solving them: q_ddot = q_ddot_free + M^-1 G^T lambda with M^-1 G^T
// from the articulated-body algorithm, "method 2"; position and velocity stabilisation).
#include "core/joint_space/loop_closure.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <exception>
#include <random>

#include "mechanism_sim/core/model/couplers.h"
#include "mechanism_sim/core/model/coupling.h"
#include "mechanism_sim/core/model/errors.h"
#include "core/absolute/evaluation.h"

namespace mechanism_sim {
namespace {

// Whether `now` holds the bits of `copy` (sizes included: -0.0 is not 0.0 here, NaN is
// itself); `copy` becomes `now` either way (same sizes: no allocation).
template <class M>
bool unchangedSince(const Eigen::MatrixBase<M>& now, M& copy) {
  bool same = now.rows() == copy.rows() && now.cols() == copy.cols();
  const double *a = now.derived().data(), *b = copy.data();
  for (Eigen::Index i = 0; same && i < now.size(); ++i) {
    std::uint64_t x, y;  // (bits: a memcmp call costs more than these few words)
    std::memcpy(&x, a + i, sizeof x);
    std::memcpy(&y, b + i, sizeof y);
    same = x == y;
  }
  if (!same) copy = now;
  return same;
}

template <class M>
bool unchangedSince(const AlignedVector<M>& now, AlignedVector<M>& copy) {
  bool same = now.size() == copy.size();
  if (!same) copy.resize(now.size());
  for (size_t k = 0; k < now.size(); ++k) same &= unchangedSince(now[k], copy[k]);
  return same;
}

// A limit whose side in the context is 0 (free): its row is zero (LimitConstraint).
inline bool inactiveLimit(const Constraint& C, const EvalContext& ctx) {
  const int l = C.limit();
  return l >= 0 && ctx.limit_side && ctx.limit_side[l] == 0;
}

}  // namespace

LoopClosures::LoopClosures(const TreeModel& model, const System& sys)
    : ClosureRows(model, sys), model_(&model), sys_(&sys) {
  {
    const State s0 = initialState(sys);
    tracked = s0.tracked;
    limit_side = s0.limit_side;
    drive = s0.drive;
    t = s0.t;
  }
  layout(model, sys, {});
  // rows that no motion of the tree moves (a planar loop's out-of-plane rows): left out
  // (laid out again either way: the tests' evaluations are forgotten)
  layout(model, sys, idleRows(model, sys));
}

void LoopClosures::layout(const TreeModel& model, const System& sys, const std::vector<std::vector<char>>& idle) {
  layOut(sys, idle);
  Jc.clear();
  Phi.setZero(m), gamma.setZero(m), scale.setZero(m), gamma_q.setZero(m), nu.setZero(m), lambda.setZero(m);
  G.setZero(m, nv), Gabs.setZero(m, nv), Gbound.setZero(m, nv), Y.setZero(nv, m);
  scratch_.vr.setZero(m), scratch_.vt.setZero(m);
  scratch_.Jc_full.clear();
  for (size_t i = 0; i < constraints.size(); ++i) {
    const Constraint& C = *sys.constraints[constraints[i]];
    const int nb = 6 * static_cast<int>(C.bodies().size());
    Jc.push_back(Eigen::MatrixXd::Zero(nrows_[i], nb));
    scratch_.Jc_full.push_back(Eigen::MatrixXd::Zero(sel_[i].empty() ? 0 : C.size(), nb));
  }
  int full = 0;  // (the largest closure evaluated into the scratch)
  for (size_t i = 0; i < constraints.size(); ++i) full = std::max(full, static_cast<int>(scratch_.Jc_full[i].rows()));
  scratch_.Phi_full.setZero(full), scratch_.gamma_full.setZero(full);
  reuse_.pose_by_q = reuse_.pose_by_x = cleared_ = factors_.all_zero = false;
  ++reuse_.g_gen;
  reuse_.rows_of.assign(constraints.size(), RowsOf::kUnknown);
  reuse_.Jc_mapped = Jc;
  scratch_.jnorm.setZero(nrows_.empty() ? 0 : *std::max_element(nrows_.begin(), nrows_.end()), 2);
  scratch_.kin.assign(sys.numBodies(), BodyKin());
  scratch_.pa.assign(model.nb, Vector6d::Zero());
  scratch_.a = scratch_.a0 = scratch_.pa;
  factors_.keep.setZero(m), scratch_.tau.setZero(nv), scratch_.qdd_cut.setZero(nv), reuse_.pose_q.setZero(model.nq);
  scratch_.zero_v.setZero(nv), scratch_.qdd_v.setZero(nv), scratch_.dv_v.setZero(nv), scratch_.ref_v.setZero(nv), scratch_.r_m.setZero(m), scratch_.x_m.setZero(m);
  factors_.A.setZero(m, m);
  factors_.least_norm = ScaledLeastNorm(m);
  info = ClosureSolveInfo{};
  info.rows = allRows();
  // The closures' blocks for the sparse solves (closure_solver.h): each closure's rows touch
  // the coordinates of its bodies' paths to the root (a direct row: its coordinates' links'
  // paths), an ancestor-closed set.
  std::vector<int> first(row);
  first.push_back(m);
  std::vector<std::vector<int>> cols(constraints.size());
  auto addPath = [&](int b, std::vector<int>& out) {
    for (int a = b; a != 0; a = model.links[a - 1].parent) {
      const TreeLink& L = model.links[a - 1];
      for (int k = 0; k < L.nv; ++k) out.push_back(L.iv + k);
    }
  };
  std::vector<int> link_of(nv, 0);
  for (const TreeLink& L : model.links)
    for (int k = 0; k < L.nv; ++k) link_of[L.iv + k] = L.body;
  for (size_t i = 0; i < constraints.size(); ++i) {
    if (direct_[i].n > 0) {
      for (int k = 0; k < direct_[i].n; ++k) addPath(link_of[direct_[i].col[k]], cols[i]);
    } else {
      for (int b : sys.constraints[constraints[i]]->bodies()) addPath(b, cols[i]);
    }
  }
  factors_.mass = TreeMassFactor(model);
  factors_.solver = ClosureSolver(model, first, cols);
  ccols_.resize(constraints.size());
  cl_of_.assign(m, 0);
  for (size_t i = 0; i < constraints.size(); ++i) {
    ccols_[i] = factors_.solver.blockCols(static_cast<int>(i));
    for (int e = first[i]; e < first[i + 1]; ++e) cl_of_[e] = static_cast<int>(i);
  }
  passage_.solver = factors_.solver;
  passage_.keep.setZero(m);
  passage_.used.assign(constraints.size(), 0);
  passage_.release.assign(constraints.size(), 0);
  passage_.in_band.assign(constraints.size(), 0);
}

// Idle rows. A row of a closure's equations whose G = Phi_x J(q) row is zero at every q is
// constant under every motion of the tree: G q_dot = 0 and gamma_q = 0 on it, and its
// multiplier does no work. A planar loop (every joint on its paths turning about one
// direction n, or sliding across it) closed by a revolute cut joint about n has three of
// its five: the two C(n1) rows that keep the axes parallel (8.11: rotations about n keep
// both axes along n) and the point row along n when n is a coordinate axis. The factor
// drops such rows at every solve as round-off (roundoffRow), after mapping them at every
// evaluation; here they are found once and left out of the rows.
// Test: every entry of the row is round-off (kClosureZeroEntry) against the bound Gbound at
// the neutral configuration and at three others drawn at random (angles across +-3 rad,
// lengths across +-length_scale, the same draws every time). A row that is not
// identically zero (its entries are analytic in q) vanishes at random points with
// probability zero (polynomial identity testing: Schwartz 1980, Zippel 1979). Only
// scleronomic closures that are not rows on q itself are tested (a drive's, a limit's or a
// coupler's rows are not idle).
std::vector<std::vector<char>> LoopClosures::idleRows(const TreeModel& model, const System& sys) {
  std::vector<std::vector<char>> idle(constraints.size());
  bool any = false;
  for (size_t i = 0; i < constraints.size(); ++i) {
    const Constraint& C = *sys.constraints[constraints[i]];
    const bool candidate = direct_[i].n == 0 && C.limit() < 0 && !C.rheonomic();
    idle[i].assign(C.size(), candidate ? 1 : 0);
    any = any || candidate;
  }
  if (!any) return {};
  TreeWorkspace ws(model);
  std::mt19937 rng(20261126u);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  const Eigen::VectorXd q0 = model.neutralPositions(sys);
  Eigen::VectorXd q = q0, dv(nv);
  for (int draw = 0; draw < 4 && any; ++draw) {
    q = q0;
    if (draw > 0) {
      for (int k = 0; k < nv; ++k) dv(k) = unit(rng) * (angle_[k] ? 3.0 : sys.length_scale);
      retract(model, q, dv);
    }
    try {
      forwardKinematics(model, q, scratch_.zero_v, ws);
      evaluate(model, sys, ws, q);
    } catch (const std::exception&) {
      return {};  // (an equation that cannot be evaluated there: no row is left out)
    }
    any = false;
    for (size_t i = 0; i < constraints.size(); ++i)
      for (int e = 0; e < static_cast<int>(idle[i].size()); ++e) {
        if (!idle[i][e]) continue;
        // (against Gbound, the norms of the row's and the column's parts: a rotation's
        // round-off is relative to the vector rotated, not to each component, Gabs's terms)
        const int r = row[i] + e;
        for (int k : ccols_[i])
          if (std::fabs(G(r, k)) > kClosureZeroEntry * Gbound(r, k)) idle[i][e] = 0;
        any = any || idle[i][e];
      }
  }
  return any ? idle : std::vector<std::vector<char>>{};
}

// The twist a unit rate of column `col` of link a gives body b (centre r_b, rotation A_b),
// in the seed's absolute velocity coordinates [v (global), omega' (body)] (RBDA 8.2).
static inline Vector6d columnTwist(const TreeWorkspace& ws, int a, int col, const Matrix3d& Ab, const Vector3d& rb) {
  const Matrix3d& Aa = ws.A[a - 1];
  const Vector3d wg = Aa * ws.S[a - 1].col(col).head<3>();
  const Vector3d vg = Aa * ws.S[a - 1].col(col).tail<3>();
  Vector6d u;
  u.head<3>() = vg + wg.cross(rb - ws.r[a - 1]);
  u.tail<3>() = Ab.transpose() * wg;
  return u;
}

bool LoopClosures::addCutJointEfforts(const TreeModel& model, const System& sys, const TreeWorkspace& ws,
                                      const Inputs& in, Eigen::VectorXd& tau) {
  bool any = false;
  const EvalContext ctx = context();
  for (int j : model.cut_joints) {
    if (j >= static_cast<int>(in.effort.size())) continue;
    const Joint& J = *sys.joints[j];
    bool nonzero = false;
    for (int k = 0; k < J.dof(); ++k) nonzero = nonzero || in.effort[j][k] != 0.0;
    if (!nonzero) continue;
    if (!any) loadKin(ws);  // (the bodies' kinematics only for a cut joint that has an effort)
    any = true;
    Row rows[kMaxJointDofs];
    J.coordinates(scratch_.kin[J.bodyI()], scratch_.kin[J.bodyJ()], ctx.tracked[sys.joint_constraint[j]], rows);
    const int bodies[2] = {J.bodyI(), J.bodyJ()};
    for (int s = 0; s < 2; ++s) {
      const int b = bodies[s];
      if (b == 0) continue;
      // the joint's generalized force on b's absolute coordinates: sum_k q_x,k^T tau_k
      Vector6d f = Vector6d::Zero();
      for (int k = 0; k < J.dof(); ++k) f += rows[k].J.segment<6>(6 * s).transpose() * in.effort[j][k];
      for (int a = b; a != 0; a = model.links[a - 1].parent) {
        const TreeLink& L = model.links[a - 1];
        for (int col = 0; col < L.nv; ++col) tau(L.iv + col) += f.dot(columnTwist(ws, a, col, ws.A[b - 1], ws.r[b - 1]));
      }
    }
  }
  return any;
}

int LoopClosures::activateReachedLimits(const System& sys, const TreeModel& model, const Eigen::VectorXd& qv,
                                        const Eigen::VectorXd& qdot, TreeWorkspace& ws, signed char* limit_side) {
  int changed = 0;
  const EvalContext ctx = context();
  bool kinematics = false;
  Row rows[kMaxJointDofs];
  for (size_t l = 0; l < sys.limits.size(); ++l) {
    if (implied_[l]) {  // never active here (a State of the absolute formulation may have it so)
      changed += limit_side[l] != 0;
      limit_side[l] = 0;
      continue;
    }
    if (limit_side[l]) continue;
    const LimitSpec& L = sys.limits[l];
    double q = 0.0;
    if (limit_direct_[l] >= 0) {  // tree coordinates: the limit's sum is q's own
      const DirectRow& d = direct_[limit_direct_[l]];
      for (int k = 0; k < d.n; ++k) q += d.coef[k] * qv(d.qcol[k]);
    } else {
      if (!kinematics) forwardKinematics(model, qv, qdot, ws), loadKin(ws), kinematics = true;
      for (const LimitTerm& term : L.terms) {
        const Joint& J = *sys.joints[term.joint];
        J.coordinates(scratch_.kin[J.bodyI()], scratch_.kin[J.bodyJ()], ctx.tracked[sys.joint_constraint[term.joint]], rows);
        q += term.c * rows[term.k].Phi;
      }
    }
    const int side = limitSide(L, q);
    if (!side) continue;
    if (drivenAtLimit(sys, L, q, ctx.t)) continue;
    limit_side[l] = static_cast<signed char>(side);
    ++changed;
  }
  return changed;
}

int LoopClosures::releasePullingLimits(signed char* limit_side) const {
  int changed = 0;
  for (size_t i = 0; i < constraints.size(); ++i) {
    const int l = limits_[i];
    if (l < 0 || !limit_side[l]) continue;
    const double lam = lambda(row[i]);
    if ((limit_side[l] < 0 && lam > 0) || (limit_side[l] > 0 && lam < 0)) {
      limit_side[l] = 0;
      ++changed;
    }
  }
  return changed;
}

void LoopClosures::loadKin(const TreeWorkspace& ws) {
  for (int b = 1; b < static_cast<int>(scratch_.kin.size()); ++b) {
    const int k = b - 1;
    scratch_.kin[b].r = ws.r[k];
    scratch_.kin[b].A_Oi = ws.A[k];
    scratch_.kin[b].v = ws.A[k] * ws.v[k].tail<3>();
    scratch_.kin[b].w = ws.v[k].head<3>();
  }
}

// G = Phi_x J(q): for a closure body b, every link a on its path to the root moves it with
// q_dot_a through S_a: in global components the twist (omega_g; v_g) of a's centre, which
// gives b's centre v_g + omega_g x (r_b - r_a) and b's omega' = A_b^T omega_g (RBDA 8.2:
// the loop Jacobian as the difference of the two bodies' Jacobians, here through the
// seed's Phi_x). gamma_q = gamma - Phi_x a0 with a0 the bodies' accelerations at
// q_ddot = 0 (the velocity-product terms J_dot q_dot).
bool LoopClosures::allFreeLimits() const {
  if (!only_limits_) return false;
  if (limits_.empty()) return true;
  const signed char* side = context().limit_side;
  if (!side) return false;  // (no sides given: inactiveLimit counts no limit free)
  for (int l : limits_)
    if (side[l] != 0) return false;
  return true;
}

void LoopClosures::clearRows() {
  if (cleared_) return;
  Phi.setZero(), gamma.setZero(), scale.setZero(), gamma_q.setZero(), nu.setZero(), lambda.setZero();
  G.setZero(), Gabs.setZero(), Y.setZero();
  for (Eigen::MatrixXd& J : Jc) J.setZero();
  factors_.keep.setZero();
  info.rank = 0;
  info.dependent = allRows();
  factors_.all_zero = true;
  cleared_ = true;
  std::fill(reuse_.rows_of.begin(), reuse_.rows_of.end(), RowsOf::kUnknown);  // (G and Gabs cleared, Gbound not)
  ++reuse_.g_gen;
}

void LoopClosures::evaluate(const TreeModel& model, const System& sys, const TreeWorkspace& ws) {
  cleared_ = false;
  const EvalContext ctx = context();
  // The bodies' kinematics are read by the closures that are not rows on q itself (those
  // give Phi from q: a limit, a drive or a coupler on tree joints, often all there is)
  bool kinematics = false;
  for (size_t i = 0; i < constraints.size() && !kinematics; ++i)
    kinematics = !(q_ && direct_[i].n > 0) && !inactiveLimit(*sys.constraints[constraints[i]], ctx);
  bool poses_same = false;
  if (kinematics) {
    loadKin(ws);
    // a0: spatial accelerations at q_ddot = 0 (RBDA table 7.1's a'_i without the S q_ddot)
    for (int b : model.order) {
      const int k = b - 1;
      const TreeLink& L = model.links[k];
      scratch_.a0[k] = ws.c[k];
      if (L.parent != 0) scratch_.a0[k] += transformMotion(ws.E[k], ws.rho[k], scratch_.a0[L.parent - 1]);
    }
    // A closure's rows of G, Gabs and Gbound are functions of its Phi_x (Jc) and of the
    // links' poses and subspaces alone: where those hold the bits of the last mapping (the
    // stepper evaluates each new q at rest for its projections, then in motion for the
    // accelerations) the rows are kept, and reuse_.g_gen says whether any row changed. (Without
    // kinematics no row is mapped: the copies stay those of the last mapping.)
    // With the tree's q given, its bits stand for the poses (forwardKinematics reads q and
    // the model alone): nq numbers compared instead of 18 a link.
    if (q_) {
      poses_same = unchangedSince(*q_, reuse_.pose_q) & reuse_.pose_by_q;
      reuse_.pose_by_q = true, reuse_.pose_by_x = false;
    } else {
      poses_same = unchangedSince(ws.A, reuse_.pose_A) & unchangedSince(ws.r, reuse_.pose_r) & unchangedSince(ws.S, reuse_.pose_S) &
                   reuse_.pose_by_x;
      reuse_.pose_by_x = true, reuse_.pose_by_q = false;
    }
  }
  bool changed = false;
  // (G, Gabs and Gbound are zero off each closure's coordinates: only those are cleared)
  auto clear = [&](size_t i) {
    for (int e = row[i]; e < row[i] + nrows_[i]; ++e)
      for (int k : ccols_[i]) G(e, k) = Gabs(e, k) = Gbound(e, k) = 0.0;
    changed = true;
  };
  auto directRow = [&](size_t i) {  // a coordinate row: G = its coefficients
    if (reuse_.rows_of[i] == RowsOf::kDirect) return;
    clear(i);
    reuse_.rows_of[i] = RowsOf::kDirect;
    const DirectRow& d = direct_[i];
    for (int k = 0; k < d.n; ++k) {
      G(row[i], d.col[k]) += d.coef[k];
      Gabs(row[i], d.col[k]) += std::fabs(d.coef[k]);
      Gbound(row[i], d.col[k]) += std::fabs(d.coef[k]);
    }
  };
  const BodyKin* ptrs[kMaxConstraintBodies];
  for (size_t i = 0; i < constraints.size(); ++i) {
    const Constraint& C = *sys.constraints[constraints[i]];
    const int n = nrows_[i], r0 = row[i];
    if (inactiveLimit(C, ctx)) {  // a free limit: a zero row (as Constraint::evaluate gives it), no mapping
      Phi.segment(r0, n).setZero(), gamma.segment(r0, n).setZero(), scale.segment(r0, n).setZero();
      gamma_q.segment(r0, n).setZero();
      Jc[i].setZero();
      if (reuse_.rows_of[i] != RowsOf::kZero) clear(i), reuse_.rows_of[i] = RowsOf::kZero;
      continue;
    }
    if (q_ && direct_[i].n > 0) {  // Phi from q itself (evaluate(..., q)); scale: the size of its terms
      const DirectRow& d = direct_[i];
      double phi = 0.0, sc = 0.0;
      for (int k = 0; k < d.n; ++k) {
        const double qk = (*q_)(d.qcol[k]);
        phi += d.coef[k] * qk;
        sc += std::fabs(d.coef[k]) * (std::fabs(qk) + (d.angle[k] ? 1.0 : sys.length_scale));
      }
      if (d.limit >= 0) {
        const LimitSpec& spec = sys.limits[d.limit];
        const double bound = ctx.limit_side[d.limit] < 0 ? spec.lower : spec.upper;
        phi -= bound;
        sc += std::fabs(bound);
      } else {
        phi -= d.offset;
        sc += std::fabs(d.offset);
      }
      Phi(r0) = phi, gamma(r0) = gamma_q(r0) = 0.0, scale(r0) = sc;
      directRow(i);
      continue;
    }
    const auto& bodies = C.bodies();
    for (size_t s = 0; s < bodies.size(); ++s) ptrs[s] = &scratch_.kin[bodies[s]];
    if (sel_[i].empty()) {
      C.evaluate(ptrs, ctx, Phi.segment(r0, n), Jc[i], gamma.segment(r0, n));
    } else if (sel_joint_[i]) {  // the rows some motion moves (layout(): the idle ones left out): a joint
      // computes those alone, straight into their places
      sel_joint_[i]->evaluateSelected(ptrs, ctx, Phi.segment(r0, n), Jc[i], gamma.segment(r0, n), sel_mask_[i]);
    } else {  // (the whole evaluation, the kept rows copied)
      const int nc = C.size();
      C.evaluate(ptrs, ctx, scratch_.Phi_full.head(nc), scratch_.Jc_full[i], scratch_.gamma_full.head(nc));
      for (int e = 0; e < n; ++e) {
        const int f = sel_[i][e];
        Phi(r0 + e) = scratch_.Phi_full(f), gamma(r0 + e) = scratch_.gamma_full(f);
        Jc[i].row(e) = scratch_.Jc_full[i].row(f);
      }
    }
    if (C.rheonomic()) C.velocityTerm(ctx, nu.data() + r0);  // (nu stays 0 elsewhere)
    for (size_t s = 0; s < bodies.size(); ++s) scratch_.lever[s] = scratch_.kin[bodies[s]].r.cwiseAbs().maxCoeff() + sys.length_scale;
    for (int e = 0; e < n; ++e) {
      double sc = 0;
      for (size_t s = 0; s < bodies.size(); ++s)
        sc += Jc[i].row(e).segment<3>(6 * s).cwiseAbs().sum() * scratch_.lever[s] + Jc[i].row(e).segment<3>(6 * s + 3).cwiseAbs().sum();
      scale(r0 + e) = sc;
    }
    if (direct_[i].n > 0) {  // gamma_q = 0: a coordinate's rate is q_ddot's own
      gamma_q.segment(r0, n).setZero();
      directRow(i);
      continue;
    }
    gamma_q.segment(r0, n) = gamma.segment(r0, n);
    for (size_t s = 0; s < bodies.size(); ++s) {
      const int b = bodies[s];
      if (b == 0) continue;
      // velocity-product part: absolute acceleration of b at q_ddot = 0 (bodyAccelerations)
      const Matrix3d& Ab = ws.A[b - 1];
      const Vector6d& a0 = scratch_.a0[b - 1];
      Vector6d acc;
      acc.head<3>() = Ab * (a0.tail<3>() + ws.v[b - 1].head<3>().cross(ws.v[b - 1].tail<3>()));
      acc.tail<3>() = a0.head<3>();
      gamma_q.segment(r0, n).noalias() -= Jc[i].middleCols<6>(6 * s).topRows(n) * acc;
    }
    if (poses_same && reuse_.rows_of[i] == RowsOf::kMapped && unchangedSince(Jc[i], reuse_.Jc_mapped[i])) continue;
    std::copy_n(Jc[i].data(), Jc[i].size(), reuse_.Jc_mapped[i].data());  // (the same size: a plain copy)
    reuse_.rows_of[i] = RowsOf::kMapped;
    clear(i);
    for (size_t s = 0; s < bodies.size(); ++s) {
      const int b = bodies[s];
      if (b == 0) continue;
      // (the body's block and its magnitudes copied once, in fixed-capacity storage when it
      // fits: the products below then run without dynamic-size overhead)
      const auto Jdyn = Jc[i].middleCols<6>(6 * s);
      if (n > kSmallRows) {
        mapBody(model, ws, b, Jdyn, Jdyn.cwiseAbs(), r0, n);
        continue;
      }
      if (n == 2) {  // (a planar loop's two rows: fixed sizes throughout, the same operations)
        const Eigen::Matrix<double, 2, 6, Eigen::RowMajor> Jb = Jdyn, Jabs = Jdyn.cwiseAbs();
        mapBody(model, ws, b, Jb, Jabs, r0, n);
        continue;
      }
      const SmallRows Jb = Jdyn, Jabs = Jdyn.cwiseAbs();
      mapBody(model, ws, b, Jb, Jabs, r0, n);
    }
  }
  if (changed) ++reuse_.g_gen;
}

// G, Gabs and Gbound of rows r0 .. r0 + n - 1 on the columns of body b's path to the root,
// from Jb (the rows' Phi_x on b's [delta r; delta theta']) and |Jb| (evaluate()).
template <class JB, class JA>
void LoopClosures::mapBody(const TreeModel& model, const TreeWorkspace& ws, int b, const JB& Jb, const JA& Jabs,
                           int r0, int n) {
  constexpr int N = JB::RowsAtCompileTime;  // (Eigen::Dynamic, or the rows' number)
  if constexpr (N != Eigen::Dynamic) n = N;
  const Matrix3d& Ab = ws.A[b - 1];
  const Vector3d& rb = ws.r[b - 1];
  // the rows' parts' norms for Gbound, once per body (they do not depend on the column)
  for (int e = 0; e < n; ++e)
    scratch_.jnorm(e, 0) = Jb.row(e).template head<3>().norm(), scratch_.jnorm(e, 1) = Jb.row(e).template tail<3>().norm();
  for (int a = b; a != 0; a = model.links[a - 1].parent) {
    const TreeLink& L = model.links[a - 1];
    const Matrix3d& Aa = ws.A[a - 1];
    const Vector3d lever = rb - ws.r[a - 1];
    for (int col = 0; col < L.nv; ++col) {
      const Vector3d wg = Aa * ws.S[a - 1].col(col).head<3>();
      const Vector3d vg = Aa * ws.S[a - 1].col(col).tail<3>();
      const Vector3d wxl = wg.cross(lever);
      Vector6d u;
      u.head<3>() = vg + wxl;
      u.tail<3>() = Ab.transpose() * wg;
      Vector6d uabs;
      uabs.head<3>() = vg.cwiseAbs() + wxl.cwiseAbs();
      uabs.tail<3>() = u.tail<3>().cwiseAbs();
      if constexpr (N != Eigen::Dynamic) {
        G.col(L.iv + col).template segment<N>(r0).noalias() += Jb * u;
        Gabs.col(L.iv + col).template segment<N>(r0).noalias() += Jabs * uabs;
      } else {
        G.col(L.iv + col).segment(r0, n).noalias() += Jb * u;
        Gabs.col(L.iv + col).segment(r0, n).noalias() += Jabs * uabs;
      }
      // (norms, not components: a bound that does not vanish where the geometry makes
      // the entry vanish, for the branch passages' normalization)
      const double sv = vg.norm() + wg.norm() * lever.norm(), sw = wg.norm();
      for (int e = 0; e < n; ++e)
        Gbound(r0 + e, L.iv + col) += scratch_.jnorm(e, 0) * sv + scratch_.jnorm(e, 1) * sw;
    }
  }
}

double LoopClosures::positionResidual() const {
  double worst = 0;
  for (int e = 0; e < m; ++e) worst = std::max(worst, relative(Phi(e), scale(e)));
  return worst;
}

void LoopClosures::velocityRows(const Eigen::VectorXd& qdot, const Eigen::VectorXd* reference, Eigen::VectorXd& r,
                                Eigen::VectorXd& t) const {
  // A direct row's terms are its own coordinates only: a coordinate the closures lock ends
  // at round-off, judged against the speed of the whole motion (as speeds: rates times
  // unit_), or the loads' velocity scale, whichever is larger.
  double V = sys_->velocity_scale;
  for (int k = 0; k < nv; ++k)
    V = std::max({V, std::fabs(qdot(k)) * unit_(k), reference ? std::fabs((*reference)(k)) * unit_(k) : 0.0});
  for (size_t i = 0; i < constraints.size(); ++i) {
    for (int e = row[i]; e < row[i] + nrows_[i]; ++e) {
      double s = -nu(e), sc = std::fabs(nu(e));
      // (each coordinate's rate floored at kFloor of the motion, as the absolute
      // formulation floors each body's: a loop that locks coordinates leaves their rates
      // at round-off, and round-off over round-off judged nothing; a free limit's row of G
      // and Gabs is zero)
      if (reuse_.rows_of[i] != RowsOf::kZero) {
        for (int k : ccols_[i]) {
          s += G(e, k) * qdot(k);
          sc += Gabs(e, k) * (std::fabs(qdot(k)) + (reference ? std::fabs((*reference)(k)) : 0.0) + kFloor * V / unit_(k));
        }
      }
      if (direct_[i].n > 0)
        for (int k = 0; k < direct_[i].n; ++k) sc += std::fabs(direct_[i].coef[k]) * V / unit_(direct_[i].col[k]);
      r(e) = s;
      t(e) = sc;
    }
  }
}

double LoopClosures::velocityResidual(const Eigen::VectorXd& qdot, const Eigen::VectorXd* reference) const {
  velocityRows(qdot, reference, scratch_.vr, scratch_.vt);
  double worst = 0;
  for (int e = 0; e < m; ++e) worst = std::max(worst, relative(scratch_.vr(e), scratch_.vt(e)));
  return worst;
}

void LoopClosures::track(const TreeWorkspace& ws, const std::vector<int>& which, std::vector<Tracked>& tracked) {
  loadKin(ws);
  const EvalContext ctx = context();
  const BodyKin* ptrs[kMaxConstraintBodies];
  for (int c : which) {
    const Constraint& C = *sys_->constraints[c];
    for (size_t s = 0; s < C.bodies().size(); ++s) ptrs[s] = &scratch_.kin[C.bodies()[s]];
    Tracked tr = tracked[c];
    C.trackAngles(ptrs, ctx, tr);  // (their rates are not kept)
    tracked[c] = tr;
  }
}

}  // namespace mechanism_sim
