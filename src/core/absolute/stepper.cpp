// Stepper: time stepping and projection onto the constraints, on an evaluation record
// (evaluation.h) and the solver interface (solver.h).
#include "core/absolute/stepper.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace mechanism_sim {
namespace {

using numerics::absolute::kDependentDrift;
using numerics::kMaxHalvings;
using numerics::absolute::kMaxTurn;
using numerics::kMaxStepError;
using HState = ConstraintSolver::HState;

}  // namespace

Stepper::Stepper(const System& sys) : ev_(sys), solver_(makeSolver(sys, stats_)), projection_(sys) {
  auto zeros = [](Eigen::VectorXd& v, int size) { v = Eigen::VectorXd::Zero(size); };
  const int nx = BodyCoordinates::positions(sys);
  zeros(lam_, sys.m), zeros(r2_, sys.m);
  zeros(a_, sys.n), zeros(r1_, sys.n);
  zeros(x0_, nx), zeros(u0_, sys.n), zeros(xs_, nx), zeros(us_, sys.n);
  tableau_ = &tableau(parseMethod(sys.options.method));
  for (int s = 0; s < Tableau::kMaxStages; ++s) zeros(kx_[s], nx), zeros(ku_[s], sys.n);
  // everything a step writes is sized here: a step allocates nothing
  backup_.assign(kMaxHalvings + 1, initialState(sys));
  start_ = backup_[0];
  tracked0_ = backup_[0].tracked;
  tracked_rate_ = backup_[0].tracked;
  initDamping(sys);
  // Rows can depend on others where equations close loops or couple joints: those outside
  // the tree (a tree's joint equations and the limits on its coordinates never do).
  for (int ci = 0; ci < sys.numConstraints(); ++ci)
    if (sys.layout[ci].row < sys.m_eq && sys.layout[ci].size > 0 && !solver_->holdsExactly(ci)) watch_dependencies_ = true;
  if (watch_dependencies_) {
    dependencies_.init(sys);
    dropped_before_.assign(sys.m, 0);
  }
}

DependencyReport Stepper::analyzeDependencies(const System& sys, State& s) {
  if (!dependencies_.ready()) dependencies_.init(sys);
  DependencyReport report;
  load(sys, s.x.data(), s.u.data());
  refreshDependencies(sys, s, &report);
  return report;
}

bool Stepper::refreshDependencies(const System& sys, State& s, DependencyReport* report) {
  dropped_before_ = s.dropped;
  std::fill(s.dropped.begin(), s.dropped.end(), 0);
  evaluate(sys, s);  // every row, none dropped
  dependencies_.analyze(sys, ev_.kin, ev_.J, s.limit_side.data(), s.dropped, report);
  evaluate(sys, s);
  return s.dropped != dropped_before_;
}


void Stepper::trackAngles(const System& sys, State& s, std::vector<Tracked>* rates) const {
  const EvalContext ctx = s.context();
  const BodyKin* ptrs[kMaxConstraintBodies];
  Tracked rate;
  for (int ci = 0; ci < sys.numConstraints(); ++ci) {
    gather(ev_, *sys.constraints[ci], ptrs);
    sys.constraints[ci]->track(ptrs, ctx, s.tracked[ci], rates ? (*rates)[ci] : rate);
  }
}


void Stepper::evaluate(const System& sys, const State& st) {
  evaluateConstraints(sys, st, ev_);
  ++stats_.evaluations;
}


void Stepper::rates(const System& sys, const State& s, const Inputs& in,
                    const std::vector<std::array<double, 3>>& friction, const double* x,
                    const double* u, double* xdot, double* udot, bool reweight) {
  load(sys, x, u);
  evaluate(sys, s);
  // H at the stage's own Jacobian: with kappa = 1e7 even the O(h^2) difference between
  // RK4's two midpoint stages makes refinement on the other's H diverge
  solver_->factor(sys, ev_, "stage", s.t, reweight);
  forces(sys, s, in, friction);
  // the residual scales of the step's first solve (stages differ from it by O(h))
  solver_->solve(sys, ev_, a_, lam_, HState::kCurrent, s.t, false);
  positionRates(sys, x, u, xdot);
  std::copy(a_.data(), a_.data() + sys.n, udot);
}

