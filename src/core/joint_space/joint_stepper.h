// The joint-space formulation's stepper: the spanning tree moves in joint
// coordinates (joint_space/tree.h: q, q_dot per joint, unit quaternions for spherical joints and
// free bodies), integrated by the same Butcher tableaus as the absolute formulation
// (tableau.h) with the articulated-body algorithm for q_ddot: O(n) a stage, and a revolute
// joint's angle is a coordinate, not a rotation to be followed (a wheel at 4000 rad/s, a
// pendulum far from the origin are exact to round-off).
//
// After every step the absolute State (x, u, acc, tracked angles) is written from the joint
// state, so every query, the node and the tools read it as they read the absolute
// formulation's. The joint state itself (State::q, qdot, qddot) is part of the State: a
// snapshot restores it bit for bit.
//
// What it runs (jointFormulationUnsupported says what it does not): trees of every
// joint type and free bodies, with gravity, applied efforts, body wrenches, springs (body
// loads at the tree's poses), and joint limits, drives and mimic couplers as equations on
// the tree (loop_closure.h: their absolute equations through G = Phi_x J(q)), and joint
// damping (efforts in the stages; stiff ones by implicit Euler after them, the absolute
// formulation's rule: classifyDamping; on spherical joints too, along the relative angular
// velocity in frame i as there), and Coulomb friction (the absolute formulation's rule,
// sized for each step: frictionFor), and loop closures (the cut joints' equations on the
// tree, their branch passages held by the motion: branch_passage.cpp; with friction or
// stiff damping, those two solves use the ordinary closure factorization).
#pragma once
#include <array>
#include <cmath>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "core/formulation.h"
#include "core/joint_space/tree.h"
#include "core/joint_space/loop_closure.h"
#include "core/absolute/solver.h"
#include "mechanism_sim/core/model/system.h"
#include "mechanism_sim/core/model/tableau.h"

namespace mechanism_sim {

// Empty when the joint formulation runs sys, else a sentence naming what it cannot run.
std::string jointFormulationUnsupported(const System& sys);

// 1 / m and J'^-1 of a body (its mass and central inertia): inv_m +inf without mass, has_J
// false where J' is not positive definite.
struct BodyInverse {
  double inv_m = HUGE_VAL;
  Matrix3d inv_J = Matrix3d::Zero();
  bool has_J = false;
};
BodyInverse bodyInverse(const Body& B);

// An upper bound on (M^-1)_kk, M the joint-space inertia of the tree, for a joint coordinate
// whose row over its joint's two bodies (Joint::coordinates) is `row`, in the configuration
// the row was taken in: row M_b^-1 row^T with the two bodies' own masses and central
// inertias (derivation at the definition). +inf (HUGE_VAL) where the row moves a body that
// has no mass or no inertia along it. For a revolute joint the row, and so the bound, is the
// same in every configuration. (JointStepper::classifyDamping.) The second form with the
// bodies' inverses (bi, bj: of J's bodies i and j) computed once.
double coordinateInverseMassBound(const System& sys, const Joint& J, const Row& row);
double coordinateInverseMassBound(const Joint& J, const Row& row, const BodyInverse& bi, const BodyInverse& bj);

class JointStepper final : public FormulationStepper {
 public:
  // Throws ModelError when the joint formulation cannot run sys (jointSpaceUnsupported).
  // embed_couplers: the couplers the tree can hold (TreeModel's embed_couplers) are held by
  // its recursions, not solved as closure rows (false: every coupler a row, as the tests'
  // cross-check runs it).
  explicit JointStepper(const System& sys, bool embed_couplers = true);
  void setMethod(Method m) override { tableau_ = &tableau(m); }

  // The joint state of s from its absolute state (an assembled or restored State: joint
  // coordinates from Joint::coordinates, quaternions from the relative rotations), then the
  // absolute state again from it (exactly on the tree) with accelerations.
  void settle(const System& sys, State& s, const Inputs& in) override;
  void adopt(const System& sys, State& s, const Inputs& in) override {
    if (s.q.size() == 0) settle(sys, s, in);
  }
  // Advances s by h; a State without joint state (an absolute formulation's snapshot) is
  // settled first. Throws UsageError for an h that is not positive and finite; s is then
  // as it was.
  void step(const System& sys, State& s, const Inputs& in, double h) override;
  const SolverStats& stats() const override { return stats_; }
  // The largest |Phi| and |G q_dot - nu| of the closures' rows (loop closures, couplers,
  // limits, drives: the equations on the tree's coordinates, the same numbers as their
  // absolute equations') at s, when s is the state this stepper's last step or settle()
  // left (else false): the tree joints' own equations hold by construction in joint
  // coordinates, so these are what a step can leave violated.
  bool stepViolation(const State& s, double& position, double& velocity) const override;
  // The inputs or the System changed: the accelerations a State holds are not reused.
  void invalidate() override { fresh_ = false; }
  // The System's joint damping changed (Mechanism::setJointDamping): which coordinates are
  // damped, and by how much, again (the constructor read them).
  void setDamping(const System& sys);
  const TreeModel& model() const { return model_; }

