// The solver interface: what the stepper, the projections, friction, the reactions and
// assembly ask of the linear algebra of  M a + Phi_q^T lambda = Q,  Phi_q a = gamma.
//   * factor at an evaluation (analysis once, at construction);
//   * precondition: the factored regularized KKT matrix applied to residuals;
//   * solve: the KKT system refined on its exact residual to a relative tolerance;
//   * applyInverseMass: the constrained inverse mass P applied to a generalized force;
//   * minimumNormMultipliers: the least-norm multipliers where equations are dependent.
// Two implementations, chosen once per mechanism (makeSolver): the tree KKT form for a
// tree of joints (TreeKktSolver) and the penalty form H = M + kappa Phi_q^T W Phi_q for
// everything else (PenaltySolver). doc/method.md "Integration method".
#pragma once
#include <algorithm>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "mechanism_sim/core/reports.h"
#include "core/linalg/block_cholesky.h"
#include "core/absolute/evaluation.h"
#include "core/absolute/kkt_topology.h"
#include "mechanism_sim/core/model/system.h"

namespace mechanism_sim {

// H = mass M + shift M~ + kappa J^T W J (block_cholesky.h), the penalty form: every
// equation weighted by its row weight W (Evaluation::W) and kappa.
class PenaltyForm {
 public:
  PenaltyForm() = default;
  // Analyzes the body graph of H (the constraints' body pairs and the rotors') and finds
  // each constraint's blocks.
  explicit PenaltyForm(const System& sys);
  // H into the factor's storage (M~: the stand-in masses, System::Minv, as
  // Levenberg-Marquardt damping).
  void assemble(const System& sys, const Evaluation& ev, double kappa, double mass, double shift);
  // Adds weight * rows^T rows for rows over the bodies of a constraint (6 columns a body,
  // in its bodies' order): assembly's targets, stiff damping's coordinate rows.
  template <class Rows>
  void addRows(const System& sys, int constraint, const Eigen::MatrixBase<Rows>& rows, double weight) {
    const ConstraintLayout& L = sys.layout[constraint];
    const int k = static_cast<int>(L.bodies.size());
    for (int k1 = 0; k1 < k; ++k1)
      for (int k2 = k1; k2 < k; ++k2) {
        const int address = address_[constraint][k1 * k + k2];
        if (address < 0) continue;
        const Mat6 B = weight * rows.template middleCols<6>(6 * k1).transpose() * rows.template middleCols<6>(6 * k2);
        if (transposed_[constraint][k1 * k + k2]) chol_.block(address) += B.transpose();
        else chol_.block(address) += B;
      }
  }
  int factorize(double pivot_tol, bool skip_zero) { return chol_.factorize(pivot_tol, skip_zero); }
  // Row weights (with reweight), H with kappa, factored; SimulationError when singular.
  void factor(const System& sys, Evaluation& ev, const char* where, double t, bool reweight);
  void solve(double* x) const { chol_.solve(x); }
  bool zeroPivot(int b, int r) const { return chol_.zeroPivot(b, r); }
  BlockCholesky& cholesky() { return chol_; }

 private:
  BlockCholesky chol_;
  // per constraint: the block of its slot pair (k1, k2), k1 <= k2, at k1 * k + k2 (-1: the
  // ground), and whether it is stored transposed
  std::vector<std::vector<int>> address_;
  std::vector<std::vector<char>> transposed_;
};

// Adds mass times the rotor inertias' G^T B G (System::rotors) into H's body blocks.
void addRotorBlocks(const System& sys, const Evaluation& ev, double mass, BlockCholesky& H);

// Adds kappa J_c^T W_c J_c of constraint ci into `target` at the given block addresses
// (lower triangle of the diagonal blocks).
void addPenalty(const System& sys, const Evaluation& ev, int ci, double kappa, BlockCholesky& target,
                const int* address, const char* transposed);

class ConstraintSolver {
 public:
  // Dimensionless weight of the equations in H = M + kappa Phi_q^T W Phi_q (solver.cpp).
  static constexpr double kKappa = numerics::absolute::kKappa;
  // What H is when a solve starts: not yet factored for this step (factor before the
  // first pass), factored at the evaluated positions, or factored at nearby positions
  // (refactored when the passes converge slowly).
  enum class HState { kNone, kCurrent, kNearby };

  ConstraintSolver(const System& sys, SolverStats& stats);
  virtual ~ConstraintSolver() = default;
  virtual const char* name() const = 0;
  // Whether the factorization holds constraint ci's equations exactly as block rows (a
  // tree joint's, in the tree KKT form), so that they never depend on others.
  virtual bool holdsExactly(int /*ci*/) const { return false; }

  // Factors at the evaluation (row weights taken again with reweight); throws
  // SimulationError naming `where` and t when the constrained mass matrix is singular.
  void factor(const System& sys, Evaluation& ev, const char* where, double t, bool reweight = true);
  // The penalty form at the evaluation, every row weighted (least-norm multipliers,
  // assembly), whatever the implementation.
  void factorPenalty(const System& sys, Evaluation& ev, const char* where, double t);
  // The penalty form, for those who assemble H themselves (assembly, stiff damping); after
  // factoring it, usePenalty(false) makes precondition() apply it (the factorization then
  // describes no evaluation: whoever needs one factors again).
  PenaltyForm& penalty() { return penalty_; }
  void usePenalty(bool describes_evaluation);
  // Whether a factorization of the equations is at hand (nearby positions will do), and
  // whether the last one was taken at these positions and active limits.
  bool factored() const { return factored_.level != EvaluationStamp::kNone; }
  bool factoredAt(const EvaluationStamp& s) const {
    return factored_.level != EvaluationStamp::kNone && factored_.samePositions(s);
  }