// Friction for the step h about to be taken, from the state with H factored there.
// The effective inertia along coordinate k is I = 1 / (q_x,k P q_x,k^T), q_x,k the
// coordinate's row (notation.h) and P the constrained inverse mass (the factored matrix
// applied to q_x,k^T: exactly on a tree's KKT matrix, up to 1/kappa with H); the effort that
// leaves q_dot = 0 after the step is I (q_dot / h + q_ddot_free) with q_ddot_free =
// q_x,k a_free - gamma_k (the coordinate's own velocity term), and friction
// supplies it up to f; a planar joint's in-plane pair is clamped to a disc (coulombFriction,
// the rule the joint formulation shares).
void Stepper::frictionFor(const System& sys, State& s, const Inputs& in, double h) {
  for (auto& f : s.friction) f = {0.0, 0.0, 0.0};
  std::fill(s.sum_friction.begin(), s.sum_friction.end(), 0.0);
  forces(sys, s, in, s.friction);
  a_ = s.acc;
  lam_ = s.lambda;
  solver_->solve(sys, ev_, a_, lam_, HState::kCurrent, s.t);
  Row rows[kMaxJointDofs];
  for (int j = 0; j < sys.numJoints(); ++j) {
    const auto& f = sys.friction[j];
    const Joint& jt = *sys.joints[j];
    const int dof = jt.dof();
    bool has = false;
    for (int k = 0; k < dof; ++k) has = has || f[k] > 0.0;
    if (!has) continue;
    jointRows(sys, ev_, s, j, rows);
    // the coupled effective inertia (q_x P q_x^T)^-1 of the coordinates that have friction,
    // and q_dot / h + q_ddot_free (with the coordinate's own gamma): coulombFriction's inputs
    double gHg[3][3] = {{0}};
    Eigen::VectorXd& Pg = solver_->dn();
    auto solveRow = [&](int k) {  // Pg = P q_x,k^T
      Pg.setZero();
      scatterRow(sys, j, rows[k], 1.0, Pg.data());
      solver_->applyInverseMass(sys, ev_);
    };
    auto dotRow = [&](int k, const Eigen::VectorXd& x) { return rowDot(sys, j, rows[k], x.data()); };
    double rate[3] = {0, 0, 0};
    for (int k = 0; k < dof; ++k) {
      if (f[k] <= 0.0) continue;
      rate[k] = rows[k].Phi_dot / h - rows[k].gamma + dotRow(k, a_);
      solveRow(k);
      for (int l = 0; l < dof; ++l)
        if (f[l] > 0.0) gHg[l][k] = dotRow(l, Pg);
    }
    coulombFriction(f, jt.planarTranslation(), rate, gHg, s.friction[j]);
  }
  // friction on sums of coordinates: the same rule on the row g = sum_i c_i q_x,i, its rate
  // sum_i c_i (q_dot_i / h + q_ddot_free,i) and inverse effective inertia g P g^T
  for (size_t r = 0; r < sys.sum_friction.size(); ++r) {
    const SumFriction& F = sys.sum_friction[r];
    if (!(F.f > 0.0)) continue;
    Row term_rows[kMaxCoordinateEfforts];
    Eigen::VectorXd& Pg = solver_->dn();
    Pg.setZero();
    double rate[3] = {0, 0, 0}, gPg[3][3] = {{0}};
    for (size_t i = 0; i < F.terms.size(); ++i) {
      const LimitTerm& t = F.terms[i];
      term_rows[i] = jointRow(sys, ev_, s, t.joint, t.k);
      rate[0] += t.c * (term_rows[i].Phi_dot / h - term_rows[i].gamma + rowDot(sys, t.joint, term_rows[i], a_.data()));
      scatterRow(sys, t.joint, term_rows[i], t.c, Pg.data());
    }
    solver_->applyInverseMass(sys, ev_);
    for (size_t i = 0; i < F.terms.size(); ++i)
      gPg[0][0] += F.terms[i].c * rowDot(sys, F.terms[i].joint, term_rows[i], Pg.data());
    std::array<double, 3> out;
    coulombFriction({F.f, 0.0, 0.0}, false, rate, gPg, out);
    s.sum_friction[r] = out[0];
  }
}


