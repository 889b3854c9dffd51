// The closures' solves (loop_closure.h): M^-1 G^T by articulated-body passes, the
// factorization of G M^-1 G^T and its least-norm solve, and constrained forward dynamics
// (Featherstone, RBDA 2008, 8.3, "method 2").
#include <algorithm>
#include <cmath>

#include "core/joint_space/loop_closure.h"

namespace mechanism_sim {

void LoopClosures::rowsTimes(const Eigen::MatrixXd& R, const Eigen::VectorXd& v, Eigen::VectorXd& out) const {
  for (int e = 0; e < m; ++e) {
    if (reuse_.rows_of[cl_of_[e]] == RowsOf::kZero && &R == &G) {  // (a free limit's row: 0)
      out(e) = 0.0;
      continue;
    }
    double s = 0.0;
    const double* r = R.data() + e;  // (row e: stride R.rows())
    const Eigen::Index ld = R.rows();
    for (int k : ccols_[cl_of_[e]]) s += r[k * ld] * v(k);
    out(e) = s;
  }
}

bool LoopClosures::rowsTransposeTimes(const Eigen::MatrixXd& R, const Eigen::VectorXd& x, Eigen::VectorXd& out) const {
  out.setZero();
  bool any = false;
  for (int e = 0; e < m; ++e) {
    if (x(e) == 0.0) continue;
    any = true;
    for (int k : ccols_[cl_of_[e]]) out(k) += R(e, k) * x(e);
  }
  return any;
}

void LoopClosures::inverseMassRowsT(const TreeModel& model, const TreeWorkspace& ws, const Eigen::MatrixXd& R,
                                    const Eigen::VectorXd& x, Eigen::VectorXd& out) {
  bool any = false;
  for (int e = 0; e < m && !any; ++e) any = x(e) != 0.0;
  if (!any) {
    out.setZero();
    return;
  }
  const ClosureSolver* rows = &R == &G ? &factors_.solver : &R == &passage_.R ? &passage_.solver : nullptr;
  if (rows && rows->inwardOfRowsT(x, out.data())) {
    outwardInverseMass(model, ws, out.data());
    return;
  }
  rowsTransposeTimes(R, x, scratch_.tau);
  applyInverseMass(model, ws, scratch_.tau.data(), out.data());
}

void LoopClosures::inverseMassGT(const Eigen::VectorXd& x, Eigen::VectorXd& out) const {
  if (rowsTransposeTimes(G, x, out)) factors_.mass.solve(out.data());  // (x = 0: every row dropped, the mass perhaps not factored)
}

// M^-1 tau: the articulated-body algorithm's passes 2 and 3 (RBDA table 7.1) with v = 0
// (c = 0) and no external force, on the factors U, D^-1 of ws: the inverse-mass
// application of RBDA 8.3.
void LoopClosures::applyInverseMass(const TreeModel& model, const TreeWorkspace& ws, const double* tau, double* out) {
  for (int k = 0; k < model.nb; ++k) scratch_.pa[k].setZero();
  if (!model.ties.empty() && tau != out) {  // (ties: in place, inverseMassInward)
    std::copy(tau, tau + model.nv, out);
    tau = out;
  }
  for (int n = model.nb - 1; n >= 0; --n) inverseMassInward(model, ws, model.order[n] - 1, tau, out, scratch_.pa);  // u kept in out
  outwardInverseMass(model, ws, out);
}

void LoopClosures::outwardInverseMass(const TreeModel& model, const TreeWorkspace& ws, double* out) {
  articulatedOutward<false>(
      model, ws, [&](int k) { return Eigen::Map<const SmallVector>(out + model.links[k].iv, model.links[k].nv); },
      [&](int k) { return out[model.links[k].pivot]; }, out, scratch_.a);
}

long LoopClosures::massFactorsGeneration(const TreeWorkspace& ws) { return ws.generation; }

void LoopClosures::factor(const TreeModel& model, const TreeWorkspace& ws, bool form_Y) {
  info.rows = allRows();
  if (m == 0) {
    info.rank = 0;
    info.dependent = idle_;
    return;
  }
  // (G, Gabs and the articulated factors as at the last factorization: it stands)
  const long ws_gen = massFactorsGeneration(ws);
  if (reuse_.fac_at_g == reuse_.g_gen && reuse_.fac_at_ws == ws_gen && (reuse_.fac_Y || !form_Y)) {
    info = reuse_.fac_info;
    return;
  }
  factorNow(model, ws);
  if (form_Y && !factors_.all_zero) formY(model, ws);
  reuse_.fac_at_g = reuse_.g_gen, reuse_.fac_at_ws = ws_gen, reuse_.fac_Y = form_Y, reuse_.fac_info = info;
}

void LoopClosures::factorNow(const TreeModel& model, const TreeWorkspace& ws) {
  // Rows whose entries are all round-off against their terms are structurally zero (a
  // planar loop's out-of-plane rows): dropped, with lambda 0 there.
  int zero_rows = 0;
  for (int e = 0; e < m; ++e) {
    const bool zero = roundoffRow(e);
    factors_.keep(e) = zero ? 0.0 : 1.0;
    zero_rows += zero;
  }
  if (zero_rows == m) {  // every row zero (free limits): nothing to solve, lambda = 0
    Y.setZero();
    info.rank = 0;
    info.dependent = allRows();
    factors_.all_zero = true;
    return;
  }
  factors_.all_zero = false;
  // G M^-1 G^T from the factored joint-space inertia, sparse where the closures are
  // (closure_solver.h)
  info.rank = factors_.solver.factor(model, ws, G, factors_.keep, factors_.least_norm, factors_.A) - zero_rows;
  info.dependent = allRows() - info.rank;  // (idle rows count as dependent ones: no motion moves them)
}

void LoopClosures::formY(const TreeModel& model, const TreeWorkspace& ws) {
  for (int e = 0; e < m; ++e) {
    if (!factors_.solver.kept(e)) {
      Y.col(e).setZero();
      continue;
    }
    for (int k = 0; k < nv; ++k) scratch_.tau(k) = G(e, k);
    applyInverseMass(model, ws, scratch_.tau.data(), Y.col(e).data());
  }
}

void LoopClosures::solve(const Eigen::VectorXd& b, Eigen::VectorXd& x) const {
  if (m == 0) return;
  if (factors_.all_zero) {
    x.setZero();
    return;
  }
  factors_.solver.solve(factors_.least_norm, b, x);
}

// RBDA 8.3: q_ddot = q_ddot_free - M^-1 G^T lambda with (G M^-1 G^T) lambda =
// G q_ddot_free - gamma_q (the seed's sign: M a + Phi_q^T lambda = Q).
ClosureSolveInfo constrainedForwardDynamics(const TreeModel& model, const System& sys, LoopClosures& cl,
                                            const Eigen::VectorXd& q, const Eigen::VectorXd& qdot,
                                            const Eigen::VectorXd& tau, TreeWorkspace& ws, Eigen::VectorXd& qddot,
                                            const Inputs* loads, bool evaluated, const ClosureSolveMode& mode) {
  // (evaluated: ws's kinematics and the closures' evaluation are at (q, q_dot) already, as
  // the stepper's projections leave them when they move nothing)
  if (evaluated) forwardDynamicsAtKinematics(model, sys, tau, ws, qddot, loads);
  else forwardDynamics(model, sys, q, qdot, tau, ws, qddot, loads);
  // efforts on cut joints: q_ddot += M^-1 (q_x,k J)^T tau_k (the recursion is linear in tau)
  if (loads && !model.cut_joints.empty()) {
    cl.scratch_.tau.setZero();
    if (cl.addCutJointEfforts(model, sys, ws, *loads, cl.scratch_.tau)) {
      cl.applyInverseMass(model, ws, cl.scratch_.tau.data(), cl.scratch_.qdd_cut.data());
      qddot += cl.scratch_.qdd_cut;
    }
  }
  if (cl.m == 0) return cl.info;
  if (cl.allFreeLimits()) {  // (zero rows: nothing acts)
    cl.clearRows();
    return cl.info;
  }
  if (!evaluated) cl.evaluate(model, sys, ws, q);
  // (held directions across this motion: branch_passage.cpp)
  const bool passage = mode.passage_ref && cl.findPassage(mode.passage_hold, &qdot);
  if (!passage || mode.regular_factor) cl.factor(model, ws, mode.form_Y);
  if (passage) {
    // a branch passage (branch_passage.cpp): the regular directions by their equations,
    // the held ones at passage_ref's acceleration across the branch
    if (!mode.regular_factor) cl.info = ClosureSolveInfo{cl.allRows(), cl.passage_.r, cl.allRows() - cl.passage_.r};
    cl.passageFactor(model, ws);
    cl.passageRhs(cl.gamma_q, cl.passage_.g, mode.passage_ref);
    cl.rowsTimes(cl.passage_.R, qddot, cl.passage_.mu);
    cl.passage_.mu -= cl.passage_.g;
    cl.passageSolve(cl.passage_.mu, cl.passage_.mu);
    cl.inverseMassRowsT(model, ws, cl.passage_.R, cl.passage_.mu, cl.scratch_.qdd_cut);
    qddot -= cl.scratch_.qdd_cut;
    // G^T lambda = R^T mu with R = P G: lambda = P^T mu per closure row
    cl.passageMultipliers(cl.passage_.mu);
    cl.rowsTimes(cl.G, qddot, cl.gamma_q);
    return cl.info;
  }
  cl.rowsTimes(cl.G, qddot, cl.lambda);  // (the right-hand side, solved in place)
  cl.lambda -= cl.gamma_q;
  cl.solve(cl.lambda, cl.lambda);
  cl.inverseMassRowsT(model, ws, cl.G, cl.lambda, cl.scratch_.qdd_cut);
  qddot -= cl.scratch_.qdd_cut;
  cl.rowsTimes(cl.G, qddot, cl.gamma_q);  // G q_ddot = gamma_q for the result
  return cl.info;
}

}  // namespace mechanism_sim
