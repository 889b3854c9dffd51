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
#pragma once
#include <array>
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "mechanism_sim/core/block_cholesky.h"
#include "mechanism_sim/core/dependencies.h"
#include "mechanism_sim/core/system.h"
#include "mechanism_sim/core/tableau.h"

namespace mechanism_sim {

// Iterations that met their tolerance and those that stopped short (with the worst
// relative residual they left).
struct SolverStats {
  long solves = 0, solve_shortfalls = 0;
  long position_projections = 0, position_shortfalls = 0;
  long velocity_projections = 0, velocity_shortfalls = 0;
  long evaluations = 0, factorizations = 0, solve_passes = 0;
  long halved_steps = 0;  // steps whose projection failed, retaken as two half steps
  double worst_solve = 0, worst_position = 0, worst_velocity = 0;
  long shortfalls() const { return solve_shortfalls + position_shortfalls + velocity_shortfalls; }
  std::string describe() const;  // one line
};

// r += dr, p <- p (x) exp(dtheta'/2) per moving body: a displacement in variation coordinates.
void displace(const System& sys, Eigen::VectorXd& x, const double* dq);


// Body kinematics of a state, ground first.
void loadKinematics(const System& sys, const double* x, const double* u, std::vector<BodyKin>& kin);

class Stepper {
 public:
  static constexpr double kKappa = 1e7;  // weight of the equations in H (stepper.cpp)
  explicit Stepper(const System& sys);  // integrates with sys.options.method

  // The integrator from here on (Mechanism::setIntegrator: the System's options changed).
  void setMethod(Method m) { tableau_ = &tableau(m); }
  const Tableau& method() const { return *tableau_; }

  // Advances s by h under the inputs. Throws StepFailure (naming the constraint) when the
  // step leaves the constraints beyond repair, SimulationError when the run cannot go on,
  // UsageError for an h that is not positive and finite; s is then as it was.
  void step(const System& sys, State& s, const Inputs& in, double h);
  // Evaluates at s and solves accelerations and multipliers (s.acc, s.lambda) with the
  // friction efforts in s; after it the queries below describe s.
  void settle(const System& sys, State& s, const Inputs& in);

  // ---- the last evaluation (after step() or settle(): the state reached)
  const std::vector<BodyKin>& kin() const { return kin_; }
  const Eigen::VectorXd& Phi() const { return Phi_; }
  const Eigen::VectorXd& gamma() const { return gamma_; }
  // Right-hand side of the velocity equations Phi_q v = nu (nu = -Phi_t: drives' rates).
  const Eigen::VectorXd& nu() const { return nu_; }
  Eigen::Ref<const Eigen::MatrixXd> jacobian(int c) const { return J_[c].topRows(sizes_[c]); }
  // max over equations of |Phi_e| and |Phi_q v - nu|_e
  double positionViolation() const;
  double velocityViolation(const System& sys, const Eigen::VectorXd& u) const;
  // Relative residuals: each equation against the size of its terms (scale-free).
  double positionResidual(const System& sys) const;
  double velocityResidual(const System& sys, const Eigen::VectorXd& u) const;
  // Size of the terms of row e of J over the bodies of c: |J_r| |r| + |J_theta| per body.
  double rowScale(const Constraint& c, const Eigen::Ref<const Eigen::MatrixXd>& J, int e) const;
  // 1 / (row M~^-1 row^T) for a row over the bodies of a constraint (see rowWeights).
  double rowWeight(const System& sys, int constraint, const Eigen::Ref<const Eigen::MatrixXd>& row) const;
  // Factors H (penalty form, cholesky()) at the evaluated state, for assembly.
  void factorHere(const System& sys, double t) { factor(sys, "assembly", t, true, true); }
  const SolverStats& stats() const { return stats_; }
  // Multipliers of the equality constraints with the least weighted norm sum_e lambda_e^2 /
  // w_e (w_e the row weight) among all that give s's constraint forces Q - M a, dependent
  // equations included: the same at the same state whatever the history (where the
  // equations are independent: s.lambda itself). Limits keep s's multipliers. Loads,
  // evaluates and factors s here (use a Stepper of its own). Returns the relative residual
  // left (a shortfall is counted in stats()).
  double minimumNormMultipliers(const System& sys, const State& s, const Inputs& in, Eigen::VectorXd& lambda);