void Stepper::requireComplete(const State& s) {
  if (s.bodies_pending) throw std::logic_error("absolute formulation: a State with its accelerations pending");
}

void Stepper::step(const System& sys, State& s, const Inputs& in, double h) {
  if (!(h > 0) || !std::isfinite(h)) throw UsageError("step must be positive and finite");
  requireComplete(s);
  // A step that fails leaves the State where it was (the last accepted step), not part
  // way through its substeps.
  start_ = s;
  try {
    advance(sys, s, in, h, 0);
  } catch (...) {
    s = start_;
    split_ = false;
    throw;
  }
}

// A step whose projection cannot bring the state back onto the constraints is taken
// again as two half steps (at most kMaxHalvings deep); SolverStats counts them.
//
// A body turning more than kMaxTurn rad in one step is beyond what RK4 follows accurately
// (its phase error per step grows like (w h)^5): such a step is taken as halves, and
// past kMaxHalvings the run stops naming the body and the step that would do.
void Stepper::advance(const System& sys, State& s, const Inputs& in, double h, int depth) {
  int fastest = 0;
  double spin = 0;
  for (int b = 0; b < sys.nb; ++b) {
    // a body with neither mass nor inertia (a gimbal's cross) is not followed: its pose
    // comes from its joints (the projection puts it there), and near the lock it turns
    // at the rate of the motion over the cosine of the middle angle
    const Body& B = sys.bodies[b + 1];
    if (B.m == 0.0 && B.Jp.isZero(0.0)) continue;
    const double w = s.u.segment<3>(BodyCoordinates::u(b) + 3).norm();
    if (w > spin) spin = w, fastest = b + 1;
  }
  if (spin * h > kMaxTurn) {
    if (depth >= kMaxHalvings) {
      const double asked = h * (1 << depth);
      std::ostringstream os;
      os << "body '" << sys.bodies[fastest].name << "' turns " << fmt(spin * asked) << " rad in one step of "
         << asked << " s (" << (1 << depth) << " substeps still turn " << fmt(spin * h)
         << " rad each); steps of at most " << fmt(kMaxTurn / spin) << " s follow it";
      throw SimulationError(os.str());
    }
    ++stats_.halved_steps;
    advance(sys, s, in, 0.5 * h, depth + 1);
    advance(sys, s, in, 0.5 * h, depth + 1);
    return;
  }
  if (depth > 0) backup_[depth] = s;  // depth 0 starts from start_ (step())
  try {
    stepOnce(sys, s, in, h);
  } catch (const StepFailure&) {
    if (depth >= kMaxHalvings) throw;
    s = depth > 0 ? backup_[depth] : start_;
    ++stats_.halved_steps;
    advance(sys, s, in, 0.5 * h, depth + 1);
    advance(sys, s, in, 0.5 * h, depth + 1);
    return;
  }
  // A step that leaps over what it should follow is taken again as halves (at most
  // kMaxHalvings deep; the deepest is kept). Its local error is estimated with the
  // derivative at its end, which finishStep solved (first same as last): with k5 = a(t + h),
  // y0 + h (k1/6 + k2/3 + k3/3 + k5/6) is of order 3 beside RK4's order 4 (the order
  // conditions: sum b = 1, sum b c = 1/2, sum b c^2 = 1/3, sum b a c = 1/6), so their
  // difference h/6 |k4 - k5| estimates the velocities' error. A leg whose ankle linkage
  // reaches its dead point at 21 rad/s (the foot turned back within half a millisecond)
  // gives an estimate of twice its velocities in a step of 1 ms; a decay at h lambda = 0.4
  // gives 4.3e-4 of its rate, about (h lambda)^4 / 24. Not judged: steps that change the active limits (an inelastic stop, a
  // velocity jump), and mechanisms with joint damping, whose damped coordinates decay at
  // RK4's own amplification by design (stiff_damping.cpp: up to h c / m = 2 in the stages,
  // where the estimate is 0.44 of the rate).
  const State& before = depth > 0 ? backup_[depth] : start_;
  if (depth >= kMaxHalvings || tableau_->stages != 4 || s.limit_side != before.limit_side) return;
  for (const auto& c : sys.damping)
    if (c[0] != 0.0 || c[1] != 0.0 || c[2] != 0.0) return;
  const double L = sys.length_scale;
  double error = 0;
  for (int b = 0; b < sys.nb; ++b) {
    const int i = BodyCoordinates::u(b);
    error = std::max({error, (ku_[3].segment<3>(i) - s.acc.segment<3>(i)).norm(),
                      (ku_[3].segment<3>(i + 3) - s.acc.segment<3>(i + 3)).norm() * L});
  }
  error *= h / 6.0;
  const double scale = std::max({motionScale(sys, before.u), motionScale(sys, s.u), sys.velocity_scale});
  if (!(error > kMaxStepError * scale)) return;
  s = before;
  ++stats_.halved_steps;
  advance(sys, s, in, 0.5 * h, depth + 1);
  advance(sys, s, in, 0.5 * h, depth + 1);
}