 private:
  // q_ddot at (q, q_dot) and time t under the inputs and springs, with the closures
  // (drives, limits, couplers) read in s's context. evaluated: ws_ holds the kinematics of
  // (q, q_dot) and closures_ their evaluation in that context (project() returned true).
  void accelerations(const System& sys, const State& s, const Inputs& in, double t, const Eigen::VectorXd& q,
                     const Eigen::VectorXd& qdot, Eigen::VectorXd& qddot, bool evaluated = false);
  // One step of h from s; on a StepFailure s is as it was (the last accepted step).
  void stepOnce(const System& sys, State& s, const Inputs& in, double h);
  // A step of h from s, depth halvings below the step asked: taken again as halves when it
  // fails or leapt (at most numerics::kMaxHalvings deep).
  void advance(const System& sys, State& s, const Inputs& in, double h, int depth);
  // s back to `before` and the step of h from it as two halves.
  void halve(const System& sys, State& s, const Inputs& in, double h, int depth, const State& before);
  // Whether the step of h that ended at s leapt over what it should follow (its error
  // estimate past numerics::kMaxStepError of the motion's velocity scale, scale0 the
  // start's).
  bool leapt(const System& sys, const State& s, double h, double scale0);
  // s back where stepOnce's last step started (what a step changes of the State; the rest
  // is computed again: fresh_ false).
  void restoreStart(State& s) const;
  void finish(const System& sys, State& s, const Inputs& in);
  // Returns whether ws_ and closures_ are left at (s.q, s.qdot) (no velocity correction).
  bool project(const System& sys, State& s);
  // Joint damping (the absolute formulation's rule, stiff_damping.cpp, in joint
  // coordinates): which damped coordinates are stiff at this step (ws_ at s.q's factors);
  // returns whether the set changed. The others stay in the stages as efforts. The set
  // found is held in s.damping_hold for the next steps where no coordinate was near the
  // bound (kHold* in joint_damping.cpp).
  bool classifyDamping(const System& sys, State& s, double h);
  // For classifyDamping, at ws_'s articulated factors (q0): the columns of M^-1 of the
  // candidates (damp_candidates_) at the damped coordinates, and with closures
  // (M^-1 G^T) and W = (M^-1 G^T) (G M^-1 G^T)^+ there (damp_Yd_, damp_W_).
  void dampedInverseMass();
  // The stiff ones after the stages: implicit Euler in the metric M + h C (Lie splitting).
  void implicitDamping(const System& sys, State& s, double h);
  // Sets s.friction to 0; returns whether any joint has Coulomb friction.
  bool clearFriction(const System& sys, State& s) const;
  // s.friction for the step h (Stepper::frictionFor's rule, coulombFriction) from s.qdot and
  // the accelerations without friction s.qddot, with ws_ and the closures at s.q's factors.
  void frictionFor(const System& sys, State& s, double h);
  // s.x, s.u, s.acc and the tracked angles from s.q, s.qdot, s.qddot.
  void writeAbsolute(const System& sys, State& s);