  // Finds the dependent rows at s (equalities and active limits; dependencies.h), writes
  // s.dropped and leaves s evaluated with them dropped. Allocates on its first call.
  DependencyReport analyzeDependencies(const System& sys, State& s);

  // ---- building blocks (assembly.cpp uses them)
  void load(const System& sys, const double* x, const double* u);
  void evaluate(const System& sys, const State& s);
  // Moves the State's tracked angles to the loaded pose (after a step or an assembly move);
  // with `rates`, writes their rates there (per constraint).
  void trackAngles(const System& sys, State& s, std::vector<Tracked>* rates = nullptr) const;
  // H = diag * M + shift I + sum_e w_e J_e^T J_e over the rows, w_e = kappa * (row weight),
  // plus extra rows (Jx: rows over the bodies of constraint `extra_constraint`).
  void assembleH(const System& sys, double kappa, double mass, double shift);
  // Adds weight * rows^T rows to H for rows over the bodies of a constraint (6 columns a
  // body, in its bodies' order): assembly's targets, stiff damping's coordinate rows.
  template <class Rows>
  void addRowsToH(const System& sys, int constraint, const Eigen::MatrixBase<Rows>& rows, double weight) {
    const ConstraintLayout& L = sys.layout[constraint];
    const int k = static_cast<int>(L.bodies.size());
    for (int k1 = 0; k1 < k; ++k1)
      for (int k2 = k1; k2 < k; ++k2) {
        const int address = L.address[k1 * k + k2];
        if (address < 0) continue;
        const Eigen::Matrix<double, 6, 6> B =
            weight * rows.template middleCols<6>(6 * k1).transpose() * rows.template middleCols<6>(6 * k2);
        if (L.transposed[k1 * k + k2]) chol_.block(address) += B.transpose();
        else chol_.block(address) += B;
      }
  }
  BlockCholesky& cholesky() { return chol_; }
  // The tree KKT matrix (stepper.cpp): empty (size 0) for a mechanism with loops.
  void assembleKKT(const System& sys);
  BlockCholesky& kkt() { return kkt_; }
  // max over bodies of max(|v|, |w| L): how fast the mechanism moves (L its length scale).
  double motionScale(const System& sys, const Eigen::VectorXd& u) const;
  void mulJ(const System& sys, const double* v, double* out) const;   // out = Phi_q v
  void addJt(const System& sys, const double* y, double* out) const;  // out += Phi_q^T y
  // The same over the listed constraints only (mulJ writes their rows only).
  void mulJ(const System& sys, const std::vector<int>& cs, const double* v, double* out) const;
  void addJt(const System& sys, const std::vector<int>& cs, const double* y, double* out) const;
  void mulM(const System& sys, const double* v, double* out) const;   // out = M v
  // Per-row weights 1 / (J_e M~^{-1} J_e^T), M~ the masses with stand-ins for massless
  // bodies (System scales): W = kappa * rowWeights makes kappa dimensionless.
  const Eigen::VectorXd& rowWeights(const System& sys);
  const Eigen::VectorXd& rowWeights(const System& sys, const std::vector<int>& constraints);

