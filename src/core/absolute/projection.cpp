// Projection onto the constraints (projection.h).
#include "core/absolute/projection.h"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace mechanism_sim {
namespace {

using numerics::absolute::kMaxNewton;
using numerics::absolute::kMaxPenaltyVelocityPasses;
using numerics::absolute::kRoundoffSteps;

// The size of a correction dn (per body: translation and rotation): max |dn| over the
// bodies, a rotation through the length scale.
double correctionSize(const System& sys, const Eigen::VectorXd& dn) {
  double c = 0;
  for (int b = 0; b < sys.nb; ++b) {
    const int i = BodyCoordinates::u(b);
    c = std::max({c, dn.segment<3>(i).cwiseAbs().maxCoeff(), dn.segment<3>(i + 3).cwiseAbs().maxCoeff() * sys.length_scale});
  }
  return c;
}

[[noreturn]] void leftConstraints(const System& sys, const Evaluation& ev, double t, double err) {
  double worst_err = 0;
  const int worst = worstConstraint(sys, ev.Phi, &worst_err);
  std::ostringstream os;
  os << "the step left the constraints (relative residual " << fmt(err) << ", largest at '"
     << sys.constraints[worst]->name() << "': " << fmt(worst_err) << ", reached at t = " << t
     << " s); try a smaller step";
  throw StepFailure(os.str());
}

}  // namespace

// The constraint with the largest |r| over its rows (r per equation), and that value.
int worstConstraint(const System& sys, const Eigen::VectorXd& r, double* value) {
  int worst = 0;
  *value = -1.0;
  for (int ci = 0; ci < sys.numConstraints(); ++ci) {
    const ConstraintLayout& L = sys.layout[ci];
    const double e = L.size ? r.segment(L.row, L.size).cwiseAbs().maxCoeff() : 0.0;
    if (e > *value) *value = e, worst = ci;
  }
  return worst;
}


// Mass-orthogonal projection of positions, simplified Newton: dq from the factored
// matrix applied to r2 = -Phi (precondition(): on H, dq = -H^-1 Phi_q^T W Phi, the
// least-squares step, dependent equations included; on the tree KKT matrix the
// mass-orthogonal step onto the tree's equations), renewing the factorization when
// progress is slow.
bool projectPositions(const System& sys, State& s, Evaluation& ev, ConstraintSolver& solver, Projection& w,
                      SolverStats& stats, bool frozen, bool to_roundoff) {
  const double tol = sys.options.position_tol;
  double err = positionResidual(sys, ev), previous = HUGE_VAL;
  int it = 0;
  for (; err > tol && it < kMaxNewton; ++it) {
    if (!frozen || (it > 1 && err > 0.1 * previous)) {  // full Newton
      solver.factor(sys, ev, "position projection", s.t);
      frozen = false;
    }
    previous = err;
    w.r2 = -ev.Phi;
    w.r1.setZero();
    if (frozen) std::swap(ev.J, w.J_frozen);
    solver.precondition(sys, ev, w.r1.data(), w.r2.data(), false);
    if (frozen) std::swap(ev.J, w.J_frozen);
    displace(sys, s.x, solver.dn().data());
    evaluateAt(sys, s, ev);
    ++stats.evaluations;
    err = positionResidual(sys, ev);
  }
  if (to_roundoff && err <= tol) {
    double previous_step = HUGE_VAL;
    for (int extra = 0; extra < kRoundoffSteps; ++extra) {
      solver.factor(sys, ev, "position projection", s.t);
      w.r2 = -ev.Phi;
      w.r1.setZero();
      solver.precondition(sys, ev, w.r1.data(), w.r2.data(), false);
      const double step = correctionSize(sys, solver.dn());
      if (!(step < 0.5 * previous_step) || step == 0.0) break;  // stagnant: round-off reached
      previous_step = step;
      displace(sys, s.x, solver.dn().data());
      evaluateAt(sys, s, ev);
      ++stats.evaluations;
      ++it;
    }
    err = positionResidual(sys, ev);
  }
  stats.countPositionProjection(err <= tol, err);
  if (err > tol && err > failureResidual(sys)) leftConstraints(sys, ev, s.t, err);
  return it > 0;
}

