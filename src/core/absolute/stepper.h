// The stepper: maps (System, State, Inputs, h) to the next State, with its own scratch
// space. Method (doc/method.md "Integration method"):
//   * accelerations and multipliers of  M a + Phi_q^T lambda = Q,  Phi_q a = gamma  from
//     the quasi-definite KKT system. A tree's joints (with their drives and limits) are
//     block rows of the factored KKT matrix (eliminated leaves first); a
//     mechanism with loops or couplers (and any factorization whose tree pivot is not
//     definite) has every equation in penalty form, H = M + Phi_q^T W Phi_q with a weight
//     per equation scaled by the masses it couples (block Cholesky, block_cholesky.h).
//     Either is refined on the exact KKT residual until it meets a relative tolerance;
//   * classical RK4 (or Heun) on the index-1 equations;
//   * after the step, mass-orthogonal projection of positions onto Phi = 0 (simplified
//     Newton) and of velocities onto Phi_q v = 0, both to relative tolerances.
// Every iteration that stops short of its tolerance is counted in SolverStats.
// The evaluation it steps on is a record (evaluation.h); the linear algebra is the solver
// interface (solver.h), its implementation chosen once per mechanism.
#pragma once
#include <array>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "core/absolute/dependencies.h"
#include "core/absolute/evaluation.h"
#include "core/absolute/projection.h"
#include "core/absolute/solver.h"
#include "core/formulation.h"
#include "mechanism_sim/core/model/system.h"
#include "mechanism_sim/core/model/tableau.h"

namespace mechanism_sim {

class Stepper final : public FormulationStepper {
 public:
  static constexpr double kKappa = ConstraintSolver::kKappa;
  explicit Stepper(const System& sys);  // integrates with sys.options.method

  // The integrator from here on (Mechanism::setIntegrator: the System's options changed).
  void setMethod(Method m) override { tableau_ = &tableau(m); }
  const Tableau& method() const { return *tableau_; }

  // Advances s by h under the inputs. Throws StepFailure (naming the constraint) when the
  // step leaves the constraints beyond repair, SimulationError when the run cannot go on,
  // UsageError for an h that is not positive and finite; s is then as it was.
  void step(const System& sys, State& s, const Inputs& in, double h) override;
  // Evaluates at s and solves accelerations and multipliers (s.acc, s.lambda) with the
  // friction efforts in s; after it evaluation() describes s.
  void settle(const System& sys, State& s, const Inputs& in) override;
  void resolve(const System& sys, State& s, const Inputs& in) override;
  void adopt(const System&, State& s, const Inputs&) override {
    requireComplete(s);
    s.q.resize(0), s.qdot.resize(0), s.qddot.resize(0);
  }

  // The last evaluation (after step() or settle(): of the state reached; its stamp says
  // which) and the solver.
  const Evaluation& evaluation() const { return ev_; }
  Evaluation& evaluation() { return ev_; }
  ConstraintSolver& solver() { return *solver_; }
  const SolverStats& stats() const override { return stats_; }

  // Finds the dependent rows at s (equalities and active limits; dependencies.h), writes
  // s.dropped and leaves s evaluated with them dropped. Allocates on its first call.
  DependencyReport analyzeDependencies(const System& sys, State& s);

  // ---- building blocks (assembly.cpp uses them): the evaluation record filled and counted
  void load(const System& sys, const double* x, const double* u) { loadKinematics(sys, x, u, ev_); }
  void evaluate(const System& sys, const State& s);
  // Moves the State's tracked angles to the loaded pose (after a step or an assembly move);
  // with `rates`, writes their rates there (per constraint).
  void trackAngles(const System& sys, State& s, std::vector<Tracked>* rates = nullptr) const;

 private:
  // s's accelerations written (State::bodies_pending: the joint formulation completes them,
  // Mechanism before it hands a State over); else std::logic_error.
  static void requireComplete(const State& s);
  bool frictionActs(const System& sys) const;
  void rates(const System& sys, const State& s, const Inputs& in,
             const std::vector<std::array<double, 3>>& friction, const double* x, const double* u,
             double* xdot, double* udot, bool reweight);
  // Q at the evaluation: the stages' damping while split_, the state's own otherwise.
  void forces(const System& sys, const State& s, const Inputs& in,
              const std::vector<std::array<double, 3>>& friction) {
    appliedForces(sys, s, in, split_ ? stage_damping_ : sys.damping, friction, ev_);
  }
  void frictionFor(const System& sys, State& s, const Inputs& in, double h);
  // Joint damping too stiff for the explicit stages (stiff_damping.cpp): which damped
  // coordinates leave the stages this step (sets split_, stage_damping_; kinematics loaded
  // at s), and the implicit Euler velocity step for them after the stages (J evaluated at s).
  void initDamping(const System& sys);
  bool classifyDamping(const System& sys, const State& s, double h);
  void implicitDamping(const System& sys, State& s, double h);
  void advance(const System& sys, State& s, const Inputs& in, double h, int depth);
  void stepOnce(const System& sys, State& s, const Inputs& in, double h);
  void finishStep(const System& sys, State& s, const Inputs& in, bool after_stages);
  bool updateLimits(const System& sys, State& s);
  bool releaseLimits(const System& sys, State& s);
  // Analyzes again (mechanisms whose rows can depend on others: loops, couplers) when the
  // active limits changed or the dropped rows drifted; returns whether s.dropped changed and
  // leaves s evaluated (kinematics loaded at s).
  bool refreshDependencies(const System& sys, State& s, DependencyReport* report = nullptr);

  SolverStats stats_;
  Evaluation ev_;
  std::unique_ptr<ConstraintSolver> solver_;
  DependencyAnalyzer dependencies_;
  bool watch_dependencies_ = false;  // rows may depend on others (loops, couplers)
  std::vector<char> dropped_before_;
  Projection projection_;  // the projections' scratch (its J_frozen: the last stage's Jacobian)
  Eigen::VectorXd a_, lam_, r1_, r2_;
  const Tableau* tableau_ = &kRk4;  // the integrator (tableau.h)
  // The step's start, a stage's start, the stages' rates and a weighted sum of them.
  Eigen::VectorXd x0_, u0_, xs_, us_, kx_[Tableau::kMaxStages], ku_[Tableau::kMaxStages];
  std::vector<State> backup_;  // per halving depth
  State start_;                // the state a step started from (restored when it fails)
  std::vector<Tracked> tracked0_, tracked_rate_;  // at the step's start
  // Stiff joint damping (stiff_damping.cpp). While split_ is set (the stages of a step that
  // has stiff coordinates) forces() takes the damping from stage_damping_, in which the
  // stiff coordinates have none; they are integrated implicitly in finishStep.
  bool split_ = false;
  long stage_shortfalls_ = 0;  // the solver's shortfall count when this step's stages began
  double split_h_ = 0.0;
  std::vector<std::array<double, 3>> stage_damping_;  // per joint coordinate
  std::vector<std::vector<int>> joints_at_;           // per moving body: the joints on it
  struct StiffRow {
    int joint, k;
    double c;
  };
  std::vector<StiffRow> stiff_;                        // capacity: every coordinate
  std::vector<std::array<Row, kMaxJointDofs>> damp_rows_;          // per joint: its rows (damped joints)
  Eigen::VectorXd damp_u0_, damp_b_, damp_mu_;
};

}  // namespace mechanism_sim
