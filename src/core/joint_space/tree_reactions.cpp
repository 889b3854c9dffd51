// Reactions of the tree joints in the joint formulation (tree_reactions.h).
//
// The pass works in the seed's absolute coordinates, per moving body b: a generalized force
// [f (global); n' (body b)] at the centre of mass, the accelerations of State::acc [r_ddot
// (global); w_dot' (body)] (which the joint stepper writes from q_ddot: bodyAccelerations,
// the RNEA's outward pass) and the body's mass matrix M_b = diag(m_b 1, J'_b). Q_b already
// holds the Euler term -w' x J' w' (appliedForces), so Newton-Euler for the body reads
// M_b a_b = Q_b + (constraint forces on b), RBDA's f^B_i - f^x_i in these coordinates.
#include "core/joint_space/tree_reactions.h"

#include <algorithm>
#include <cmath>

#include <Eigen/LU>

namespace mechanism_sim {

TreeReactionWorkspace::TreeReactionWorkspace(const System& sys)
    : ev(sys), context(initialState(sys)), load(sys.nb, Vector6d::Zero()), tree(sys.numConstraints(), 0) {
  std::fill(context.dropped.begin(), context.dropped.end(), 0);
}

void treeJointMultipliers(const System& sys, const TreeModel& model, const State& s, const Inputs& in,
                          TreeReactionWorkspace& w, Eigen::VectorXd& lambda) {
  // 1. s's kinematics and every equation, dependent ones too (their Jacobians carry the
  //    closures' forces and the joints' rows the solve below needs), and Q
  State& ctx = w.context;
  ctx.tracked = s.tracked, ctx.limit_side = s.limit_side, ctx.drive = s.drive, ctx.t = s.t;
  Evaluation& ev = w.ev;
  loadKinematics(sys, s.x.data(), s.u.data(), ev);
  evaluateConstraints(sys, ctx, ev);
  appliedForces(sys, s, in, sys.damping, s.friction, ev);
  // 2. every body's load besides its tree joint: Q_b and the closures' -Phi_x,b^T lambda
  //    (seed: the reaction generalized force of a constraint is -Phi_q^T lambda)
  for (int k = 0; k < sys.nb; ++k) w.load[k] = ev.Q.segment<6>(BodyCoordinates::u(k));
  std::fill(w.tree.begin(), w.tree.end(), 0);
  for (int j = 0; j < sys.numJoints(); ++j)
    if (model.joint_link[j] >= 0) w.tree[sys.joint_constraint[j]] = 1;
  // couplers the tree holds (TreeLink::tie): solved below, at their slaves' links
  for (int k : model.ties) w.tree[model.links[k].tie_coupler] = 1;
  w.tie_effort.assign(model.nb, 0.0), w.tie_x.assign(model.nb, 0.0), w.tie_col.assign(model.nb, 0.0);
  for (int c = 0; c < sys.numConstraints(); ++c) {
    if (w.tree[c]) continue;  // a tree joint: solved below
    const ConstraintLayout& L = sys.layout[c];
    bool any = false;
    for (int e = 0; e < L.size; ++e) any = any || lambda[L.row + e] != 0.0;
    if (!any) continue;  // (a free limit)
    forEachBlock(sys, ev, c, [&](int, int moving, const auto& Jb) {
      w.load[moving].noalias() -= Jb.topRows(L.size).transpose() * lambda.segment(L.row, L.size);
    });
  }
  //    and the rotors' -G^T B G a (transmission.h; their G^T B gamma is in Q)
  if (!sys.rotors.empty()) {
    Eigen::VectorXd Ba = Eigen::VectorXd::Zero(sys.n);
    addRotorMass(sys, ev, s.acc.data(), Ba.data());
    for (int k = 0; k < sys.nb; ++k) w.load[k] -= Ba.segment<6>(BodyCoordinates::u(k));
  }
  // 3. leaves first (RBDA table 5.1's inward loop): the wrench F_b the tree joint applies
  //    to body b is what b's motion needs beyond its load,
  //      F_b = M_b a_b - load_b,
  //    and the joint applies -F_b to the parent (the same line of action: a joint's rows
  //    on its two bodies are equal and opposite wrenches), moved to the parent's centre
  //    of mass and components (RBDA's X^T f), as part of the parent's load.
  const double Lscale = sys.length_scale;
  double worst_tau = 0.0, largest = 0.0;
  Row rows[kMaxJointDofs];
  for (auto it = model.order.rbegin(); it != model.order.rend(); ++it) {
    const int b = *it, k = b - 1;
    const TreeLink& link = model.links[k];
    const Body& B = sys.bodies[b];
    const double* a = s.acc.data() + BodyCoordinates::u(k);
    Vector6d F;
    F.head<3>() = B.m * Eigen::Map<const Vector3d>(a);
    F.tail<3>() = B.Jp * Eigen::Map<const Vector3d>(a + 3);
    F -= w.load[k];
    if (link.parent != 0) {
      const BodyKin &kb = ev.kin[b], &kp = ev.kin[link.parent];
      const Vector3d f = F.head<3>();
      const Vector3d n_p = kb.A_Oi * F.tail<3>() + (kb.r - kp.r).cross(f);  // about the parent's centre, global
      Vector6d& lp = w.load[link.parent - 1];
      lp.head<3>() -= f;
      lp.tail<3>() -= kp.A_Oi.transpose() * n_p;
    }
    if (link.joint < 0) continue;  // a free body: nothing transmits (F is round-off)
    // 4. F_b = -Phi_x,b^T lambda + q_x,b^T tau on the joint's slot of b (body i when the
    //    link runs from the joint's body j: reversed), solved for (lambda, tau): the
    //    columns span every wrench (constraint forces and the coordinates' efforts are
    //    complementary), so the solve is exact. Torque rows over the length scale, so the
    //    pivoting weighs forces and torques alike (then partial pivoting suffices: full
    //    pivoting gives the same reactions in test_tree_reactions.cpp for a factorization
    //    about twice as long).
    const Joint& J = *link.ptr;
    const int slot = link.reversed ? 0 : 1;
    const int ci = sys.joint_constraint[link.joint];
    const ConstraintLayout& L = sys.layout[ci];
    const int dof = J.dof();
    J.coordinates(ev.kin[J.bodyI()], ev.kin[J.bodyJ()], s.tracked[ci], rows);
    Matrix6d A;
    A.leftCols(L.size) = -ev.J[ci].block(0, 6 * slot, L.size, 6).transpose();
    for (int d = 0; d < dof; ++d) A.col(L.size + d) = rows[d].J.segment<6>(6 * slot).transpose();
    A.bottomRows<3>() /= Lscale;
    Vector6d rhs = F;
    rhs.tail<3>() /= Lscale;
    const Vector6d x = Eigen::PartialPivLU<Matrix6d>(A).solve(rhs);
    lambda.segment(L.row, L.size) = x.head(L.size);
    // A held coupler q_s = r q_m + o (TreeLink::tie) acts as efforts -lambda along q_s and
    // r lambda along q_m (couplers.h), left out of the loads: the slave's joint transmits
    // -lambda along its coordinate beyond the applied efforts, which gives lambda, and the
    // master's r lambda (the transmitted wrenches are what the loads would have made them).
    Vector6d x_rest = x;
    if (link.tie_coupler >= 0) {  // (a slave; its master's link comes later, an ancestor or a sibling's)
      const double lc = -x(L.size);
      lambda[sys.layout[link.tie_coupler].row] = lc;
      w.tie_effort[link.tie] += link.tie_mult * lc;
      x_rest(L.size) = 0.0;
    } else if (link.tie_master || link.tie == k) {  // a master: judged below, its slaves all done
      w.tie_x[k] = x(L.size), w.tie_col[k] = A.col(L.size).norm();
      x_rest(L.size) = 0.0;
    }
    if (dof > 0) worst_tau = std::max(worst_tau, (A.rightCols(dof) * x_rest.tail(dof)).norm());
    largest = std::max(largest, rhs.norm());
  }
  for (int k = 0; k < model.nb; ++k)
    if (model.links[k].tie_master || model.links[k].tie == k)
      worst_tau = std::max(worst_tau, std::fabs(w.tie_x[k] - w.tie_effort[k]) * w.tie_col[k]);
  w.worst_effort = largest > 0.0 ? worst_tau / largest : 0.0;
}

}  // namespace mechanism_sim