 private:
  void forces(const System& sys, const State& s, const Inputs& in,
              const std::vector<std::array<double, 3>>& friction);
  // Factors at the evaluated positions: the tree KKT matrix, or H alone with `penalty`
  // (and when a tree pivot is not definite).
  void factor(const System& sys, const char* where, double t, bool reweight = true, bool penalty = false);
  // The spanning tree of joints whose equations the KKT factorization holds (once).
  void buildTree(const System& sys);
  // Adds kappa J_c^T W_c J_c of constraint ci into `target` at the given block addresses.
  void addPenalty(const System& sys, int ci, double kappa, BlockCholesky& target, const int* address,
                  const char* transposed);
  // The factored regularized KKT matrix applied to residuals (r1 per body, r2 per row):
  //   [M + J_p^T W J_p, J_t^T; J_t, 0] [dn; dl_t] = [r1 + J_p^T W r2_p; r2_t],
  //   dl_p = W (J_p dn - r2_p)  (t: tree rows, p: penalized rows, W with kappa).
  // Writes dn_ and, with `multipliers`, dl_.
  void precondition(const System& sys, const double* r1, const double* r2, bool multipliers);
  // What H is when a solve starts: not yet factored for this step (factor before the
  // first pass), factored at the evaluated positions, or factored at nearby positions
  // (refactored here when the passes converge slowly).
  enum class HState { kNone, kCurrent, kNearby };
  // Refines s.acc/lambda-warm-started a_, lam_. With rescale false the residual scales of
  // the last solve are kept (the stages of one step: their terms differ by O(h)).
  bool solveKKT(const System& sys, HState h, double t, bool rescale = true);
  bool frictionActs(const System& sys) const;
  void residualScales(const System& sys);
  void rates(const System& sys, const State& s, const Inputs& in,
             const std::vector<std::array<double, 3>>& friction, const double* x, const double* u,
             double* xdot, double* udot, bool reweight);
  void frictionFor(const System& sys, State& s, const Inputs& in, double h);
  // Joint damping too stiff for the explicit stages (stiff_damping.cpp): which damped
  // coordinates leave the stages this step (sets split_, stage_damping_; kin_ loaded at s),
  // and the implicit Euler velocity step for them after the stages (J_ evaluated at s).
  void initDamping(const System& sys);
  bool classifyDamping(const System& sys, const State& s, double h);
  void implicitDamping(const System& sys, State& s, double h);
  void advance(const System& sys, State& s, const Inputs& in, double h, int depth);
  void stepOnce(const System& sys, State& s, const Inputs& in, double h);
  void finishStep(const System& sys, State& s, const Inputs& in, bool after_stages);
  bool projectPositions(const System& sys, State& s, bool frozen);  // whether it moved
  bool projectVelocities(const System& sys, State& s);  // whether it moved
  bool updateLimits(const System& sys, State& s);
  bool releaseLimits(const System& sys, State& s);
  void jointRows(const System& sys, const State& s, int j, Row* rows) const;
  // body_scale_[b] = {max(|u_r|, |u_theta| L, floor), max(|u_theta|, |u_r| / L, floor / L)}:
  // what the translational and rotational parts of body b's velocities (or accelerations)
  // u are measured against.
  void bodyScales(const System& sys, const Eigen::VectorXd& u, double floor) const;
  double velocityResidualAtScales(const System& sys, const Eigen::VectorXd& u,
                                  const std::vector<std::array<double, 2>>& scales) const;
  // The loaded states of c's bodies in c.bodies() order, as Constraint calls take them.
  void gather(const Constraint& c, const BodyKin** ptrs) const;
  // The largest relative position residual of the dropped equality rows (0 when none is dropped):
  // large when the rows kept no longer imply them.
  double droppedResidual(const System& sys) const;
  // Analyzes again (mechanisms whose rows can depend on others: loops, couplers) when the
  // active limits changed or the dropped rows drifted; returns whether s.dropped changed and
  // leaves s evaluated (kinematics loaded at s).
  bool refreshDependencies(const System& sys, State& s, DependencyReport* report = nullptr);
  [[noreturn]] void leftConstraints(const System& sys, double t, double err) const;