void Stepper::stepOnce(const System& sys, State& s, const Inputs& in, double h) {
  // Stage 1 at the accepted state. Its accelerations and multipliers are in the State (the
  // last step solved them there); the evaluation left by that step is reused when it
  // describes this very state (compared by content). A solve runs, on a fresh
  // factorization, only when the inputs changed, so a restored State continues
  // bit-identically.
  const bool reuse = ev_.stamp.level == EvaluationStamp::kSolved && ev_.stamp.describes(s);
  stage_shortfalls_ = stats_.solve_shortfalls;
  load(sys, s.x.data(), s.u.data());
  if (!reuse) evaluate(sys, s);
  // Damped coordinates too stiff for the stages leave them (finishStep integrates them).
  classifyDamping(sys, s, h);
  bool factored = false;
  if (frictionActs(sys)) {
    solver_->factor(sys, ev_, "stage 1", s.t);
    factored = true;
    frictionFor(sys, s, in, h);
  } else {
    for (auto& f : s.friction) f = {0.0, 0.0, 0.0};  // (friction set to 0 since the last step)
    std::fill(s.sum_friction.begin(), s.sum_friction.end(), 0.0);
  }
  forces(sys, s, in, s.friction);
  a_ = s.acc;
  lam_ = s.lambda;
  solver_->solve(sys, ev_, a_, lam_, factored ? HState::kCurrent : HState::kNone, s.t);
  x0_ = s.x;
  u0_ = s.u;
  positionRates(sys, x0_.data(), u0_.data(), kx_[0].data());
  ku_[0] = a_;
  // Branch references of tracked angles at each stage: predicted from their rates, so
  // an angle may advance by more than pi in one step (a wheel at 4000 rad/s, 1 ms). The
  // rates at this state are those finishStep tracked here when the evaluation is reused.
  tracked0_ = s.tracked;
  if (!reuse) {
    const EvalContext ctx = s.context();
    const BodyKin* ptrs[kMaxConstraintBodies];
    for (int ci = 0; ci < sys.numConstraints(); ++ci) {
      gather(ev_, *sys.constraints[ci], ptrs);
      sys.constraints[ci]->trackedRates(ptrs, ctx, tracked_rate_[ci]);
    }
  }
  auto predictTracked = [&](double dt) {
    for (size_t ci = 0; ci < s.tracked.size(); ++ci)
      for (int k = 0; k < 2; ++k) s.tracked[ci][k] = tracked0_[ci][k] + tracked_rate_[ci][k] * dt;
  };
  const double t0 = s.t;
  const Tableau& T = *tableau_;
  const double* kx[Tableau::kMaxStages];
  const double* ku[Tableau::kMaxStages];
  for (int k = 0; k < T.stages; ++k) kx[k] = kx_[k].data(), ku[k] = ku_[k].data();
  for (int k = 1; k < T.stages; ++k) {
    combineStages(h, T.a[k], k, T.a_den[k], x0_, kx, xs_);
    combineStages(h, T.a[k], k, T.a_den[k], u0_, ku, us_);
    const double dt = T.c[k] * h;
    predictTracked(dt);
    s.t = t0 + dt;  // rheonomic equations (drives) are evaluated at the stage's time
    // the row weights only precondition: computed at the first stage, kept for the step
    rates(sys, s, in, s.friction, xs_.data(), us_.data(), kx_[k].data(), ku_[k].data(), k == 1);
  }
  combineStages(h, T.b, T.stages, T.b_den, x0_, kx, s.x);
  combineStages(h, T.b, T.stages, T.b_den, u0_, ku, s.u);
  for (int b = 0; b < sys.nb; ++b) s.x.segment<4>(BodyCoordinates::x(b) + 3).normalize();
  predictTracked(h);  // references near the new angles; finishStep tracks them exactly
  s.t = t0;
  s.countStep(h);
  finishStep(sys, s, in, true);
}

