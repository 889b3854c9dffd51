// Loop closures on the joint-space tree (joint_space/tree.h): the joints the spanning tree does
// not use (TreeModel::cut_joints) keep the seed lecture's constraint equations
// Phi(x) = 0 (Joint::evaluate at the absolute poses forwardKinematics gives), and become
// constraints on the tree coordinates q (Featherstone, "Rigid Body Dynamics Algorithms"
// (RBDA), 2008, chapter 8, "Closed Loop Systems", 8.1-8.3):
//
//   G = Phi_x J(q)            (m x nv), J(q) mapping q_dot to the bodies' velocities
//                             (v global, omega' body: the seed's [delta r, delta theta'])
//   G q_ddot = gamma_q        gamma_q = gamma - Phi_x (J_dot q_dot): from the absolute
//                             Phi_x a = gamma with a = J(q) q_ddot + J_dot q_dot
//   M q_ddot + h = tau - G^T lambda                     (RBDA 8.1, eq. 8.3, with the seed's
//                                                        sign: M a + Phi_q^T lambda = Q)
//   q_ddot = q_ddot_free - M^-1 G^T lambda,  (G M^-1 G^T) lambda = G q_ddot_free - gamma_q
//                                                       (RBDA 8.3, eqs. 8.12-8.13)
// with M^-1 G^T from articulated-body passes on G's rows (zero velocity, zero gravity: the
// "inverse mass" application, RBDA 8.3 / 7.3), no M or M^-1 formed. lambda per closure row
// is then the absolute formulation's multiplier of that row (same sign), so reactions
// compare. Dependent closure rows (a planar four-bar's cut revolute: 3 of its 5 rows) are
// handled by a rank-revealing solve: rows whose G entries are all round-off against their
// own terms are dropped (lambda 0), the rest Jacobi-scaled (row e by 1/sqrt(A_ee)) and
// solved by a complete orthogonal decomposition with relative threshold
// kClosureRankThreshold: the least-norm lambda of the scaled system.
//
// Closures are every constraint of the System the tree does not hold: cut joints, and
// couplers (URDF mimic), couplings (sum_i c_i q_i = c_0, coupling.h), drives (rheonomic:
// Phi_q v = nu, gamma with the prescribed acceleration) and position limits (a zero row
// while the limit's side in the context is 0, dropped by the solve with lambda 0). All of
// them go through the same G = Phi_x J(q): their absolute equations (Constraint::evaluate
// with the caller's EvalContext) are the reference, and mapping Phi_x through J(q)
// reproduces them to round-off whatever the joint type, the link's direction (reversed) or
// the coordinate's branch (tracked angles). Limits, couplers and couplings on coordinates
// of tree links other than spherical ones (whose q are the joints' own coordinates,
// Joint::coordinates) skip that mapping: their rows are e_k^T (a limit on a sum: sum_i
// c_i e_i^T), e_a^T - r e_b^T and sum_i c_i e_i^T, gamma_q 0 (DirectRow); Phi still comes from their absolute equations.
// A free limit (side 0) is a zero row and is not evaluated at all. Drives, and rows on
// spherical coordinates or cut joints, go through the mapping.
// Closures are listed in System order, so closure row e is System row sys_row[e] and
// lambda(e) is State::lambda(sys_row[e]) of the absolute formulation.
#pragma once
#include <vector>

#include <Eigen/Core>
#include <Eigen/Cholesky>
#include <Eigen/QR>
#include <Eigen/SVD>

#include "core/joint_space/closure_solver.h"
#include "core/joint_space/tree.h"
#include "core/linalg/scaled_least_norm.h"

