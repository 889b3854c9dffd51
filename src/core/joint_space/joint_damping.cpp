// The joint formulation's damping (joint_damping.h): which damped coordinates are stiff
// at the step (classify, against the integrator's stability bound), their
// constrained inverse mass, and the implicit integration of the stiff ones.
#include <algorithm>
#include <cmath>

#include <Eigen/Cholesky>

#include "core/joint_space/joint_damping.h"
#include "core/absolute/evaluation.h"
#include "core/damping/stiff_damping_rule.h"
#include "core/numerics.h"
#include "mechanism_sim/core/model/errors.h"

namespace mechanism_sim {

void JointDamping::set(const System& sys) {
  kin_.assign(sys.bodies.size(), BodyKin());
  damped_.clear();
  cut_damped_.clear();
  for (const TreeLink& L : model_.links) {
    if (L.joint < 0) continue;
    for (int k = 0; k < L.nv; ++k)
      if (sys.damping[L.joint][k] > 0.0) damped_.push_back({L.joint, k, L.iv + k, sys.damping[L.joint][k], L.axis == AxisMotion::kTurn});
  }
  for (int j : model_.cut_joints)
    for (int k = 0; k < sys.joints[j]->dof(); ++k)
      if (sys.damping[j][k] > 0.0 && (cut_damped_.empty() || cut_damped_.back() != j)) cut_damped_.push_back(j);
  const int nd = static_cast<int>(damped_.size());
  paths_.link_of_v.assign(model_.nv, 0);
  for (int k = 0; k < model_.nb; ++k)
    for (int i = 0; i < model_.links[k].nv; ++i) paths_.link_of_v[model_.links[k].iv + i] = k;
  paths_.damped_of_v.assign(model_.nv, -1);
  paths_.links.assign(nd, {});
  paths_.coords.assign(nd, {});
  for (int i = 0; i < nd; ++i) {
    paths_.damped_of_v[damped_[i].iv] = i;
    // (a master's coordinate eliminated at a common ancestor, TreeLink::pivot, is listed
    // there, not at the master's own link: every path through that ancestor has it in the
    // same place, so the shared coordinates below stay each path's tail)
    for (int k = paths_.link_of_v[damped_[i].iv];; k = model_.links[k].parent - 1) {
      const TreeLink& L = model_.links[k];
      paths_.links[i].push_back(k);
      if (L.pivot >= 0) paths_.coords[i].push_back(L.pivot);
      if (!(L.tie >= 0 && L.iv == model_.links[L.tie].iv))
        for (int v = 0; v < L.nv; ++v) paths_.coords[i].push_back(L.iv + v);
      if (L.parent == 0) break;
    }
  }
  // the coordinates two paths share are their common ancestors', the tail of each path
  paths_.shared.clear();
  paths_.shared_first.assign(nd + 1, 0);
  for (int k = 0; k < nd; ++k) {
    paths_.shared_first[k] = static_cast<int>(paths_.shared.size());
    for (int l = 0; l < nd; ++l) {
      const std::vector<int>& pl = paths_.coords[l];
      const std::vector<int>& pk = paths_.coords[k];
      int from = static_cast<int>(pl.size());
      while (from > 0 && std::find(pk.begin(), pk.end(), pl[from - 1]) != pk.end()) --from;
      if (from < static_cast<int>(pl.size())) paths_.shared.push_back({l, from});
    }
  }
  paths_.shared_first[nd] = static_cast<int>(paths_.shared.size());
  damp_Zd_.setZero(model_.nv, nd), damp_Xd_.setZero(model_.nv, nd);  // (zero off each path, always)
  damp_Minv_.setZero(nd, nd);
  damp_Yd_.setZero(nd, closures_.m), damp_W_.setZero(nd, closures_.m);
  damp_W_lo_.assign(closures_.m, 0), damp_W_hi_.assign(closures_.m, 0);
  damp_used_.reserve(closures_.m);
  damp_x_.setZero(model_.nv);
  damp_col_.setZero(nd);
  damp_filter_.assign(nd, 0.0);
  damp_rcb_.assign(nd, 0.0);
  body_inverse_.clear();  // (classify's bound: the bodies' inverses once)
  for (const Body& B : sys.bodies) body_inverse_.push_back(bodyInverse(B));
  damp_p_.assign(model_.nb, Vector6d::Zero());
  damp_mark_.assign(model_.nb, 0);
  damp_links_.reserve(model_.nb);
  damp_touched_.assign(nd, 0);
  damp_column_of_.assign(nd, -1);
  damp_direct_.assign(closures_.m, 0);
  damp_nz_.reserve(static_cast<size_t>(closures_.m) * model_.nv);
  damp_nz_first_.assign(closures_.m + 1, 0);
  damp_candidates_.reserve(nd);
  damp_need_.reserve(nd);
  stiff_.assign(nd, 0);
  quiet_h_ = quiet_bound_ = std::nan("");
  stiff_list_.reserve(nd);
  implicit_.Y.setZero(model_.nv, nd);
  implicit_.K.setZero(nd, nd);
  damp_e_.setZero(model_.nv), implicit_.z.setZero(nd), implicit_.du.setZero(model_.nv);
  implicit_.zero.setZero(model_.nv), implicit_.qdd.setZero(model_.nv), implicit_.tau.setZero(model_.nv);
  implicit_.v.assign(model_.nb, Vector6d::Zero());
  implicit_.w.setZero(nd), implicit_.c.setZero(model_.nv);
  implicit_.Z.setZero(model_.nv, closures_.m), implicit_.AW.setZero(closures_.m, closures_.m);
  damp_r_.setZero(closures_.m), damp_mu_.setZero(closures_.m);
  implicit_.least_norm = ScaledLeastNorm(closures_.m);
  implicit_.f.assign(model_.nb, Vector6d::Zero());
  damp_rows_.assign(kMaxJointDofs, Row());
}


BodyInverse bodyInverse(const Body& B) {
  BodyInverse out;
  if (B.m > 0.0) out.inv_m = 1.0 / B.m;
  const Eigen::LLT<Matrix3d> llt(B.Jp);
  if (llt.info() == Eigen::Success && llt.matrixLLT().diagonal().minCoeff() > 0.0) {
    out.inv_J = llt.solve(Matrix3d::Identity());
    out.has_J = true;
  }
  return out;
}

double coordinateInverseMassBound(const Joint& J, const Row& row, const BodyInverse& bi, const BodyInverse& bj) {
  // (M^-1)_kk = 1 / min { x^T M x : x_k = 1 } for M SPD (the minimum is taken at
  // x = M^-1 e_k / (M^-1)_kk). x^T M x is twice the kinetic energy, sum_b u_b^T M_b u_b over
  // the bodies' velocities u = J(q) x (u_b = [v; omega'], M_b = diag(m, J'): the bodies' own
  // masses and central inertias, of which the tree's are composed), and x_k = row u (the
  // coordinate's rate is its row times the bodies' velocities: settle() reads q_dot so). Leaving
  // out every condition on u but row u = 1 (that the joints hold the bodies together, that u
  // comes from joint rates) and the energies of all bodies but the row's two can only lower
  // the minimum:
  //   min { x^T M x : x_k = 1 } >= min { sum_{b = i, j} u_b^T M_b u_b : row u = 1 } = 1 / (row M_b^-1 row^T),
  // so (M^-1)_kk <= row M_b^-1 row^T = sum_b |g_b,r|^2 / m_b + g_b,theta J'_b^-1 g_b,theta^T.
  // (System::Minv is not used: its stand-ins raise every moment, which would make the bound
  // fall short by up to 1e-3.) A body the row moves where it has no mass or no inertia (a
  // massless link) leaves the minimum at 0: no bound.
  double sum = 0.0;
  for (int slot = 0; slot < 2; ++slot) {
    if ((slot == 0 ? J.bodyI() : J.bodyJ()) == System::kGround) continue;
    const BodyInverse& inv = slot == 0 ? bi : bj;
    const Vector3d gr = row.J.segment<3>(6 * slot).transpose(), gt = row.J.segment<3>(6 * slot + 3).transpose();
    if (!gr.isZero(0.0)) sum += gr.squaredNorm() * inv.inv_m;
    if (!gt.isZero(0.0)) {
      if (!inv.has_J) return HUGE_VAL;
      sum += gt.dot(inv.inv_J * gt);
    }
  }
  return std::isfinite(sum) ? sum : HUGE_VAL;
}

double coordinateInverseMassBound(const System& sys, const Joint& J, const Row& row) {
  return coordinateInverseMassBound(J, row, bodyInverse(sys.bodies[J.bodyI()]), bodyInverse(sys.bodies[J.bodyJ()]));
}

// Which damped coordinates are stiff at this step, by stiff_damping.cpp's rule (see there):
// s_k = h sum_l sqrt(c_k c_l) |P_lk| over the damped coordinates l (Gershgorin on
// h C^1/2 P C^1/2, the damped modes' decay rates; P the constrained inverse mass), stiff
// above the tableau's stiff_bound. Three tests, cheapest first:
//  1. An upper bound on every s_k at once, from a bound beta_l >= (M^-1)_ll per damped
//     coordinate (coordinateInverseMassBound; for a revolute joint independent of the
//     configuration, so kept): P is positive semidefinite and P <= M^-1 (the closures'
//     term M^-1 G^T (G M^-1 G^T)^+ G M^-1 is positive semidefinite), so
//        |P_lk| <= sqrt(P_ll P_kk) <= sqrt((M^-1)_ll (M^-1)_kk) <= sqrt(beta_l beta_k),
//        s_k <= h sqrt(c_k beta_k) sum_l sqrt(c_l beta_l) =: u_k.
//     A coordinate with u_k within stiff_bound is not stiff (the heavy links of a 7-dof
//     arm: there nothing more is computed).
//  2. Else the absolute formulation's bound with the joint's own damped coordinates, the
//     rows on their two bodies and System::Minv: a filter, not a bound (it leaves out the
//     other joints' terms), so only where it is below stiff_bound / 4 is the coordinate
//     taken as not stiff (it finds the same stiff coordinates as 3. would).
//  3. Else P_lk itself, at the damped l only (dampedInverseMass: O(depth) an entry, where a
//     column of P costs passes over the tree).
// (1. decides only where 3. would decide the same: u_k >= s_k.)
//
// The set found is held for the next steps (s.damping_hold), as stiff solvers keep their
// Jacobian over steps while it serves (Hairer & Wanner, "Solving ODEs II", IV.8): for at
// most kHoldSteps, while no body has turned by more than kHoldMotion rad or moved by more
// than kHoldMotion of the length scale from where it was found, under the same step, bound
// and limit sides. Only where every coordinate's h s_k was at least kHoldMargin away from
// the bound (above or below), and ln(h s_k) changed since the classification before at a
// pace that over kHoldMotion would cover at most half its distance to ln(bound): P is a
// smooth function of the configuration, but a nearly singular mass matrix (a light link
// carrying a heavy one) can make it change by half within 0.2 rad, so the pace is
// measured, not assumed. A coordinate near the bound, or nearing it fast, is classified
// again every step. A set held gives the stages every bit the classification itself would
// have given them (the test HeldClassificationSwitchesWhereEachStepsWould), and one whose
// s_k crossed the bound unseen would still be stable: RK4's limit, 2.785, is 1.39 times its
// bound of 2.
namespace {
using numerics::joint_space::kHoldSteps;
using numerics::joint_space::kHoldMotion;
using numerics::joint_space::kHoldMargin;

// How far the bodies are from their positions x0 (State::x): the largest of |r - r0| / L
// and 2 |p - p0| (the rotation angle to first order; a quaternion's sign flip counts as far).
double motionSince(const System& sys, const Eigen::VectorXd& x0, const Eigen::VectorXd& x) {
  double d = 0.0;
  for (int b = 0; b < sys.nb; ++b) {
    const int o = BodyCoordinates::x(b);
    d = std::max({d, (x.segment<3>(o) - x0.segment<3>(o)).norm() / sys.length_scale,
                  2.0 * (x.segment<4>(o + 3) - x0.segment<4>(o + 3)).norm()});
  }
  return d;
}
}  // namespace

bool JointDamping::classify(const System& sys, State& s, double h, const Tableau& tableau) {
  const double bound = tableau.stiff_bound;
  const int nd = static_cast<int>(damped_.size());
  // (no coordinate can be stiff under this step and bound, wherever the tree is: the last
  // classification cleared every one by bounds that do not change with the configuration)
  if (!readsState(h, tableau)) return false;
  State::DampingHold& hold = s.damping_hold;
  // (whether the hold was found under this step, bound and limit sides, and how far the
  // bodies have moved since: both for holding it and for the pace below)
  const bool before = hold.rate.size() == static_cast<size_t>(nd) && hold.stiff.size() == static_cast<size_t>(nd) &&
                      hold.h == h && hold.bound == bound && hold.limit_side == s.limit_side &&
                      hold.x.size() == s.x.size();
  const double moved = before ? motionSince(sys, hold.x, s.x) : 0.0;
  if (before && hold.left > 0 && moved <= kHoldMotion) {
    --hold.left;
    bool changed = false;
    stiff_list_.clear();
    for (int i = 0; i < nd; ++i) {
      if (stiff_[i] != hold.stiff[i]) changed = true;
      stiff_[i] = hold.stiff[i];
      if (stiff_[i]) stiff_list_.push_back(i);
    }
    return changed;
  }
  bool kinematics = false;
  damp_candidates_.clear();
  double spread = 0.0;  // sum_l sqrt(c_l beta_l) (1.)
  for (int i = 0; i < nd; ++i) {
    Damped& d = damped_[i];
    const Joint& J = *sys.joints[d.j];
    double sum = d.bound;  // the filter (2.): sum over the damped coordinates of the same joint
    double beta = d.beta;
    if (sum < 0.0) {
      if (!kinematics) loadKinematics(sys, s.x.data(), s.u.data(), kin_), kinematics = true;
      J.coordinates(kin_[J.bodyI()], kin_[J.bodyJ()], s.tracked[J.id()], damp_rows_.data());
      sum = stiff_damping::decayRate(1.0, d.c, [&](auto add) {
        for (const Damped& o : damped_) {
          if (o.j != d.j) continue;
          for (int slot = 0; slot < 2; ++slot) {
            const int b = slot == 0 ? J.bodyI() : J.bodyJ();
            if (b == System::kGround) continue;
            add(o.c, stiff_damping::bodyInverseMass(damp_rows_[d.k].J.segment<6>(6 * slot),
                                                    damp_rows_[o.k].J.segment<6>(6 * slot), sys.Minv[b - 1]));
          }
        }
      });
      beta = coordinateInverseMassBound(J, damp_rows_[d.k], body_inverse_[J.bodyI()], body_inverse_[J.bodyJ()]);
      if (d.revolute) d.bound = sum, d.beta = beta;
    }
    damp_filter_[i] = sum;
    damp_rcb_[i] = std::sqrt(d.c * beta);
    spread += damp_rcb_[i];
  }
  // (u_k NaN or infinite: no bound. 1 - 1e-9: where u_k = s_k, as for a body turning about
  // a principal axis through its centre on the ground, the two may differ by round-off.)
  const double below = bound * (1.0 - 1e-9);
  // (the set may be held: every coordinate kHoldMargin from the bound, changing slowly)
  bool margin = true;
  hold.rate.resize(nd);
  for (int i = 0; i < nd; ++i) {
    const double upper = h * damp_rcb_[i] * spread, filter = h * damp_filter_[i];
    if (!(upper <= below) && filter > bound / 4) {
      damp_candidates_.push_back(i);
      continue;
    }
    margin = margin && (upper <= bound / kHoldMargin || filter <= bound / (4 * kHoldMargin));
    hold.rate[i] = std::nan("");  // (no exact rate: the margin is the bound's or the filter's)
  }
  if (!damp_candidates_.empty()) dampedInverseMass();
  bool changed = false;
  stiff_list_.clear();
  for (int i = 0, next = 0; i < nd; ++i) {
    bool stiff = false;
    if (next < static_cast<int>(damp_candidates_.size()) && damp_candidates_[next] == i) {
      // P e_k at the damped coordinates: with closures, P = M^-1 - M^-1 G^T (G M^-1 G^T)^+
      // G M^-1 (the absolute formulation's P): a finger coupled to its hand is not stiff
      // when the hand carries it. G M^-1 e_k is row k of M^-1 G^T.
      damp_col_ = damp_Minv_.col(next++);
      if (damp_touched_[i])  // (by columns: Eigen's product kernels cost more at these sizes)
        // (a row on other branches of the closures has Yd 0 here: skipped, the same bits;
        // so are the entries where W's column is zero, which would change at most the sign
        // of a zero entry, and |P_lk| is read)
        for (int e : damp_used_)
          if (damp_Yd_(i, e) != 0.0) {
            const int lo = damp_W_lo_[e], n = damp_W_hi_[e] - lo;
            damp_col_.segment(lo, n) -= damp_W_.col(e).segment(lo, n) * damp_Yd_(i, e);
          }
      const double rate = stiff_damping::decayRate(h, damped_[i].c, [&](auto add) {
        for (int l = 0; l < nd; ++l) add(damped_[l].c, damp_col_(l));
      });
      stiff = stiff_damping::isStiff(rate, bound);
      // the pace since the classification before, per unit of motion, of ln(rate) (below
      // 1e-3 of the bound as at it: a rate that far below is not near it, and a coordinate
      // a limit holds has a rate of round-off): kHoldMotion at that pace may use at most
      // half the distance to the bound, and that at least ln(kHoldMargin)
      const double distance = std::fabs(std::log(rate / bound)), floor = 1e-3 * bound;
      const double change =
          !before ? HUGE_VAL : std::fabs(std::log(std::max(rate, floor) / std::max(hold.rate[i], floor)));
      margin = margin && distance >= std::log(kHoldMargin) &&
               (change == 0.0 || change * kHoldMotion <= 0.5 * distance * moved);
      hold.rate[i] = rate;
    }
    if (stiff != static_cast<bool>(stiff_[i])) changed = true;
    stiff_[i] = stiff;
    if (stiff) stiff_list_.push_back(i);
  }
  // (every coordinate a revolute joint's, whose screen and filter are kept, and none a
  // candidate: none is stiff under this h and bound in any configuration)
  bool quiet = damp_candidates_.empty();
  for (const Damped& d : damped_) quiet = quiet && d.bound >= 0.0;
  quiet_h_ = quiet ? h : std::nan(""), quiet_bound_ = quiet ? bound : std::nan("");
  hold.left = margin ? kHoldSteps : 0;
  hold.stiff = stiff_, hold.x = s.x, hold.limit_side = s.limit_side, hold.h = h, hold.bound = bound;
  // (the implicit step's metric is the articulated factors' M, without a rotor's coupling)
  if (!stiff_list_.empty() && !model_.rotor_couplings.empty())
    throw SimulationError("joint-space dynamics: the damping of joint '" + sys.joints[damped_[stiff_list_[0]].j]->name() +
                          "' is stiff at this step and a rotor inertia couples two joints, which the implicit damping "
                          "does not take: use a smaller step or --formulation absolute");
  return changed;
}

// What classify's entries of P are made of, at ws_'s articulated factors (q0), by the
// sparse factorization of closure_solver.h (RBDA 8.5): with M = L^T D L as the
// articulated-body algorithm factors it (D_k = S_k^T I^A_k S_k, ws_.Dinv), L^-T x is its
// inward pass with zero velocity on x (inverseMassInward), which for a unit vector e_l or a
// closure row touches only the links on its paths to the root; then
//   (M^-1)_lk = z_l^T D^-1 z_k  (z_l = L^-T e_l: over the coordinates the two paths share),
//   (M^-1 G^T)_le = z_l^T D^-1 L^-T G_e^T, or sum_c G_ec (M^-1)_lc for a row on damped
//   coordinates c (a coupler's, a limit's),
// and with closures W = (M^-1 G^T)_D (G M^-1 G^T)^+ from closures_' factorization at q0
// (stage 1 ran there), so that P_Dk = (M^-1)_Dk - W (M^-1 G^T)_k^T.
void JointDamping::dampedInverseMass() {
  auto scaleByDinv = [&](int k, const double* z, double* x) {  // x = D_k^-1 z on link k
    const TreeLink& L = model_.links[k];
    if (L.pivot >= 0) x[L.pivot] = ws_.tie_Dinv[k] * z[L.pivot];  // (TreeLink::pivot)
    if (L.tie >= 0) return;  // (no pivot of its own; its entry is 0, or its master's pivot's)
    if (L.nv == 1) {
      x[L.iv] = ws_.Dinv[k](0, 0) * z[L.iv];
    } else if (L.nv > 0) {
      const SmallVector u = Eigen::Map<const SmallVector>(z + L.iv, L.nv);
      Eigen::Map<SmallVector>(x + L.iv, L.nv) = ws_.Dinv[k] * u;
    }
  };
  const int nd = static_cast<int>(damped_.size());
  for (int i = 0; i < nd; ++i) {
    double* z = damp_Zd_.col(i).data();
    for (int v : paths_.coords[i]) z[v] = 0.0;
    z[damped_[i].iv] = 1.0;
    for (int k : paths_.links[i]) damp_p_[k].setZero();
    for (int k : paths_.links[i]) inverseMassInward(model_, ws_, k, z, z, damp_p_);
    for (int k : paths_.links[i]) scaleByDinv(k, z, damp_Xd_.col(i).data());
  }
  // (M^-1)_Dk: the candidates' columns, then those of the damped coordinates that closure
  // rows on damped coordinates only touch
  damp_need_ = damp_candidates_;
  std::fill(damp_touched_.begin(), damp_touched_.end(), 0);
  std::fill(damp_column_of_.begin(), damp_column_of_.end(), -1);
  for (size_t a = 0; a < damp_need_.size(); ++a) damp_column_of_[damp_need_[a]] = static_cast<int>(a);
  const int m = closures_.m;
  damp_nz_.clear();  // per closure row its nonzero entries' coordinates (a free limit's: none)
  for (int e = 0; e < m; ++e) {
    damp_nz_first_[e] = static_cast<int>(damp_nz_.size());
    damp_direct_[e] = 1;
    for (int v : closures_.rowColumns(e))  // (G is zero off them)
      if (closures_.G(e, v) != 0.0) {
        damp_nz_.push_back(v);
        if (paths_.damped_of_v[v] < 0) damp_direct_[e] = 0;
      }
    damp_nz_first_[e + 1] = static_cast<int>(damp_nz_.size());
    if (!damp_direct_[e]) continue;
    for (int p = damp_nz_first_[e]; p < damp_nz_first_[e + 1]; ++p) {
      const int c = paths_.damped_of_v[damp_nz_[p]];
      if (damp_column_of_[c] < 0) damp_column_of_[c] = static_cast<int>(damp_need_.size()), damp_need_.push_back(c);
    }
  }
  for (size_t a = 0; a < damp_need_.size(); ++a) {
    const int k = damp_need_[a];
    // over the coordinates the two paths share (none: 0): X_k is zero off k's path, so the
    // terms left out are zeros, and the sum of the others, in the same order, has every
    // bit it had over the whole path
    damp_Minv_.col(a).setZero();
    for (int p = paths_.shared_first[k]; p < paths_.shared_first[k + 1]; ++p) {
      const int l = paths_.shared[p].l;
      const std::vector<int>& path = paths_.coords[l];
      double y = 0.0;
      for (size_t r = paths_.shared[p].from; r < path.size(); ++r) y += damp_Zd_(path[r], l) * damp_Xd_(path[r], k);
      damp_Minv_(l, a) = y;
    }
  }
  if (m == 0) return;
  // (M^-1 G^T)_D by columns: a row on damped coordinates from those columns, another by its
  // own inward pass over the links on the paths of its nonzero entries
  damp_used_.clear();
  for (int e = 0; e < m; ++e) {
    if (damp_nz_first_[e] == damp_nz_first_[e + 1]) continue;  // a zero row: reaches nothing
    damp_used_.push_back(e);
    if (damp_direct_[e]) {
      damp_Yd_.col(e).setZero();
      for (int p = damp_nz_first_[e]; p < damp_nz_first_[e + 1]; ++p) {
        const int v = damp_nz_[p];
        damp_Yd_.col(e) += closures_.G(e, v) * damp_Minv_.col(damp_column_of_[paths_.damped_of_v[v]]);
      }
      continue;
    }
    for (int p = damp_nz_first_[e]; p < damp_nz_first_[e + 1]; ++p)
      for (int k = paths_.link_of_v[damp_nz_[p]]; k >= 0 && !damp_mark_[k]; k = model_.links[k].parent - 1) damp_mark_[k] = 1;
    damp_links_.clear();
    for (auto it = model_.order.rbegin(); it != model_.order.rend(); ++it)
      if (damp_mark_[*it - 1]) damp_links_.push_back(*it - 1), damp_mark_[*it - 1] = 0;
    damp_e_ = closures_.G.row(e).transpose();
    double* z = damp_e_.data();
    damp_x_.setZero();
    for (int k : damp_links_) damp_p_[k].setZero();
    for (int k : damp_links_) inverseMassInward(model_, ws_, k, z, z, damp_p_);
    for (int k : damp_links_) scaleByDinv(k, z, damp_x_.data());
    for (int l = 0; l < nd; ++l) {
      double y = 0.0;
      for (int v : paths_.coords[l]) y += damp_Zd_(v, l) * damp_x_(v);
      damp_Yd_(l, e) = y;
    }
  }
  // only the rows that reach a damped coordinate count (a free limit's row is zero)
  size_t kept = 0;
  for (int e : damp_used_)
    if (!damp_Yd_.col(e).isZero(0.0)) damp_used_[kept++] = e;
  damp_used_.resize(kept);
  for (int l = 0; l < nd; ++l) {
    damp_touched_[l] = 0;
    for (int e : damp_used_)
      if (damp_Yd_(l, e) != 0.0) {
        damp_touched_[l] = 1;
        break;
      }
  }
  // (G M^-1 G^T)^+ by the columns of those rows (the closures' own solve: dropped rows 0,
  // least norm where rows depend), then W over them
  for (int f : damp_used_) {
    damp_r_.setZero();
    damp_r_(f) = 1.0;
    closures_.solve(damp_r_, damp_mu_);
    damp_W_.col(f).setZero();
    for (int e : damp_used_)  // (rows on other branches than f's have mu 0 exactly: skipped)
      if (damp_mu_(e) != 0.0) damp_W_.col(f) += damp_Yd_.col(e) * damp_mu_(e);
    // where the column is not zero (classify reads it there only)
    int lo = 0, hi = nd;
    while (lo < hi && damp_W_(lo, f) == 0.0) ++lo;
    while (hi > lo && damp_W_(hi - 1, f) == 0.0) --hi;
    damp_W_lo_[f] = lo, damp_W_hi_[f] = hi;
  }
}

// u' = argmin 1/2 |u' - u|_M^2 + 1/2 h sum_stiff c_k u'_k^2, i.e. (M + h E C E^T) u' = M u
// (E the stiff coordinates), by Woodbury with Y = M^-1 E (at the positions the stages
// reached) and B = E^T Y:  u' - u = -Y (C^-1 / h + B)^-1 E^T u, a small SPD solve. The
// impulse held over the step moves the positions by h (u' - u) / 2 (stiff_damping.cpp,
// items 3-4). It never adds energy: |u'|_M <= |u|_M.
void JointDamping::implicit(const System& sys, State& s, double h) {
  const int ns = static_cast<int>(stiff_list_.size());
  // Y at the positions the stages reached (the metric the kinetic energy is measured in
  // there): articulated factors at s.q, one inverse-mass pass per stiff coordinate
  forwardDynamics(model_, sys, s.q, implicit_.zero, implicit_.zero, ws_, implicit_.qdd);
  for (int a = 0; a < ns; ++a) {
    damp_e_.setZero();
    damp_e_(damped_[stiff_list_[a]].iv) = 1.0;
    closures_.applyInverseMass(model_, ws_, damp_e_.data(), implicit_.Y.col(stiff_list_[a]).data());
  }
  for (int a = 0; a < ns; ++a) {
    const int ia = stiff_list_[a];
    for (int b = 0; b < ns; ++b) implicit_.K(a, b) = implicit_.Y(damped_[ia].iv, stiff_list_[b]);
    implicit_.K(a, a) += 1.0 / (h * damped_[ia].c);
    implicit_.z(a) = s.qdot(damped_[ia].iv);
  }
  // K = C^-1 / h + E^T M^-1 E is SPD (a positive diagonal plus an inverse mass): its
  // Cholesky factor in place on the leading ns x ns block (no allocation)
  Eigen::Ref<Eigen::MatrixXd> K = implicit_.K.topLeftCorner(ns, ns);
  const Eigen::LLT<Eigen::Ref<Eigen::MatrixXd>> llt(K);
  auto solveK = [&](Eigen::VectorXd& z) { llt.solveInPlace(z.head(ns)); };  // z = K^-1 z
  solveK(implicit_.z);
  implicit_.du.setZero();
  for (int a = 0; a < ns; ++a) implicit_.du -= implicit_.Y.col(stiff_list_[a]) * implicit_.z(a);
  s.qdot += implicit_.du;
  if (closures_.m > 0) {
    // With closures (couplers, drives, active limits) the same minimum subject to
    // G u' = nu at the end of the step: u' = u_free - Z mu with Z = W^-1 G^T, W = M + h E C E^T
    // (Z = M^-1 G^T - Y K^-1 Y^T G^T by Woodbury), (G Z) mu = G u_free - nu: the absolute
    // formulation's KKT in the metric M + h G^T C G (stiff_damping.cpp, item 3).
    EvalContext ctx = s.context();
    ctx.t = s.timeAfterStep(h);
    closures_.setContext(ctx);
    closures_.evaluate(model_, sys, ws_, s.q);  // G and nu at s.q (ws_: s.q at rest)
    closures_.factor(model_, ws_, true);  // closures_.Y = M^-1 G^T
    const int m = closures_.m;
    implicit_.Z = closures_.Y;
    for (int e = 0; e < m; ++e) {
      for (int a = 0; a < ns; ++a) implicit_.w(a) = closures_.G.row(e).dot(implicit_.Y.col(stiff_list_[a]));
      solveK(implicit_.w);
      for (int a = 0; a < ns; ++a) implicit_.Z.col(e) -= implicit_.Y.col(stiff_list_[a]) * implicit_.w(a);
    }
    implicit_.AW.noalias() = closures_.G * implicit_.Z;
    damp_r_.noalias() = closures_.G * s.qdot;
    damp_r_ -= closures_.nu;
    // as the closures' own solve: zero rows (free limits) held at mu = 0, least norm for
    // dependent rows
    implicit_.least_norm.factor(implicit_.AW);
    implicit_.least_norm.solve(damp_r_, damp_mu_);
    implicit_.c.noalias() = implicit_.Z * damp_mu_;
    s.qdot -= implicit_.c;
    implicit_.du -= implicit_.c;
  }
  implicit_.du *= 0.5 * h;
  // The positions move by h (u' - u) / 2 with each body keeping its absolute velocity (v
  // global, omega' body: the absolute formulation's u, which the move leaves as they are):
  // in joint coordinates the rates are then the M-nearest to those body velocities at the
  // new positions, u'' = M(q')^-1 J(q')^T M_b V (V the bodies' velocities at (q, u'), M_b
  // their own inertias). That is a projection: the kinetic energy does not rise (keeping
  // u' itself raised it by 6e-11 a step on a light chain of a tumbling base).
  forwardKinematics(model_, s.q, s.qdot, ws_);
  for (int k = 0; k < model_.nb; ++k) {
    implicit_.v[k].head<3>() = ws_.v[k].head<3>();              // omega' (body)
    implicit_.v[k].tail<3>() = ws_.A[k] * ws_.v[k].tail<3>();   // v (global)
  }
  retract(model_, s.q, implicit_.du);
  forwardDynamics(model_, sys, s.q, implicit_.zero, implicit_.zero, ws_, implicit_.qdd);  // factors at q'
  for (int k = 0; k < model_.nb; ++k) {  // momenta at the centres, body components
    const Body& B = sys.bodies[k + 1];
    implicit_.f[k].head<3>() = B.Jp * implicit_.v[k].head<3>();
    implicit_.f[k].tail<3>() = B.m * (ws_.A[k].transpose() * implicit_.v[k].tail<3>());
  }
  implicit_.tau.setZero();
  for (auto it = model_.order.rbegin(); it != model_.order.rend(); ++it) {  // J^T f, leaves first
    const int k = *it - 1;
    const TreeLink& L = model_.links[k];
    implicit_.tau.segment(L.iv, L.nv) = ws_.S[k].transpose() * implicit_.f[k];
    if (L.parent != 0) implicit_.f[L.parent - 1] += transformForceBack(ws_.E[k], ws_.rho[k], implicit_.f[k]);
  }
  closures_.applyInverseMass(model_, ws_, implicit_.tau.data(), s.qdot.data());
}

}  // namespace mechanism_sim