  TreeModel model_;
  TreeWorkspace ws_;
  State start_;                 // the step's start, once it is taken as halves (start_valid_)
  State::Clock clock0_;         // stepOnce's start (restoreStart)
  Eigen::VectorXd qddot_ref0_;
  bool judged_ = false, start_valid_ = false;  // the step is judged by its error; start_ holds it
  std::vector<State> backup_;   // a substep's start, by depth (advance)
  Eigen::VectorXd acc_k4_;      // the bodies' accelerations of RK4's k4 at the step's end (leapt)
  LoopClosures closures_;  // drives, limits and couplers: equations on the tree
  std::vector<signed char> limit_side0_;
  std::vector<std::array<double, 3>> friction0_;  // s.friction at the step's start
  Eigen::VectorXd fric_e_, fric_y_;               // e_k and P e_k (frictionFor)
  const Tableau* tableau_ = &kRk4;
  SolverStats stats_;
  Eigen::VectorXd tau_, q0_, v0_, qs_, vs_, kq_[Tableau::kMaxStages], kv_[Tableau::kMaxStages], sum_q_, sum_v_;
  Inputs loads_;  // the inputs plus the springs' body loads
  struct Damped {
    int j = 0, k = 0, iv = 0;  // joint, its coordinate, q_dot's index
    double c = 0.0;
    // A revolute joint's angle: its rows on the two bodies are the axis in each body's
    // frame, so classifyDamping's filter and bound do not change with the configuration:
    // kept in `bound` and `beta` once computed (-1: not yet).
    bool revolute = false;
    double bound = -1.0;
    double beta = -1.0;  // coordinateInverseMassBound
  };
  std::vector<Damped> damped_;  // every damped tree coordinate
  // per damped_ entry: the links of its path to the root (its own first) and their velocity
  // coordinates; per velocity coordinate its link and its damped_ entry (-1: none)
  std::vector<std::vector<int>> damp_path_, damp_path_v_;
  std::vector<int> link_of_v_, damp_index_of_v_;
  // per damped_ entry k, the entries l whose paths share coordinates with k's (their common
  // ancestors': the tail of l's path), from damp_shared_first_[k] on: l and where in
  // damp_path_v_[l] the shared ones begin
  struct Shared {
    int l = 0, from = 0;
  };
  std::vector<Shared> damp_shared_;
  std::vector<int> damp_shared_first_;
  Eigen::MatrixXd damp_Zd_, damp_Xd_;  // L^-T e_l and D^-1 L^-T e_l per damped_ entry l
  Eigen::MatrixXd damp_Minv_;          // (M^-1)_Dk, column a for damped_ entry damp_need_[a]
  Eigen::MatrixXd damp_Yd_, damp_W_;   // (M^-1 G^T)_D and W (damped x closure rows)
  std::vector<int> damp_W_lo_, damp_W_hi_;  // per used closure row: W's column is zero off [lo, hi)
  std::vector<int> damp_used_;         // closure rows whose column of damp_Yd_ is not zero
  std::vector<int> damp_candidates_;   // damped_ entries whose P column is needed
  std::vector<int> damp_need_;         // ... and those closure rows need
  std::vector<int> damp_column_of_;    // per damped_ entry: its column of damp_Minv_, or -1
  std::vector<char> damp_direct_;      // per closure row: on damped coordinates only
  std::vector<int> damp_nz_, damp_nz_first_;  // per closure row: its nonzero entries' coordinates
  std::vector<char> damp_touched_;     // per damped_ entry: its row of damp_Yd_ is not zero
  Eigen::VectorXd damp_col_, damp_rc_, damp_x_;  // P e_k; sqrt(c) per damped_ entry; scratch
  std::vector<double> damp_filter_, damp_rcb_;   // per damped_ entry, this step: the filter, sqrt(c beta)
  std::vector<BodyInverse> body_inverse_;        // per System body (the bound's)
  AlignedVector<Vector6d> damp_p_;     // the inward passes' forces
  std::vector<char> damp_mark_;        // per link: on a closure row's paths
  std::vector<int> damp_links_;        // those links, children before parents
  std::vector<int> cut_damped_;  // cut joints with damping (efforts: accelerations())
  std::vector<int> cut_constraints_;  // the cut joints' System constraints (their tracked angles)
  std::vector<char> stiff_;     // per damped_: integrated implicitly (classifyDamping)
  std::vector<int> stiff_list_;  // indices into damped_ of the stiff ones
  Eigen::MatrixXd damp_Y_;       // M^-1 e_iv per damped_ entry: of the stiff ones at the stages' end
  Eigen::MatrixXd damp_K_;       // C^-1 / h + E^T M^-1 E over the stiff ones, and its Cholesky factor
  Eigen::VectorXd damp_e_, damp_z_, damp_du_, damp_zero_, damp_qdd_, damp_tau_;
  AlignedVector<Vector6d> damp_v_, damp_f_;  // bodies' velocities and momenta (implicitDamping)
  Eigen::VectorXd damp_w_, damp_c_, damp_r_, damp_mu_;  // with closures (implicitDamping)
  Eigen::MatrixXd damp_Z_, damp_AW_;
  ScaledLeastNorm damp_least_norm_;  // of G W^-1 G^T
  std::vector<Row> damp_rows_;   // Joint::coordinates of a damped joint (the bound)
  // s.qddot is q_ddot at (q_end_, v_end_) under the current inputs: stage 1 of the next step
  bool fresh_ = false;
  Eigen::VectorXd q_end_, v_end_;
  std::array<double, 2> end_violation_{{0.0, 0.0}};  // stepViolation() at (q_end_, v_end_)
  Eigen::VectorXd end_rate_;                         // G q_dot there
  // State::q_round and qdot_round at the step's start (restored when the step fails)
  Eigen::VectorXd comp_q_, comp_v_;
  Eigen::VectorXd a_ref_;  // q_ddot at the step's start: what a branch passage holds
  std::vector<BodyKin> kin_;
  Eigen::VectorXd spring_x_, spring_u_;
};

}  // namespace mechanism_sim