namespace mechanism_sim {

// The branch passages' gate for a closure of two normalized rows W (2 x k, k >= 2):
// whether W W^T - shift I is positive definite as Eigen's LLT decides it (the same
// operations in the same order; branch_passage.cpp).
bool passageGateTwoRows(const Eigen::Ref<const Eigen::MatrixXd>& W, double shift);

// The closures' thresholds (numerics.h says why each has its value).
using numerics::joint_space::kClosureZeroEntry;
using numerics::joint_space::kPassageBand;
using numerics::joint_space::kPassageDependent;
using numerics::joint_space::kPassageNear;
using numerics::joint_space::kPassageGate;
using numerics::joint_space::kPassageRoundoffSteps;
using numerics::joint_space::kRoundoffStepBound;

struct ClosureSolveInfo {
  int rows = 0;       // closure rows m
  int rank = 0;       // independent rows
  int dependent = 0;  // m - rank (rows of G that are zero, or combinations of others)
};

struct ClosureProjectionReport {
  bool converged = false;
  int iterations = 0;
  double residual = 0.0;  // relative, as closureResidual / closureVelocityResidual
  int dependent = 0;      // at the last linear solve (0: none was needed)
  // ws holds the kinematics of (q, the rates asked for) and the closures' evaluation is
  // there: constrainedForwardDynamics(..., evaluated = true) may start from them
  bool at_rates = false;
};

// How a solve treats branch passages and what it forms: the caller's choice per call
// (constrainedForwardDynamics, projectClosurePositions, projectClosureVelocities), not
// state of the closures.
//   passage_ref: where two branches of a loop cross (a parallelogram four-bar passing flat),
//     G loses a rank that the loop's geometry, not round-off, takes away: locally Phi ~ x y
//     with x along the motion and y across it. Near the crossing the equations determine y
//     only to eps / x, its rate to eps / x^2 and its acceleration to eps / x^3, so any solve
//     there (a stage, a projection) turns round-off into motion. passage_ref, when set (the
//     joint stepper sets it to the accelerations at the start of its step), makes every
//     solve take the passage instead (branch_passage.cpp): each closure's rows are
//     normalized by the size of their terms (rates as speeds: W = D_r G diag(1/unit)),
//     decomposed W = U S V^T, and a direction whose singular value is below kPassageBand
//     (and above kPassageDependent: a structural dependency) is held by the motion instead
//     of by the equations: its acceleration (v o unit)^T a is passage_ref's (the transverse
//     acceleration is continuous along the branch), the projections leave its position and
//     rate as the integration carried them. The other directions keep the equations
//     exactly (v_i^T a = u_i^T D_r gamma_q / s_i). Outside a passage nothing changes.
//     nullptr: no passage is looked for.
//   passage_hold: false: the decomposition applies, nothing is held (a settle).
//   regular_factor: whether constrainedForwardDynamics also factors the ordinary closure
//     solve (factor()) where it takes a passage's: solve() and Y read that factorization
//     (the joint stepper's friction and damping at a step's start); false skips it (the
//     later stages).
//   form_Y: whether the factorization also forms Y = M^-1 G^T (the solves themselves do
//     not need it: a caller that reads Y).
struct ClosureSolveMode {
  const Eigen::VectorXd* passage_ref = nullptr;
  bool passage_hold = true;
  bool regular_factor = true;
  bool form_Y = true;
};

// The branch passages' state and scratch (branch_passage.cpp, LoopClosures::findPassage):
// the closures' decompositions at the last evaluation, the directions held by the motion,
// and the factorization of the reduced rows R M^-1 R^T.
struct BranchPassageWork {
  using Small6 = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, 6, 6>;
  // Per reduced row j (one per direction of a
  // closure's decomposition that is not dependent): R_j = sum_e P(j, e) G_e (= (v_j o unit)^T),
  // held_[j] whether it is held by the motion. Per held or dependent direction: w = D_r u,
  // z = D_r^-1 u over the System rows (the component b' = b - z (w . b) is not judged).
  Eigen::MatrixXd P, R, A, w, z;
  std::vector<char> held;
  Eigen::VectorXd b, g, mu, dr;
  Eigen::MatrixXd W;  // one closure's normalized rows, over its columns
  Small6 gram;        // W W^T - kPassageGate^2 I and its Cholesky factor (findPassage's
  Eigen::LLT<Small6> llt;  // test away from passages)
  std::vector<int> rows, cols;
  Eigen::VectorXd m, h;  // a closure's rates and held direction over its columns
  Eigen::VectorXd rate;     // findPassage()'s rate at its last call (rate_set)
  bool rate_set = false;
  Eigen::JacobiSVD<Eigen::MatrixXd> svd;
  Eigen::JacobiSVD<Small6> svd6;  // (the same up to 6 x 6)
  // (and a planar loop's two rows over three columns, a four-bar's, in fixed-size storage:
  // the same operations, bit for bit, for less work; V in full, its first two
  // columns the thin V's)
  Eigen::JacobiSVD<Eigen::Matrix<double, 2, 3>> svd23;
  int r = 0, band = 0;
  int excl = 0;  // rows of w, z: the held directions and the dependent ones
  std::vector<char> excl_held;  // per row of w: a held direction (else dependent)
  std::vector<char> release;    // per closure: its passage released (held by the equations)
  std::vector<char> in_band;    // per closure: a direction below kPassageBand at the last findPassage()
  bool near = false, reduce = false;
  long met = 0;
  ScaledLeastNorm least_norm;  // of R M^-1 R^T (rows of different closures may depend)
  ClosureSolver solver;            // the sparse solve of the passages' rows R (slot e: the closure of row e of G)
  Eigen::VectorXd keep;            // per slot of R: 1 for a direction kept
  std::vector<int> used;           // per closure: its slots used at the last findPassage()
  long gen = 0;                    // findPassage()'s results
  long at_g = -1, fac_at_p = -1, fac_at_ws = -1;  // the generations they were made at
  bool at_hold = true;
};

// What the closures of a tree are, built once from the tree and the System: which System
// constraints the tree does not hold (cut joints, couplers, couplings, drives, limits), their
// rows' layout in System order (less the idle rows no motion moves), the rows taken directly
// on q, and the coordinates each row may touch. Nothing in it changes with an evaluation or
// a solve; LoopClosures, the workspace that evaluates and solves the closures, is built on it.
class ClosureRows {
 public:
  // sys constraint index per closure, ascending: every constraint that is not a tree
  // joint's (cut joints, couplers, drives, limits)
  std::vector<int> constraints;
  std::vector<int> row;          // first closure row per closure
  std::vector<int> sys_row;      // per closure row: its System row (sys.layout[c].row + e)
  int m = 0;                     // closure rows (less the idle ones: idleRowCount())
  int nv = 0;
  // Rows of the closures' equations no motion of the tree moves, left out (LoopClosures::idleRows)
  int idleRowCount() const { return idle_; }
  // The coordinates closure row e may touch: those on its bodies' paths to the root (G, Gabs
  // and Gbound are zero in every other column)
  const std::vector<int>& rowColumns(int e) const { return ccols_[cl_of_[e]]; }
  // Whether every closure is a limit (none: true).
  bool onlyLimits() const { return only_limits_; }