// Mass-orthogonal projection of velocities onto Phi_q v = nu: dv from the factored matrix
// applied to r2 = nu - Phi_q v (on H: dv = H^-1 Phi_q^T W r2), repeated until the relative
// residual meets velocity_tol. A pass that gains less than a factor 2 ends it (as in
// solveKKT): what is left lies along equations that are nearly dependent at this
// configuration (a parallelogram passing flat), where each further pass moves the
// velocities by about residual / sigma_min^2 along the dependent direction and gains
// little. A pass that made it worse is undone; the residual left is counted. The gain is
// measured against the scales of the velocities the projection started from: the residual
// relative to the current velocities does not fall when the projection stops most of the
// motion (a limit that just engaged reads relative 1 before and after a pass that cuts the
// velocity into it by orders of magnitude). It is measured twice: against each body's
// starting scale (a slow part's equations judged on its own motion) and against the
// mechanism's (every body at the largest starting motion). A pass gains when it gains on
// either and does harm only when it does on both: its remainder, about 1 / (kappa sigma) of
// the residual it was given, spreads over the bodies the equations couple, and on a body
// that was at rest it is judged on that body's floor (kFloor of the motion). A five-bar in
// a vertical plane with one motor resting on its stop shows both: on that motor's own
// floored scale the first pass of a step reads no better, or worse, while on the
// mechanism's scale it gains by orders of magnitude; judged on the body's scale alone, the
// pass would be undone and the step fail.
bool projectVelocities(const System& sys, State& s, Evaluation& ev, ConstraintSolver& solver, Projection& w,
                       SolverStats& stats, bool to_roundoff) {
  const double tol = sys.options.velocity_tol;
  double err = velocityResidual(sys, ev, s.u, w.body_scale);
  const bool moves = err > tol;
  // the residual against the starting scales: each body's, and the mechanism's
  double gauge = err, gauge_all = 0.0;
  if (moves) {
    w.start_scale = w.body_scale;
    const double V = std::max(motionScale(sys, s.u), kFloor * sys.velocity_scale);
    std::fill(w.mechanism_scale.begin(), w.mechanism_scale.end(), std::array<double, 2>{V, V / sys.length_scale});
    gauge_all = velocityResidualAtScales(sys, ev, s.u, w.mechanism_scale);
  }
  for (int it = 0; err > tol && it < kMaxPenaltyVelocityPasses; ++it) {
    mulJ(sys, ev, sys.all_constraints, s.u.data(), w.r2.data());
    w.r2 = ev.nu - w.r2;
    w.r1.setZero();
    solver.precondition(sys, ev, w.r1.data(), w.r2.data(), false);
    s.u += solver.dn();
    err = velocityResidual(sys, ev, s.u, w.body_scale);
    if (err <= tol) break;
    const double previous = gauge, previous_all = gauge_all;
    gauge = velocityResidualAtScales(sys, ev, s.u, w.start_scale);
    gauge_all = velocityResidualAtScales(sys, ev, s.u, w.mechanism_scale);
    if (gauge > previous && gauge_all > previous_all) {
      s.u -= solver.dn();
      err = velocityResidual(sys, ev, s.u, w.body_scale);
      break;
    }
    if (gauge > 0.5 * previous && gauge_all > 0.5 * previous_all) break;
  }
  if (to_roundoff && err <= tol) {
    double previous_step = HUGE_VAL;
    for (int extra = 0; extra < kRoundoffSteps; ++extra) {
      mulJ(sys, ev, sys.all_constraints, s.u.data(), w.r2.data());
      w.r2 = ev.nu - w.r2;
      w.r1.setZero();
      solver.precondition(sys, ev, w.r1.data(), w.r2.data(), false);
      const double step = correctionSize(sys, solver.dn());
      if (!(step < 0.5 * previous_step) || step == 0.0) break;
      previous_step = step;
      s.u += solver.dn();
    }
    err = velocityResidual(sys, ev, s.u, w.body_scale);
  }
  stats.countVelocityProjection(err <= tol, err);
  if (err <= tol) return moves;
  if (err > failureResidual(sys)) {
    // as for positions: the step cannot be repaired (it is retaken in halves, then the run
    // stops) rather than going on with the velocity constraints visibly broken
    mulJ(sys, ev, sys.all_constraints, s.u.data(), w.query.data());
    w.query -= ev.nu;
    double worst_v = 0;
    const int worst = worstConstraint(sys, w.query, &worst_v);
    std::ostringstream os;
    os << "the velocities cannot be brought onto the constraints (relative residual " << fmt(err)
       << ", largest at '" << sys.constraints[worst]->name() << "': " << fmt(worst_v) << ", reached at t = " << s.t
       << " s); the mechanism may be near a singular or locking configuration (joint axes almost but not "
          "exactly aligned?) or too badly scaled for double precision (parts of very different sizes)";
    throw StepFailure(os.str());
  }
  return moves;
}

}  // namespace mechanism_sim
