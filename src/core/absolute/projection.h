// Projection onto the constraints (doc/method.md "Integration method"): free functions on a
// State, its evaluation record and the solver interface, as the stepper and whoever
// embeds the core call them.
//   * positions: simplified Newton on Phi = 0, mass-orthogonal, to position_tol;
//   * velocities: mass-orthogonal onto Phi_q v = nu, to velocity_tol.
// Both count their shortfalls in SolverStats; past kFailureResidual the step cannot be
// repaired (StepFailure, naming the constraint).
#pragma once
#include <algorithm>
#include <array>
#include <vector>

#include <Eigen/Core>

#include "core/absolute/evaluation.h"
#include "core/absolute/solver.h"
#include "core/numerics.h"

namespace mechanism_sim {

// Above this relative residual the step fails, between the tolerance and it a projection is
// counted short (numerics.h).
using numerics::absolute::kFailureResidual;

// The relative residual past which a projection fails the step: kFailureResidual, or the
// description's precision (kDescriptionPrecision, what assembly accepts) where its dependent
// equations disagree at that precision (System::description_residual > 0). Which rows the
// solves keep changes as the mechanism moves (the dependencies are analyzed again), each
// choice has its own least-squares pose, and rows that the file's round-off leaves nearly
// but not exactly dependent are kept where their independence shows above the analysis's
// pivot: residuals of the disagreement's size there (positions, and velocities along the
// nearly dependent rows) are the description's precision, not a step that left the
// constraints. They are counted short and reported.
inline double failureResidual(const System& sys) {
  return sys.description_residual > 0.0 ? std::max(kFailureResidual, numerics::assembly::kDescriptionPrecision)
                                        : kFailureResidual;
}

// The projections' scratch, sized once for a System (no allocation in a projection).
struct Projection {
  Eigen::VectorXd r1, r2, query;
  // per body: the velocity residual's scales, those the velocity projection started from,
  // and the mechanism's (every body at the largest starting motion of any)
  std::vector<std::array<double, 2>> body_scale, start_scale, mechanism_scale;
  std::vector<Jacobian> J_frozen;  // the Jacobian H was factored with (frozen Newton)
  Projection() = default;
  explicit Projection(const System& sys)
      : r1(Eigen::VectorXd::Zero(sys.n)), r2(Eigen::VectorXd::Zero(sys.m)), query(Eigen::VectorXd::Zero(sys.m)),
        body_scale(sys.nb, {0.0, 0.0}), start_scale(sys.nb, {0.0, 0.0}), mechanism_scale(sys.nb, {0.0, 0.0}),
        J_frozen(Evaluation(sys).J) {}
};

// Moves s.x onto Phi = 0 (ev evaluated at s on entry and on return). With `frozen` the
// factorization at hand and w.J_frozen (the Jacobian it was taken with) make the Newton
// steps, refactored when progress is slow. Returns whether it moved.
// to_roundoff: Newton goes on past the tolerance while its correction keeps halving (at
// most kRoundoffSteps more): near a configuration where equations become dependent (a
// parallelogram passing flat, where the stage solves stall) a residual at the tolerance
// leaves the positions off by residual / sigma_min along the nearly dependent direction.
bool projectPositions(const System& sys, State& s, Evaluation& ev, ConstraintSolver& solver, Projection& w,
                      SolverStats& stats, bool frozen, bool to_roundoff = false);
// Moves s.u onto Phi_q v = nu with the factorization at hand (at s's positions). Returns
// whether it moved. to_roundoff as for positions.
bool projectVelocities(const System& sys, State& s, Evaluation& ev, ConstraintSolver& solver, Projection& w,
                       SolverStats& stats, bool to_roundoff = false);
// The constraint with the largest |r| over its rows (r per equation), and that value.
int worstConstraint(const System& sys, const Eigen::VectorXd& r, double* value);

}  // namespace mechanism_sim