 protected:
  // The closures and their direct rows; the rows' layout is layOut()'s.
  ClosureRows(const TreeModel& model, const System& sys);
  // The rows of each closure's constraint but those idle[i] marks (empty: every one).
  void layOut(const System& sys, const std::vector<std::vector<char>>& idle);
  // A limit or a coupler on coordinates of tree joints whose coordinates are q's own
  // (every link but a spherical one): its row of G is sum_i c_i e_i (limit, coupling) or
  // e_a - r e_b (coupler) and gamma_q is 0, without the mapping through J(q).
  struct DirectRow {
    int n = 0;           // entries (0: not direct)
    int col[kMaxCoordinateEfforts] = {};   // velocity coordinates
    int qcol[kMaxCoordinateEfforts] = {};  // their position coordinates
    double coef[kMaxCoordinateEfforts] = {};
    double offset = 0.0;  // a coupler's or coupling's: Phi = sum coef q - offset
    int limit = -1;       // a limit's (System limit index): Phi = sum coef q - its bound on the active side
    bool angle[kMaxCoordinateEfforts] = {};
  };
  std::vector<DirectRow> direct_;  // per closure
  // per sys limit: its closure where that is a direct row (its sum over coordinates of q), or -1
  std::vector<int> limit_direct_;
  std::vector<char> implied_;      // per sys limit: a held slave's, implied by its master's (never active)
  std::vector<int> nrows_;         // per closure: its rows (the constraint's, less its idle ones)
  // Idle rows (LoopClosures::idleRows): rows of a closure's equations whose G row is zero
  // wherever the tree is (a planar loop's out-of-plane rows), so that no motion of the tree
  // changes them. They are left out of the closures' rows: per closure the constraint's rows
  // that are kept (empty: every one), and the idle ones' System rows (their multipliers are 0).
  std::vector<std::vector<int>> sel_;
  std::vector<unsigned> sel_mask_;         // the kept rows as bits, for Joint::evaluateRows
  std::vector<const Joint*> sel_joint_;    // the closure's joint (kept rows of a joint), or null
  std::vector<int> idle_sys_rows_;
  int idle_ = 0;
  int allRows() const { return m + idle_; }  // the closures' equations, idle ones too (info)
  std::vector<char> angle_;        // per velocity coordinate: an angle
  Eigen::VectorXd unit_;           // per velocity coordinate: length scale (an angle) or 1
  bool only_limits_ = false;       // every closure is a limit
  std::vector<int> limits_;        // per closure: its System limit index (-1: not a limit)
  // max_k |dv_k| unit_k: a correction's size as a length (positions) or speed (rates)
  double correctionSize(const Eigen::VectorXd& dv) const;
  // per closure: the coordinates its rows can touch (the sparse solve's blocks,
  // ClosureSolver::blockCols); per row: its closure
  std::vector<std::vector<int>> ccols_;
  std::vector<int> cl_of_;
};

// The closures of a tree (ClosureRows) and the workspace their evaluations and solves
// write: sized once by the constructor.
class LoopClosures : public ClosureRows {
 public:
  LoopClosures(const TreeModel& model, const System& sys);