void Stepper::settle(const System& sys, State& s, const Inputs& in) {
  requireComplete(s);
  for (int b = 0; b < sys.nb; ++b) s.x.segment<4>(BodyCoordinates::x(b) + 3).normalize();
  finishStep(sys, s, in, false);
}

void Stepper::resolve(const System& sys, State& s, const Inputs& in) {
  load(sys, s.x.data(), s.u.data());
  evaluate(sys, s);
  const bool factored = solver_->factoredAt(ev_.stamp);
  if (!factored) solver_->factor(sys, ev_, "drive reference", s.t);
  forces(sys, s, in, s.friction);
  a_ = s.acc;
  lam_ = s.lambda;
  solver_->solve(sys, ev_, a_, lam_, factored ? HState::kNearby : HState::kCurrent, s.t);
  s.acc = a_;
  s.lambda = lam_;
  ev_.stamp.level = EvaluationStamp::kSolved;
}

bool Stepper::frictionActs(const System& sys) const {
  for (const auto& f : sys.friction)
    if (f[0] > 0 || f[1] > 0 || f[2] > 0) return true;
  for (const SumFriction& F : sys.sum_friction)
    if (F.f > 0) return true;
  return false;
}

// Brings a new state onto the constraints and solves its accelerations:
//  1. limits that were passed become active (a perfectly inelastic stop);
//  2. H is factored here (the penalty form needs H at the current Jacobian: a stale one
//     would turn kappa |delta J| into error);
//  3. positions: simplified Newton on Phi = 0, mass-orthogonal;
//  4. velocities onto Phi_q v = 0, mass-orthogonal;
//  5. tracked angles move on; accelerations and multipliers are solved at the final state
//     (refined on its own Jacobian) and stored in the State; limits that would pull let go.
void Stepper::finishStep(const System& sys, State& s, const Inputs& in, bool after_stages) {
  // (H consistent with the evaluation, the last stage's: factored at the same positions)
  const bool factored_here = solver_->factoredAt(ev_.stamp);
  load(sys, s.x.data(), s.u.data());
  // 0. stiff joint damping, implicit Euler (stiff_damping.cpp): velocities and positions
  //    move, and H is left factored with the damping in it (refactored below)
  const bool split_was = split_;
  if (after_stages && split_) {
    evaluate(sys, s);
    implicitDamping(sys, s, split_h_);
    load(sys, s.x.data(), s.u.data());
  }
  split_ = false;  // from here on forces() applies all the damping (the state's own)
  // After the stages, H and Phi_q of the last stage are a consistent pair: the Newton
  // steps use them frozen (the correction's direction is off by O(h) in a step of the
  // size of the local error: below RK4's truncation). A limit that just became active
  // is not in them: then full Newton, H refactored each iteration.
  // (implicit damping leaves a factorization that describes no evaluation)
  const bool consistent = factored_here && !(after_stages && split_was);
  // Where rows can depend on others, a change of the active limits is analyzed
  // (dependencies.h): a limit reached together with another through a loop is dependent.
  const bool limits_changed = updateLimits(sys, s);
  bool frozen = !limits_changed && after_stages && consistent;
  if (limits_changed && watch_dependencies_) {
    refreshDependencies(sys, s);  // (leaves s evaluated)
  } else {
    if (frozen) std::swap(ev_.J, projection_.J_frozen);
    evaluate(sys, s);
  }
  // a stage solve that stalled: equations nearly dependent here (projection.h, to_roundoff)
  const bool near_dependent = after_stages && stats_.solve_shortfalls > stage_shortfalls_;
  bool moved = projectPositions(sys, s, ev_, *solver_, projection_, stats_, frozen, near_dependent);
  // A projection that stops one joint on its limit moves the joints around it: in a chain
  // it can carry another joint past its own stop (a three-rod chain swinging onto its
  // stops). Such limits become active and the positions are projected again, at most once
  // per limit.
  for (size_t pass = 0; pass < sys.limits.size() && updateLimits(sys, s); ++pass) {
    frozen = false;
    if (watch_dependencies_) refreshDependencies(sys, s);
    else evaluate(sys, s);
    moved = projectPositions(sys, s, ev_, *solver_, projection_, stats_, false) || moved;
  }
  // The rows kept stopped implying the rows dropped: the loop turned in space so that
  // another of its cut joint's rows is the dependent one (a parallelogram gripper on an
  // arm turning it by 90 degrees). Analyzed again here and projected again.
  if (watch_dependencies_ && droppedResidual(sys, ev_) > kDependentDrift * sys.options.position_tol &&
      refreshDependencies(sys, s)) {
    frozen = false;
    moved = projectPositions(sys, s, ev_, *solver_, projection_, stats_, false) || moved;
  }
  if (moved || !frozen) solver_->factor(sys, ev_, "projection", s.t, !frozen);  // velocities need H at this Phi_q
  if (near_dependent && !moved && frozen) solver_->factor(sys, ev_, "projection", s.t);
  const bool sped = projectVelocities(sys, s, ev_, *solver_, projection_, stats_, near_dependent);
  // Tracked angles move to the new pose. The evaluation above stands when neither
  // projection moved the state: its branch references were predicted within O(h^2) of
  // these (the branch, all an evaluation takes from them, is the same).
  if (moved || sped) load(sys, s.x.data(), s.u.data());
  trackAngles(sys, s, &tracked_rate_);  // (the next step's stage 1 reuses the rates)
  if (moved || sped) evaluate(sys, s);
  for (int pass = 0;; ++pass) {
    forces(sys, s, in, s.friction);
    solver_->solve(sys, ev_, a_, lam_, HState::kNearby, s.t);
    if (pass > static_cast<int>(sys.limits.size()) || !releaseLimits(sys, s)) break;
    if (watch_dependencies_) refreshDependencies(sys, s);
    else evaluate(sys, s);
    solver_->factor(sys, ev_, "limit release", s.t);
  }
  s.acc = a_;
  s.lambda = lam_;
  ev_.stamp.level = EvaluationStamp::kSolved;  // (the evaluation describes s: see settle())
}

// Activates a limit whose coordinate has passed its bound; returns whether any did.
bool Stepper::updateLimits(const System& sys, State& s) {
  bool changed = false;
  for (size_t l = 0; l < sys.limits.size(); ++l) {
    const LimitSpec& L = sys.limits[l];
    if (s.limit_side[l]) continue;
    const double q = limitValue(sys, ev_, s, L);
    const int side = limitSide(L, q);
    if (!side) continue;
    if (drivenAtLimit(sys, L, q, s.t)) continue;
    s.limit_side[l] = static_cast<signed char>(side);
    changed = true;
  }
  return changed;
}

// Releases limits whose multiplier would pull; returns whether any did.
bool Stepper::releaseLimits(const System& sys, State& s) {
  bool released = false;
  for (size_t l = 0; l < sys.limits.size(); ++l) {
    if (!s.limit_side[l]) continue;
    const double lam = lam_[sys.layout[sys.limits[l].constraint].row];
    if ((s.limit_side[l] < 0 && lam > 0) || (s.limit_side[l] > 0 && lam < 0)) {
      s.limit_side[l] = 0;
      released = true;
    }
  }
  return released;
}


}  // namespace mechanism_sim