  std::vector<BodyKin> kin_;
  std::vector<char> dropped_;
  DependencyAnalyzer dependencies_;
  bool watch_dependencies_ = false;  // rows may depend on others (loops, couplers)
  std::vector<char> dropped_before_;
  std::vector<double> dropped_scale_;  // per row: the size of a dropped row's terms
  double length_scale_ = 1.0;  // of the last evaluation (State::dropped)
  using Jacobian = Eigen::Matrix<double, 6, Eigen::Dynamic>;  // 6 rows, zero past the size
  std::vector<Jacobian> J_, J_frozen_;  // J_frozen_: the last stage's, during projection
  std::vector<int> sizes_;
  mutable Eigen::VectorXd query_;
  mutable std::vector<std::array<double, 2>> body_scale_;  // bodyScales(): per body
  std::vector<std::array<double, 2>> start_scale_;  // projectVelocities(): those it started from
  Eigen::VectorXd Phi_, nu_, gamma_, W_, Q_, a_, lam_, r1_, r2_, s1_, s2_, dn_, dm_, dl_;
  std::vector<Eigen::Matrix<double, 6, 6>> Minv_;  // per moving body, with stand-ins
  BlockCholesky chol_;
  // Tree KKT: block rows 0..nb-1 the bodies, nb + k the k-th tree joint's equations.
  BlockCholesky kkt_;
  bool kkt_mode_ = false;           // the last factorization is kkt_ (else chol_)
  std::vector<int> tree_node_;      // per constraint: its KKT block row, -1 when penalized
  struct NodeRow {
    int row, constraint, e;         // global row; its constraint and row there
  };
  std::vector<std::vector<NodeRow>> node_rows_;  // per tree block (row nb + k): its rows
  std::vector<int> penalized_;      // constraints in penalty form when kkt_mode_ is on
  std::vector<int> all_constraints_;
  // per constraint: KKT blocks of its slot pairs (penalized: body-body as in
  // ConstraintLayout; tree: (node, slot) in address[slot], the node's diagonal last)
  std::vector<std::vector<int>> kkt_address_;
  std::vector<std::vector<char>> kkt_transposed_;
  std::vector<int> kkt_added_;      // off-diagonal blocks the penalized equations add to
  Eigen::VectorXd z_, zero_rows_;
  const Tableau* tableau_ = &kRk4;  // the integrator (tableau.h)
  // The step's start, a stage's start, the stages' rates and a weighted sum of them.
  Eigen::VectorXd x0_, u0_, xs_, us_, kx_[Tableau::kMaxStages], ku_[Tableau::kMaxStages], sum_x_, sum_u_;
  // The evaluation and factorization describe this state (compared by content, so no
  // flag has to be kept in step with anything).
  Eigen::VectorXd eval_x_, eval_u_;
  std::vector<signed char> eval_side_;
  double eval_t_ = 0.0;
  std::vector<DriveRamp> eval_drive_;
  bool have_eval_ = false;
  SolverStats stats_;
  std::vector<State> backup_;  // per halving depth
  State start_;                // the state a step started from (restored when it fails)
  std::vector<Tracked> tracked0_, tracked_rate_;  // at the step's start
  // Stiff joint damping (stiff_damping.cpp). While split_ is set (the stages of a step that
  // has stiff coordinates) forces() takes the damping from stage_damping_, in which the
  // stiff coordinates have none; they are integrated implicitly in finishStep.
  bool split_ = false;
  double split_h_ = 0.0;
  std::vector<std::array<double, 3>> stage_damping_;  // per joint coordinate
  std::vector<std::array<double, 3>> damping_bound_;  // s_k of the step (0: undamped)
  std::vector<std::vector<int>> joints_at_;           // per moving body: the joints on it
  struct StiffRow {
    int joint, k;
    double c;
  };
  std::vector<StiffRow> stiff_;                        // capacity: every coordinate
  std::vector<std::array<Row, kMaxJointDofs>> damp_rows_;          // per joint: its rows (damped joints)
  Eigen::VectorXd damp_u0_, damp_b_, damp_mu_;
  // positions loaded, evaluated and factored at: H and Phi_q are a consistent pair when
  // the last two agree
  Eigen::VectorXd loaded_x_, evaluated_x_, factored_x_;
  std::vector<signed char> evaluated_side_, factored_side_;
};

}  // namespace mechanism_sim
