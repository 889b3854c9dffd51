// Joint damping the explicit stages cannot follow: which damped coordinates
// are stiff at this step, and the implicit Euler step that integrates them.
//
// Viscous damping tau_k = -c_k q_dot_k, q_dot_k = q_x,k u (q_x,k the coordinate's row,
// notation.h; q_x the damped coordinates' rows), decays on its own with the rates of
// P q_x^T C q_x (P the constrained inverse mass), the eigenvalues of
// S = C^1/2 q_x P q_x^T C^1/2. RK4's interval of stability on the negative real axis ends at
// h rate = 2.785 (rk3: 2.513, Heun: 2): a 1 g frame link of 1e-7 kg m^2 damped at
// 0.1 N m s/rad has h rate = 1000 at h = 1 ms, and the step explodes.
//
//  1. A bound (classifyDamping; the rule is core/damping/stiff_damping_rule.h, which the
//     joint formulation calls too). P <= M^-1 as quadratic forms (constraints only add
//     effective mass), so lambda_max(h S) <= lambda_max(h C^1/2 q_x M^-1 q_x^T C^1/2), and by
//     Gershgorin that is at most max_k s_k with
//        s_k = h sum_l sqrt(c_k c_l) sum_b |q_x,k,b M_b^-1 q_x,l,b^T|,
//     l over the damped coordinates on a body b of k's joint (k included), M_b^-1 the
//     block-diagonal inverse masses with the stand-ins of the row weights (System::Minv). A ratio of
//     like quantities: metres or millimetres give the same s_k. Where it exceeds the
//     threshold, s_k is taken again with P itself (1b.), one solve per such coordinate: a
//     light link that carries a heavy one is not stiff, its joint moves the heavy one.
//  2. Coordinates with s_k <= s* stay in the stages; any set of them has
//     h S within s* too (the rows of a principal submatrix are shorter). s* is where
//     implicit Euler, 1 / (1 + s) a step, becomes as accurate on the damped mode as the
//     explicit method's amplification R(-s) (against exp(-s)): RK4 (R = 1 - s + s^2/2 -
//     s^3/6 + s^4/24) at s = 2 (both 1/3), rk3 near 1.6, Heun (1 - s + s^2/2) at 1 (both
//     1/2). Below s* the stages are the better of the two, and stable (s* is under each
//     method's limit, 2.785, 2.513, 2); above it implicit Euler is, and stays stable where
//     the stages would explode. (A lower threshold costs accuracy and time: at s = 1
//     implicit Euler is 36 % off exp(-1) where RK4 is 2 % off, and each coordinate sent to
//     it adds a solve a step.)
//  3. The others leave the stages (forces() reads stage_damping_) and are integrated by
//     implicit Euler after them (Lie splitting of the stiff linear part, Hairer & Wanner,
//     "Solving ODEs II", IV.3 and IV.15; MuJoCo integrates joint damping implicitly the
//     same way, in the metric M + h D: documentation "Computation / Numerical
//     integration"). L-stable: their modes relax in I / c << h, so first order costs
//     nothing that shows. The velocities after the stages, u, become
//        u' = argmin 1/2 (u' - u)^T M (u' - u) + 1/2 h sum_k c_k (q_x,k u')^2,  Phi_q u' = nu,
//     i.e.  (M + h q_x^T C q_x) u' + Phi_q^T mu = M u,  Phi_q u' = nu,  the velocity
//     projection in the metric M + h q_x^T C q_x, solved as solveKKT solves (H in penalty
//     form with the extra weighted rows, refined on the exact residual). It never adds
//     energy: with nu = 0, u'^T (M + h C) u' = u'^T M u <= |u'|_M |u|_M, so |u'|_M <= |u|_M.
//  4. The impulse M (u' - u) is the damping force of implicit Euler (with its reaction)
//     held over the step; held over the step it also moves the positions, by h (u' - u) / 2.
//     Without that a light link would move with its undamped stage velocity (a load tau
//     spins it up by h tau / I within the step, h^2 tau / 2I of travel, where the damped
//     link creeps at tau / c); with it the positions advance by h (u_n + u_n+1) / 2.
#include <algorithm>
#include <cmath>
#include <sstream>
#include <string>

#include "core/absolute/stepper.h"
#include "core/damping/stiff_damping_rule.h"
#include "mechanism_sim/core/model/inertia.h"

