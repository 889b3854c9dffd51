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
// formulation's rule: JointDamping, joint_damping.h; on spherical joints too, along the relative angular
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
#include "core/joint_space/joint_damping.h"
#include "core/joint_space/loop_closure.h"
#include "core/absolute/solver.h"
#include "mechanism_sim/core/model/system.h"
#include "mechanism_sim/core/model/tableau.h"

namespace mechanism_sim {

// Empty when the joint formulation runs sys, else a sentence naming what it cannot run.
std::string jointFormulationUnsupported(const System& sys);

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
  void resolve(const System& sys, State& s, const Inputs& in) override;
  const SolverStats& stats() const override { return stats_; }
  // The largest |Phi| and |G q_dot - nu| of the closures' rows (loop closures, couplers,
  // limits, drives: the equations on the tree's coordinates, the same numbers as their
  // absolute equations') at s, when s is the state this stepper's last step or settle()
  // left (else false): the tree joints' own equations hold by construction in joint
  // coordinates, so these are what a step can leave violated.
  bool stepViolation(const State& s, double& position, double& velocity) const override;
  // The inputs or the System changed: the accelerations a State holds are not reused.
  void invalidate() override { end_.fresh = false; }
  // s.x, s.u and s.acc from s.q, s.qdot, s.qddot: a step leaves them pending
  // (State::bodies_pending), the bodies' state being read only by queries, by the step's
  // error estimate and by the damping classification; settle() and resolve() write them.
  void completeState(State& s) override;
  // The System's joint damping changed (Mechanism::setJointDamping): which coordinates are
  // damped, and by how much, again (the constructor read them).
  void setDamping(const System& sys);
  void dampingChanged(const System& sys) override { setDamping(sys); }
  // A tree joint's coordinates are q's own (the poses are written from them, and
  // Joint::coordinates at those poses gives the same numbers to round-off); not a
  // spherical or free joint's (a quaternion in q, a rotation vector as coordinates).
  int stateCoordinate(const State& s, int joint, bool rate) const override;
  // The closures' multipliers (couplers, drives, limits) as the step solved them, the tree
  // joints' from the recursive Newton-Euler pass over s's accelerations (tree_reactions.h).
  bool reactionMultipliers(const System& sys, const State& s, const Inputs& in,
                           std::unique_ptr<TreeReactionWorkspace>& scratch, Eigen::VectorXd& lambda,
                           const Evaluation** with) const override;
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
  bool leapt(const System& sys, State& s, double h, double scale0);
  // s back where stepOnce's last step started (what a step changes of the State; the rest
  // is computed again: end_.fresh false).
  void restoreStart(State& s) const;
  void finish(const System& sys, State& s, const Inputs& in);
  // Returns whether ws_ and closures_ are left at (s.q, s.qdot) (no velocity correction).
  bool project(const System& sys, State& s);
  // Sets s.friction to 0; returns whether any joint has Coulomb friction.
  bool clearFriction(const System& sys, State& s) const;
  // s.friction for the step h (Stepper::frictionFor's rule, coulombFriction) from s.qdot and
  // the accelerations without friction s.qddot, with ws_ and the closures at s.q's factors.
  void frictionFor(const System& sys, State& s, double h);
  // y = P y, P the constrained inverse mass M^-1 - M^-1 G^T (G M^-1 G^T)^+ G M^-1 at ws_ and
  // the closures' factors (frictionFor's g P g^T); mass: M is factored already (set here).
  void constrainedInverseMass(Eigen::VectorXd& y, bool& mass);
  // The inputs' joint efforts for the accelerations from here on (tau_in_), and whether
  // they add s.friction (false only where no joint has Coulomb friction: it is zero).
  void setInputs(const Inputs& in, bool friction);
  // The tracked angles from s.q (s.x, s.u, s.acc left pending), the closures' multipliers
  // and violations.
  void writeAbsolute(const System& sys, State& s);

  TreeModel model_;
  TreeWorkspace ws_;
  LoopClosures closures_;  // drives, limits and couplers: equations on the tree
  ClosureSolveMode closure_mode_;  // how the closures' solves take branch passages (loop_closure.h)
  JointDamping damping_;  // (after model_, ws_ and closures_, which it reads)
  const Tableau* tableau_ = &kRk4;
  SolverStats stats_;
  Eigen::VectorXd tau_in_;     // the inputs' joint efforts (setInputs)
  bool friction_acts_ = true;  // accelerations() adds s.friction (setInputs)
  bool judged_ = false;        // the step is judged by its error estimate (advance)
  // What a step changes of the State, as it was at the step's start: restoreStart puts it
  // back when the step fails; the whole State once the step is taken as halves.
  struct StepStart {
    State whole;  // (valid: the step is taken as halves)
    bool valid = false;
    State::Clock clock;
    Eigen::VectorXd qddot_ref;
    std::vector<signed char> limit_side;
    std::vector<std::array<double, 3>> friction;
    std::vector<double> sum_friction;
    Eigen::VectorXd q_round, qdot_round;  // the update's round-off carried in (compensated sums)
    std::vector<State> backup;            // a substep's start, by depth (advance)
  } start_;
  // The stages' vectors (stepOnce): the efforts, the start, a stage's position, each
  // stage's velocity, the stages' derivatives (kq only where q has quaternions: else the
  // velocities are the position rates); the bodies' accelerations of RK4's k4 at the step's
  // end (leapt).
  struct Stages {
    Eigen::VectorXd tau, q0, v0, qs, vs[Tableau::kMaxStages], kq[Tableau::kMaxStages], kv[Tableau::kMaxStages], acc_k4;
  } stages_;
  // Coulomb friction's vectors (frictionFor): e_k, P e_k, G P e_k and its closure solve.
  struct FrictionWork {
    Eigen::VectorXd e, y, r, mu;
  } friction_;
  // The state the last step or settle() left: s.qddot is q_ddot at (q, v) under the current
  // inputs (fresh: stage 1 of the next step); ws_ held its kinematics at ws_.generation
  // `generation`; the closures' violations there (stepViolation()) and G q_dot.
  struct End {
    bool fresh = false;
    Eigen::VectorXd q, v;
    long generation = -1;
    std::array<double, 2> violation{{0.0, 0.0}};
    Eigen::VectorXd rate;
  } end_;
  TreeWorkspace query_ws_;  // completeState's kinematics where ws_ no longer holds s's
  Inputs loads_;            // the inputs plus the springs' body loads
  std::vector<int> cut_constraints_;  // the cut joints' System constraints (their tracked angles)
  // The tree coordinates that are tracked angles of their joints (Joint::trackedSlot): where
  // writeAbsolute puts each in State::tracked.
  struct TrackedCoordinate {
    int constraint = 0, slot = 0, iq = 0;
  };
  std::vector<TrackedCoordinate> tracked_coordinates_;
  std::vector<int> limit_rows_;  // per System limit: its row (its multiplier in State::lambda)
  Eigen::VectorXd a_ref_;  // q_ddot at the step's start: what a branch passage holds
  std::vector<BodyKin> kin_;
  Eigen::VectorXd spring_x_, spring_u_;
};

}  // namespace mechanism_sim