  // The System the closures read between calls (their sizes, the constraints' equations):
  // one with the same layout as the constructor's. A Mechanism's parameters change by copy
  // on write (a new System, the constraints shared), so its stepper rebinds on every call.
  void rebind(const System& sys) { sys_ = &sys; }

  // The context the closures' equations read. By default the closure's own copies (from
  // initialState(sys): tracked angles per sys constraint, limit sides all 0 (free), drive
  // ramps, t; track() keeps the tracked angles; set them freely). setContext(ctx) makes
  // every later evaluation read the caller's context instead (State::context(): its
  // pointers must stay valid while used; call it again after the State's vectors are
  // reallocated, or per evaluation through evaluate(model, sys, ws, ctx)); clearContext()
  // goes back to the copies.
  std::vector<Tracked> tracked;
  std::vector<signed char> limit_side;
  std::vector<DriveRamp> drive;
  double t = 0.0;
  void setContext(const EvalContext& ctx) { external_ = ctx, has_external_ = true; }
  void clearContext() { has_external_ = false; }
  EvalContext context() const {
    return has_external_ ? external_ : EvalContext{tracked.data(), limit_side.data(), t, drive.data()};
  }

  // ---- evaluate(): at the kinematics in a TreeWorkspace
  Eigen::VectorXd Phi, gamma;  // the absolute formulation's, per closure row
  Eigen::VectorXd scale;       // per row: the size of Phi's terms (as evaluation.cpp)
  Eigen::MatrixXd G;           // Phi_x J(q), m x nv
  Eigen::MatrixXd Gabs;        // |Phi_x| |J(q)|: the size of each entry's terms
  Eigen::MatrixXd Gbound;      // the same with norms of the rows' and columns' parts: does
                               // not vanish with the geometry (branch passages)
  Eigen::VectorXd gamma_q;     // G q_ddot = gamma_q
  Eigen::VectorXd nu;          // G q_dot = nu (drives' velocity terms; 0 for the rest)
  std::vector<Eigen::MatrixXd> Jc;  // per closure: Phi_x (size x 6 slots)
  // (G, Gabs and Gbound are the caller's to read, not to write: evaluate() keeps a closure's
  // rows while their inputs hold the same bits, and findPassage() and factor() their results)

  // ---- solves
  Eigen::MatrixXd Y;       // M^-1 G^T (nv x m), formed by factor(..., form_Y = true)
  Eigen::VectorXd lambda;  // multipliers per closure row (absolute sign convention)
  ClosureSolveInfo info;   // of the last solve