  // The factored matrix applied to residuals r1 (per body) and r2 (per row), writing dn()
  // and, with multipliers, dl():
  //   [M + J_p^T W J_p, J_t^T; J_t, 0] [dn; dl_t] = [r1 + J_p^T W r2_p; r2_t],
  //   dl_p = W (J_p dn - r2_p)  (t: rows held exactly, p: penalized rows, W with kappa).
  virtual void precondition(const System& sys, const Evaluation& ev, const double* r1, const double* r2,
                            bool multipliers) = 0;
  // dn() <- P dn(): the constrained inverse mass applied to the generalized force in dn()
  // (exactly on the tree KKT matrix, to 1/kappa with H).
  void applyInverseMass(const System& sys, const Evaluation& ev) {
    precondition(sys, ev, dn_.data(), zero_rows_.data(), false);
  }
  Eigen::VectorXd& dn() { return dn_; }
  const Eigen::VectorXd& dl() const { return dl_; }

  // Refines accelerations a and multipliers lambda (warm start) on the KKT system at the
  // evaluation (ev.Q, ev.gamma, ev.J) to solve_tol; with rescale false the residual scales
  // of the last solve are kept (the stages of one step: their terms differ by O(h)).
  // Returns whether it met the tolerance (a shortfall is counted).
  bool solve(const System& sys, Evaluation& ev, Eigen::VectorXd& a, Eigen::VectorXd& lambda, HState h,
             double t, bool rescale = true);

 protected:
  virtual void factorHere(const System& sys, Evaluation& ev, const char* where, double t, bool reweight) = 0;
  void residualScales(const System& sys, const Evaluation& ev, const Eigen::VectorXd& a, const Eigen::VectorXd& lambda);
  // The penalty form's preconditioner (every row weighted).
  void preconditionPenalty(const System& sys, const Evaluation& ev, const double* r1, const double* r2,
                           bool multipliers);

  SolverStats& stats_;
  PenaltyForm penalty_;
  bool penalty_active_ = true;  // the last factorization is penalty_'s
  EvaluationStamp factored_;    // positions and limits of the last factorization
  Eigen::VectorXd r1_, r2_, s1_, s2_, dn_, dm_, dl_, zero_rows_;
  std::vector<std::array<double, 2>> body_scale_;
};

// Every equation in penalty form: mechanisms with loop closures or couplers (and any other
// that is not a tree of definite bodies).
class PenaltySolver : public ConstraintSolver {
 public:
  using ConstraintSolver::ConstraintSolver;
  const char* name() const override { return "penalty"; }
  void precondition(const System& sys, const Evaluation& ev, const double* r1, const double* r2,
                    bool multipliers) override {
    preconditionPenalty(sys, ev, r1, r2, multipliers);
  }

 protected:
  void factorHere(const System& sys, Evaluation& ev, const char* where, double t, bool reweight) override;
};

// The tree's joints (with their drives and limits) as block rows of the quasi-definite KKT
// matrix, eliminated leaves first (KktTopology); drives and limits that do not fit in their
// joint's block in penalty form. Where a tree pivot is not definite (its joint's equations
// dependent at this configuration) that factorization takes the penalty form.
class TreeKktSolver : public ConstraintSolver {
 public:
  TreeKktSolver(const System& sys, KktTopology topology, SolverStats& stats);
  const char* name() const override { return "tree KKT"; }
  bool holdsExactly(int ci) const override { return T_.node[ci] >= 0; }
  void precondition(const System& sys, const Evaluation& ev, const double* r1, const double* r2,
                    bool multipliers) override;
  // The KKT matrix at the evaluation (bench_factor.cpp times its factorization).
  void assembleKKT(const System& sys, const Evaluation& ev);
  BlockCholesky& kkt() { return kkt_; }

 protected:
  void factorHere(const System& sys, Evaluation& ev, const char* where, double t, bool reweight) override;

 private:
  KktTopology T_;
  BlockCholesky kkt_;
  Eigen::VectorXd z_;
};

// The implementation for this mechanism: the tree KKT form where kktTopology(sys) is a tree.
std::unique_ptr<ConstraintSolver> makeSolver(const System& sys, SolverStats& stats);

// Multipliers of the equality constraints with the least weighted norm sum_e lambda_e^2 /
// w_e (w_e the row weight) among all that give s's constraint forces Q - M a, dependent
// equations included: the same at the same state whatever the history (where the
// equations are independent: s.lambda itself). Limits keep s's multipliers. Evaluates s
// into ev (every row) and factors the penalty form there. Returns the relative residual
// left (a shortfall is counted in the solver's stats).
double minimumNormMultipliers(const System& sys, const State& s, const Inputs& in, Evaluation& ev,
                              ConstraintSolver& solver, SolverStats& stats, Eigen::VectorXd& lambda);

}  // namespace mechanism_sim