namespace mechanism_sim {
namespace {

// The refinement's limits (numerics.h).
constexpr int kMaxPasses = numerics::absolute::kStiffPasses;
constexpr double kRoundOff = numerics::absolute::kStiffRoundOff;

using stiff_damping::Row6;

// The slot (0: body i, 1: body j) of body b in joint jt.
inline int slotOf(const Joint& jt, int b) { return jt.bodyI() == b ? 0 : 1; }

}  // namespace

void Stepper::initDamping(const System& sys) {
  const int nj = sys.numJoints();
  stage_damping_.assign(nj, {0.0, 0.0, 0.0});
  damp_rows_.assign(nj, std::array<Row, kMaxJointDofs>());
  joints_at_.assign(sys.nb, {});
  for (int j = 0; j < nj; ++j)
    for (int b : {sys.joints[j]->bodyI(), sys.joints[j]->bodyJ()})
      if (b != System::kGround) joints_at_[b - 1].push_back(j);
  stiff_.clear();
  stiff_.reserve(3 * nj);
  damp_u0_ = Eigen::VectorXd::Zero(sys.n);
  damp_b_ = Eigen::VectorXd::Zero(sys.n);
  damp_mu_ = Eigen::VectorXd::Zero(sys.m);
}

bool Stepper::classifyDamping(const System& sys, const State& s, double h) {
  split_ = false;
  stiff_.clear();
  const int nj = sys.numJoints();
  bool any = false;
  for (int j = 0; j < nj; ++j) {
    const auto& c = sys.damping[j];
    if (c[0] > 0 || c[1] > 0 || c[2] > 0) {
      jointRows(sys, ev_, s, j, damp_rows_[j].data());
      any = true;
    }
  }
  if (!any) return false;
  const double stiff = tableau_->stiff_bound;  // s_k above which a coordinate is stiff (2.)
  for (int j = 0; j < nj; ++j) {
    const Joint& jt = *sys.joints[j];
    for (int k = 0; k < jt.dof(); ++k) {
      const double c = sys.damping[j][k];
      if (!(c > 0)) continue;
      // h sum_l sqrt(c_k c_l) sum_b |q_x,k,b M_b^-1 q_x,l,b^T|  (1.)
      const double rate = stiff_damping::decayRate(h, c, [&](auto add) {
        for (int slot = 0; slot < 2; ++slot) {
          const int b = slot == 0 ? jt.bodyI() : jt.bodyJ();
          if (b == System::kGround) continue;
          const Row6 g = damp_rows_[j][k].J.segment<6>(6 * slot);
          for (int l : joints_at_[b - 1]) {
            const Joint& jl = *sys.joints[l];
            const int sl = slotOf(jl, b);
            for (int kl = 0; kl < jl.dof(); ++kl) {
              const double cl = sys.damping[l][kl];
              if (!(cl > 0)) continue;
              add(cl, stiff_damping::bodyInverseMass(g, damp_rows_[l][kl].J.segment<6>(6 * sl), sys.Minv[b - 1]));
            }
          }
        }
      });
      if (stiff_damping::isStiff(rate, stiff)) stiff_.push_back({j, k, c});
    }
  }
  if (stiff_.empty()) return false;
  // (1b.) The block-diagonal bound ignores what the joints carry: a 1 g link that carries a
  // 2 kg arm has a slow damped mode. For the coordinates it flags, the rows of S with the
  // constrained inverse mass itself, P q_x,k^T from the factored matrix (exactly on a tree's
  // KKT matrix, to 1/kappa with H; H factored at these or nearby positions: a bound needs no
  // more), Gershgorin over every damped coordinate.
  if (!solver_->factored()) solver_->factor(sys, ev_, "stage 1", s.t);
  size_t kept = 0;
  for (size_t i = 0; i < stiff_.size(); ++i) {
    const StiffRow r = stiff_[i];
    Eigen::VectorXd& Pg = solver_->dn();  // P q_x,k^T
    Pg.setZero();
    scatterRow(sys, r.joint, damp_rows_[r.joint][r.k], 1.0, Pg.data());
    solver_->applyInverseMass(sys, ev_);
    const double rate = stiff_damping::decayRate(h, r.c, [&](auto add) {
      for (int l = 0; l < nj; ++l) {
        const Joint& jl = *sys.joints[l];
        for (int kl = 0; kl < jl.dof(); ++kl) {
          const double cl = sys.damping[l][kl];
          if (cl > 0) add(cl, rowDot(sys, l, damp_rows_[l][kl], Pg.data()));
        }
      }
    });
    if (stiff_damping::isStiff(rate, stiff)) stiff_[kept++] = r;
  }
  stiff_.resize(kept);
  // A stiff coordinate whose motor damping couples it with another (RotorInertia::
  // damping_coupling, explicit in forces()) would diverge under the explicit stages: the
  // implicit step takes the diagonal only. The run stops saying so.
  for (const StiffRow& r : stiff_)
    for (const RotorInertia& R : sys.rotors) {
      if (R.damping_coupling == 0.0 || R.coords.size() < 2) continue;
      for (int c = 0; c < 2; ++c)
        if (R.coords[c].first == r.joint && R.coords[c].second == r.k)
          throw SimulationError("the damping of joint '" + sys.joints[r.joint]->name() +
                                "' is stiff at this step and the motors' damping couples it with joint '" +
                                sys.joints[R.coords[1 - c].first]->name() +
                                "', which the implicit damping does not take: use a smaller step");
    }
  split_ = !stiff_.empty();
  if (split_) {
    stage_damping_ = sys.damping;
    for (const StiffRow& r : stiff_) stage_damping_[r.joint][r.k] = 0.0;
    split_h_ = h;
  }
  return split_;
}

// (3.) and (4.) at the positions after the stages (kin_ loaded and J_ evaluated there).
void Stepper::implicitDamping(const System& sys, State& s, double h) {
  // The stiff coordinates' rows q_x,k at these positions (damp_rows_ holds those of the
  // step's start), then H + h sum_k c_k q_x,k^T q_x,k over the bodies of each one's joint.
  for (const StiffRow& r : stiff_) jointRows(sys, ev_, s, r.joint, damp_rows_[r.joint].data());
  rowWeights(sys, ev_, sys.all_constraints);
  PenaltyForm& H = solver_->penalty();
  H.assemble(sys, ev_, ConstraintSolver::kKappa, 1.0, 0.0);
  for (int b = 1; b <= sys.nb; ++b) {  // singular mass blocks, as PenaltyForm::factor (massFloor)
    const Body& B = sys.bodies[b];
    const Vec6 floor = massFloor(B.m, B.Jp, sys.Minv[b - 1].diagonal().cwiseInverse(), sys.mass_scale, sys.inertia_scale);
    bool transposed = false;
    if (!floor.isZero(0.0)) H.cholesky().block(H.cholesky().address(b - 1, b - 1, &transposed)).diagonal() += floor;
  }
  for (const StiffRow& r : stiff_)
    H.addRows(sys, sys.joint_constraint[r.joint], damp_rows_[r.joint][r.k].J, h * r.c);
  ++stats_.factorizations;
  if (H.factorize(0.0, false) != 0) {
    std::ostringstream os;
    os << "at t = " << s.t << " s (implicit damping): the constrained mass matrix is singular; some motion moves no mass";
    throw SimulationError(os.str());
  }
  solver_->usePenalty(false);  // not H of the equations alone: whoever needs H factors it
  // Refinement of [M + hC, Phi_q^T; Phi_q, 0] [u'; mu] = [M u; nu] from (u, 0), as in
  // solveKKT: r1 = M u - (M + hC) u' - Phi_q^T mu, r2 = nu - Phi_q u'.
  damp_u0_ = s.u;
  mulM(sys, damp_u0_.data(), damp_b_.data());
  addRotorMass(sys, ev_, damp_u0_.data(), damp_b_.data());
  const Eigen::VectorXd& dn = solver_->dn();
  damp_mu_.setZero();  // -mu
  const double scale = motionScale(sys, damp_u0_);
  double previous = HUGE_VAL, step = 0;
  for (int pass = 0; pass < kMaxPasses; ++pass) {
    mulM(sys, s.u.data(), r1_.data());
    addRotorMass(sys, ev_, s.u.data(), r1_.data());
    r1_ = damp_b_ - r1_;
    addJt(sys, ev_, sys.all_constraints, damp_mu_.data(), r1_.data());
    for (const StiffRow& r : stiff_) {
      const Row* rows = damp_rows_[r.joint].data();
      const double q_dot = rowDot(sys, r.joint, rows[r.k], s.u.data());
      scatterRow(sys, r.joint, rows[r.k], -(h * r.c * q_dot), r1_.data());
    }
    mulJ(sys, ev_, sys.all_constraints, s.u.data(), r2_.data());
    r2_ = ev_.nu - r2_;
    solver_->precondition(sys, ev_, r1_.data(), r2_.data(), true);
    s.u += dn;
    damp_mu_ -= solver_->dl();
    ++stats_.solve_passes;
    step = motionScale(sys, dn);
    if (!(step > kRoundOff * scale) || step > 0.5 * previous) break;
    previous = step;
  }
  // A refinement that stopped (passes out, or gaining less than a factor 2) with its last
  // correction above the solve tolerance of the velocities' scale is counted, as solveKKT's.
  ++stats_.solves;
  const double left = scale > 0 ? step / scale : step;
  if (left > sys.options.solve_tol) {
    ++stats_.solve_shortfalls;
    stats_.worst_solve = std::max(stats_.worst_solve, left);
  }
  // (4.) the positions: h (u' - u) / 2
  solver_->dn() = (0.5 * h) * (s.u - damp_u0_);
  displace(sys, s.x, solver_->dn().data());
}

}  // namespace mechanism_sim