  // Phi, Jc, G, Gabs, gamma_q at ws's kinematics (forwardKinematics or forwardDynamics at
  // (q, q_dot): gamma_q needs q_dot).
  void evaluate(const TreeModel& model, const System& sys, const TreeWorkspace& ws);
  // The same with the tree's coordinates q of ws's kinematics: the direct rows (limits and
  // couplers on tree coordinates) then take Phi from q itself (q_a - r q_b - offset,
  // q - bound), not from their absolute equations (the joints' coordinates at the poses,
  // which are the same numbers: q_k is Joint::coordinates' Phi), and their absolute gamma
  // is not computed (0).
  void evaluate(const TreeModel& model, const System& sys, const TreeWorkspace& ws, const Eigen::VectorXd& q) {
    q_ = &q;
    evaluate(model, sys, ws);
    q_ = nullptr;
  }
  // The same with the caller's context (setContext(ctx), then evaluate).
  void evaluate(const TreeModel& model, const System& sys, const TreeWorkspace& ws, const EvalContext& ctx) {
    setContext(ctx);
    evaluate(model, sys, ws);
  }
  // lambda into a vector over the System's rows (State::lambda's layout, size sys.m):
  // out(sys_row[e]) = lambda(e); the tree joints' rows are left as they are.
  void systemMultipliers(Eigen::VectorXd& out) const {
    for (int e = 0; e < m; ++e) out(sys_row[e]) = lambda(e);
    for (int r : idle_sys_rows_) if (r >= 0) out(r) = 0.0;  // (rows no motion moves: no force)
  }
  // tau += (q_x,k J(q))^T tau_k for every cut joint's coordinate k with effort tau_k in `in`
  // (its rows q_x,k from Joint::coordinates over its two bodies, mapped as G), at ws's
  // kinematics; returns whether any such effort is nonzero.
  bool addCutJointEfforts(const TreeModel& model, const System& sys, const TreeWorkspace& ws, const Inputs& in,
                          Eigen::VectorXd& tau);
  // max_e |Phi_e| / scale_e (0/0 = 0), after evaluate().
  double positionResidual() const;
  // max_e |(G q_dot - nu)_e| / (sum_k |G_ek| (|q_dot_k| + |reference_k|) + |nu_e|) (0/0 = 0), after
  // evaluate(): reference, when given, holds rates the q_dot was computed from (the
  // velocity projection passes its input, so a mechanism the closures lock, where q_dot
  // ends at round-off, is judged against the rates that came in).
  double velocityResidual(const Eigen::VectorXd& qdot, const Eigen::VectorXd* reference = nullptr) const;
  // out = M^-1 tau by articulated-body passes with zero velocity and gravity on the
  // articulated inertias in ws (forwardDynamics at the same q computed them).
  void applyInverseMass(const TreeModel& model, const TreeWorkspace& ws, const double* tau, double* out);
  // Its outward pass alone: out holds u = L^-T tau (the inward pass's), q_ddot = M^-1 tau after.
  void outwardInverseMass(const TreeModel& model, const TreeWorkspace& ws, double* out);
  // The same by the joint-space inertia factored at ws (closure_solver.h): factorMass(model,
  // ws) once (O(n d^2)), then each inverseMass(x) (x = M^-1 x in place) costs O(n d), less
  // for a unit vector. The closures' own solves factor it themselves.
  void factorMass(const TreeModel& model, const TreeWorkspace& ws) { factors_.mass.compute(model, ws); }
  void inverseMass(double* x) const { factors_.mass.solve(x); }
  // out = G v, and out = M^-1 G^T x at factorMass()'s factors, over each closure row's
  // coordinates (G is zero elsewhere)
  void timesG(const Eigen::VectorXd& v, Eigen::VectorXd& out) const { rowsTimes(G, v, out); }
  void inverseMassGT(const Eigen::VectorXd& x, Eigen::VectorXd& out) const;
  // The factorization of G M^-1 G^T, and with form_Y Y = M^-1 G^T (after evaluate() and
  // forwardDynamics).
  void factor(const TreeModel& model, const TreeWorkspace& ws, bool form_Y = true);
  // Whether every closure is a limit and every limit is free in context(): then every
  // row is zero wherever the tree is, and clearRows() gives what evaluate() and factor()
  // would (zero rows, lambda = 0), without the kinematics (a tree arm between its stops).
  bool allFreeLimits() const;
  void clearRows();
  // x = (G M^-1 G^T)^+ b as above (after factor()); x and b of size m (x may be b).
  // No allocation.
  void solve(const Eigen::VectorXd& b, Eigen::VectorXd& x) const;
  // Limits' activation, the caller's (the absolute Stepper's rules, on limit_side: size
  // sys.limits.size(), e.g. State::limit_side.data()):
  //   activateReachedLimits: a free limit whose coordinate is past a bound gets side -1 /
  //     +1 (one a drive moves throws SimulationError past round-off: drivenAtLimit); the
  //     coordinate is q's own where the limit is on a tree coordinate (a direct row),
  //     else Joint::coordinates at q's kinematics (forwardKinematics into ws, only then),
  //     tracked angles of context();
  //   releasePullingLimits: after a solve (lambda), an active limit whose multiplier would
  //     pull (side -1 with lambda > 0, side +1 with lambda < 0) gets side 0.
  // Both return how many sides they changed; the caller then evaluates and solves again.
  int activateReachedLimits(const System& sys, const TreeModel& model, const Eigen::VectorXd& q,
                            const Eigen::VectorXd& qdot, TreeWorkspace& ws, signed char* limit_side);
  int releasePullingLimits(signed char* limit_side) const;
  // ---- branch passages (branch_passage.cpp; ClosureSolveMode says when the solves take them)
  // After evaluate(): each closure's rows (those that are not round-off) decomposed on their
  // own. true where some closure is near a loss of rank (a singular value below
  // kPassageGate: a passage, or one coming) or has rows that are dependent without being
  // zero: the solves then take the decomposition's rows (the regular directions by their
  // equations, the held ones by the motion, the dependent ones, s below kPassageDependent,
  // dropped by this geometric threshold rather than by the rank threshold of the
  // Jacobi-scaled G M^-1 G^T, which near a crossing keeps their round-off and leaves no null
  // space: a four-bar whose cut joint has non-zero dependent rows stopped dead at its flat
  // passage). false: the ordinary solves apply. hold: ClosureSolveMode::passage_hold. rate:
  // the rates of the motion at these coordinates (the acceleration solves pass their q_dot;
  // nullptr: none, as in the projections): a held direction is then taken across the motion
  // (branch_passage.cpp, "across the motion"), its reaction doing no work on it.
  bool findPassage(bool hold = true, const Eigen::VectorXd* rate = nullptr);
  // Directions held by the motion at the last findPassage(), and how many passages were met
  // (findPassage() calls that found one) since construction.
  int passageDirections() const { return passage_.band; }
  long passagesMet() const { return passage_.met; }
  // Whether the last findPassage() saw a direction below kPassageNear (a passage, or one
  // close): the projections then go on to round-off past their tolerance.
  bool passageNear() const { return passage_.near; }
  // max_e |b''_e| / scale_e, b'' = b's components on the held directions (0: none held)
  double heldResidual(const Eigen::VectorXd& b, const Eigen::VectorXd& scale_e);
  // The closures with a held direction at the last findPassage() are released: held by
  // their equations until they leave the band. Returns whether any was.
  bool releaseHeld();
  // At an accepted state (the position projection's end): closures out of the band there
  // end their spell (the next passage is held again).
  void endPassageSpells();
  // What the last findPassage() returned (at the last evaluate()).
  bool passageFound() const { return passage_.reduce; }

  // The tracked angles of the System constraints `which` (tracked: indexed by System
  // constraint, e.g. State::tracked) moved to ws's kinematics (Constraint::trackAngles, reading
  // context()), after an accepted step: the joint stepper's cut joints.
  void track(const TreeWorkspace& ws, const std::vector<int>& which, std::vector<Tracked>& tracked);

 private:
  void loadKin(const TreeWorkspace& ws);
  const Eigen::VectorXd* q_ = nullptr;  // evaluate()'s q, for the direct rows' Phi
  // The rows' layout (ClosureRows::layOut) and everything sized by it; the evaluations'
  // kept results are forgotten.
  void layout(const TreeModel& model, const System& sys, const std::vector<std::vector<char>>& idle);
  std::vector<std::vector<char>> idleRows(const TreeModel& model, const System& sys);
  // evaluate()'s mapping of one body's rows onto G, Gabs and Gbound (loop_closure.cpp)
  static constexpr int kSmallRows = 6;
  using SmallRows = Eigen::Matrix<double, Eigen::Dynamic, 6, Eigen::RowMajor, kSmallRows, 6>;
  template <class JB, class JA>
  void mapBody(const TreeModel& model, const TreeWorkspace& ws, int b, const JB& Jb, const JA& Jabs, int r0, int n);
  bool cleared_ = false;            // clearRows() ran since the last evaluate()
  bool closureRows(size_t c);
  BranchPassageWork passage_;  // branch_passage.cpp
  // R, M^-1 R^T and the factor of R M^-1 R^T at ws (after findPassage() > 0)
  void passageFactor(const TreeModel& model, const TreeWorkspace& ws);
  // per closure row: r = G q_dot - nu and the size of its terms t (velocityResidual's)
  void velocityRows(const Eigen::VectorXd& qdot, const Eigen::VectorXd* reference, Eigen::VectorXd& r,
                    Eigen::VectorXd& t) const;
  // g = P b, 0 on the held rows; with accel (ClosureSolveMode::passage_ref), R_j accel on
  // the held rows
  void passageRhs(const Eigen::VectorXd& b, Eigen::VectorXd& g, const Eigen::VectorXd* accel = nullptr) const;
  // lambda = P^T mu (G^T lambda = R^T mu)
  void passageMultipliers(const Eigen::VectorXd& mu);
  // max_e |b'_e| / scale_e, b' = b without its components on the held directions
  double passageResidual(const Eigen::VectorXd& b, const Eigen::VectorXd& scale_e);
  // out = G v over each row's coordinates (G is zero elsewhere)
  void rowsTimes(const Eigen::MatrixXd& R, const Eigen::VectorXd& v, Eigen::VectorXd& out) const;
  // out = R^T x over each row's coordinates (R laid out as G); false where x = 0
  bool rowsTransposeTimes(const Eigen::MatrixXd& R, const Eigen::VectorXd& x, Eigen::VectorXd& out) const;
  // Whether row e of G is round-off against its terms at every coordinate (kClosureZeroEntry)
  bool roundoffRow(int e) const {
    for (int k : ccols_[cl_of_[e]])
      if (std::fabs(G(e, k)) > kClosureZeroEntry * Gabs(e, k)) return false;
    return true;
  }
  // out = M^-1 R^T x, R laid out as G (rows in the closures' slots), at ws: R = G or the
  // passages' passage_.R right after their factorization (factor(), passageFactor() at the same
  // G or R and ws: every caller) from its passes on the rows (ClosureSolver::inwardOfRowsT)
  // and the outward pass; any other R by an inverse-mass pass (applyInverseMass)
  void inverseMassRowsT(const TreeModel& model, const TreeWorkspace& ws, const Eigen::MatrixXd& R,
                        const Eigen::VectorXd& x, Eigen::VectorXd& out);
  void passageSolve(const Eigen::VectorXd& b, Eigen::VectorXd& x) const {
    passage_.solver.solve(passage_.least_norm, b, x);
  }
  // Work on inputs that hold the bits of the last call's is not done again (the stepper
  // evaluates each accepted q at rest for its projections, then in motion for the
  // accelerations, and a step whose inputs were set again recomputes its first stage
  // there): evaluate() keeps a closure's rows of G, Gabs and Gbound where its Jc and the
  // links' poses and subspaces are unchanged, findPassage() its results while G is,
  // factor() and passageFactor() theirs while their rows and ws's articulated factors are.
  // The generations count changes; an "at" member is the generation a result was made at.
  enum class RowsOf : signed char { kUnknown, kZero, kDirect, kMapped };
  // What evaluate() and factor() reuse while their inputs hold the same bits.
  struct Reuse {
    std::vector<RowsOf> rows_of;             // per closure: what its rows of G hold
    std::vector<Eigen::MatrixXd> Jc_mapped;  // per closure: the Jc they were mapped from
    AlignedVector<Matrix3d> pose_A;          // the links' poses and subspaces at the last evaluate()
    AlignedVector<Vector3d> pose_r;
    AlignedVector<MotionSubspace> pose_S;
    Eigen::VectorXd pose_q;                  // or the tree's q there (evaluate(..., q))
    bool pose_by_q = false, pose_by_x = false;  // which of the two the last mapping kept
    long g_gen = 0;   // G, Gabs, Gbound
    long fac_at_g = -1, fac_at_ws = -1;
    bool fac_Y = false;
    ClosureSolveInfo fac_info;
  };
  Reuse reuse_;
  // The closures' factorizations: the dense fallback, the joint-space inertia factored
  // (factorMass), the sparse solves of G and of the passages' rows R (slot e of R: the
  // closure of row e of G), the rows kept
  struct Factors {
    Eigen::MatrixXd A;            // G M^-1 G^T (the dense solve's; scaled in place)
    ScaledLeastNorm least_norm;   // its dense factorization (closure_solver.h: the fallback)
    TreeMassFactor mass;
    ClosureSolver solver;
    Eigen::VectorXd keep;         // per row: 1, or 0 for a dropped (zero) row
    bool all_zero = false;        // every row dropped at the last factor()
  };
  Factors factors_;
  // The scratch of one call (evaluate(), the solves, the projections): nothing in it is
  // read across calls.
  struct Scratch {
    std::vector<BodyKin> kin;      // ground first
    AlignedVector<Vector6d> pa, a;  // inverse-mass passes
    AlignedVector<Vector6d> a0;     // spatial accelerations at q_ddot = 0
    Eigen::VectorXd tau, qdd_cut;
    Eigen::VectorXd zero_v, qdd_v, dv_v, ref_v, r_m, x_m;  // the projections'
    Eigen::VectorXd vr, vt;         // velocityRows' (a const query)
    // evaluate()'s: per body of a closure its lever (scale), per row the norms of the row's
    // parts on a body's [v; omega'] (Gbound)
    double lever[kMaxConstraintBodies] = {};
    Eigen::Matrix<double, Eigen::Dynamic, 2> jnorm;
    std::vector<Eigen::MatrixXd> Jc_full;  // the closures' rows, idle ones too
    Eigen::VectorXd Phi_full, gamma_full;
  };
  mutable Scratch scratch_;
  // ws's articulated factors' generation (TreeWorkspace::generation)
  long massFactorsGeneration(const TreeWorkspace& ws);
  void factorNow(const TreeModel& model, const TreeWorkspace& ws);
  // Y = M^-1 G^T at factorNow()'s factors (its kept rows; a dropped row's column 0)
  void formY(const TreeModel& model, const TreeWorkspace& ws);
  bool findPassageNow();
  const TreeModel* model_ = nullptr;
  const System* sys_ = nullptr;
  EvalContext external_;
  bool has_external_ = false;
  friend ClosureSolveInfo constrainedForwardDynamics(const TreeModel&, const System&, LoopClosures&,
                                                     const Eigen::VectorXd&, const Eigen::VectorXd&,
                                                     const Eigen::VectorXd&, TreeWorkspace&, Eigen::VectorXd&,
                                                     const Inputs*, bool, const ClosureSolveMode&);
  friend ClosureProjectionReport projectClosurePositions(const TreeModel&, const System&, LoopClosures&,
                                                         Eigen::VectorXd&, TreeWorkspace&, double, int,
                                                         const Eigen::VectorXd*, const ClosureSolveMode&);
  friend ClosureProjectionReport projectClosureVelocities(const TreeModel&, const System&, LoopClosures&,
                                                          const Eigen::VectorXd&, Eigen::VectorXd&, TreeWorkspace&,
                                                          double, int, bool, bool, const ClosureSolveMode&);
};

// Constrained forward dynamics: q_ddot and closures.lambda at (q, q_dot) with efforts tau
// and optional loads (as forwardDynamics; loads->effort of cut joints acts through
// addCutJointEfforts, the tree joints' efforts are read from tau only), at closures.context(),
// branch passages as `mode` says. Returns the solve's rank report.
ClosureSolveInfo constrainedForwardDynamics(const TreeModel& model, const System& sys, LoopClosures& closures,
                                            const Eigen::VectorXd& q, const Eigen::VectorXd& qdot,
                                            const Eigen::VectorXd& tau, TreeWorkspace& ws, Eigen::VectorXd& qddot,
                                            const Inputs* loads = nullptr, bool evaluated = false,
                                            const ClosureSolveMode& mode = {});

// q (+) dv: q moved by dv (velocity coordinates): q_k + dv_k, a spherical joint's
// quaternion exp(dv/2) (x) q, a free body's r + dv and p (x) exp(dv'/2) (positionRates'
// conventions), so a step along G's columns moves Phi by G dv to first order.
void retract(const TreeModel& model, Eigen::VectorXd& q, const Eigen::VectorXd& dv);

// Newton on Phi(q) = 0 with the M-weighted least-norm step dq = -M^-1 G^T (G M^-1 G^T)^+ Phi,
// until closures.positionResidual() <= tol (at most max_iterations steps). ws ends at q's
// kinematics with zero velocity, or with `rates` when given (the equations' Phi and G do
// not read them; gamma does: report.at_rates says ws and the evaluation are at (q, rates)).
// Both projections allocate nothing (the closures' scratch), and take branch passages as
// `mode` says.
ClosureProjectionReport projectClosurePositions(const TreeModel& model, const System& sys, LoopClosures& closures,
                                                Eigen::VectorXd& q, TreeWorkspace& ws, double tol = 1e-13,
                                                int max_iterations = 20, const Eigen::VectorXd* rates = nullptr,
                                                const ClosureSolveMode& mode = {});
// q_dot -= M^-1 G^T (G M^-1 G^T)^+ (G q_dot - nu) (the M-nearest q_dot with G q_dot = nu), repeated
// while the relative residual exceeds tol (at most max_iterations). evaluated_at_q: ws and
// closures already hold q's kinematics and evaluation, as projectClosurePositions leaves
// them; at_rates: that kinematics has these q_dot (projectClosurePositions with rates =
// &qdot and report.at_rates). The articulated factors and the closures' factorization are
// taken only when a correction is needed (a q_dot on the closures leaves both as they
// were). ws ends at (q, q_dot)'s kinematics; report.at_rates: the evaluation too (no
// correction moved q_dot).
ClosureProjectionReport projectClosureVelocities(const TreeModel& model, const System& sys, LoopClosures& closures,
                                                 const Eigen::VectorXd& q, Eigen::VectorXd& qdot, TreeWorkspace& ws,
                                                 double tol = 1e-13, int max_iterations = 3,
                                                 bool evaluated_at_q = false, bool at_rates = false,
                                                 const ClosureSolveMode& mode = {});

}  // namespace mechanism_sim
