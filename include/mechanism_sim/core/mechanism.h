// A mechanism, as programs embed it: describe it (bodies, joints, forces), build and
// assemble it, then step it and ask where it is. The core's public facade: a thin owner of
// the System it builds once (model/system.h), the State it advances (a plain value:
// snapshot() copies it, restore() assigns it), the Inputs set between steps, and the
// stepper of the formulation that runs (src/core/absolute/ or src/core/joint_space/, whose
// headers are private to the library; doc/embedding.md draws the rooms).
#pragma once
#include <algorithm>
#include <array>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "mechanism_sim/core/model/actuator_limits.h"
#include "mechanism_sim/core/model/system.h"
#include "mechanism_sim/core/reports.h"

namespace mechanism_sim {

class FormulationStepper;  // src/core/formulation.h
class Stepper;       // absolute formulation (src/core/absolute/stepper.h)
class JointStepper;  // joint formulation (src/core/joint_space/joint_stepper.h)
struct Evaluation;   // src/core/absolute/evaluation.h

// A target for one joint coordinate during assembly.
struct CoordinateTarget {
  int joint = 0, k = 0;
  double value = 0.0;
};

struct AssemblyReport {
  double position_residual = 0.0, velocity_residual = 0.0;  // relative (scale-free)
  int iterations = 0;
};

// Force (global) and torque (global, about B_j) that a constraint applies to its body j
// (the last of its bodies; for a limit, drive or coupler, the joint point of the joint
// whose body j that is).
struct Reaction {
  Vector3d force = Vector3d::Zero(), torque = Vector3d::Zero();
};

class Mechanism {
 public:
  static constexpr int kGround = System::kGround;
  using Snapshot = State;
  Mechanism();
  ~Mechanism();
  Mechanism(const Mechanism&) = delete;
  Mechanism& operator=(const Mechanism&) = delete;

  // ---- model building (before build())
  int addBody(const Body& body);
  int addJoint(std::unique_ptr<Joint> joint);
  // URDF <mimic>: q_a(k_a) = multiplier * q_b(k_b) + offset, an exact constraint.
  int addCoupler(const std::string& name, int joint_a, int k_a, int joint_b, int k_b,
                 double multiplier, double offset);
  // A coupling sum_i c_i q_i = c_0 among 2 to kMaxCouplingTerms joint coordinates (gears,
  // racks, differentials, planetary trains; coupling.h): an exact constraint whose multiplier
  // (couplingReaction) stands for the effort -c_i lambda along each q_i.
  struct CouplingCoordinate {
    int joint = 0, k = 0;
    double c = 0.0;
  };
  int addCoupling(const std::string& name, const std::vector<CouplingCoordinate>& terms, double c0);
  // The same coupling with a backlash b > 0: a clearance |sum_i c_i q_i - c_0| <= b/2 instead
  // of the equation, two stops on the sum that act as a joint's limits do (inelastic
  // impacts, released when they would pull; LimitSpec::terms). Returns its limit, whose
  // multiplier (limitReaction; 0 in the gap) stands for the effort -c_i lambda along each q_i.
  int addBacklashCoupling(const std::string& name, const std::vector<CouplingCoordinate>& terms, double c0,
                          double backlash);
  int addSpring(const SpringDamper& spring);
  // The reflected inertia of a transmission's rotors on one or two joint coordinates
  // (transmission.h): the kinetic energy 1/2 q_dot^T B q_dot, in both formulations (a
  // coupled B runs in absolute coordinates). Before build(); build() validates it.
  void addRotorInertia(const RotorInertia& rotor);
  // Coulomb friction of bound f on a sum of joint coordinates (System::sum_friction; a
  // differential motor's shaft). Before build(); build() validates it.
  void addSumFriction(const SumFriction& friction);
  // Position limits of a coordinate: unilateral, activated on contact with no rebound,
  // released when the joint pulls away.
  void setJointLimits(int joint, int k, double lower, double upper);
  // Prescribed motion of coordinate k (drive.h): q_k = f(t), an exact rheonomic
  // constraint whose multiplier is the driving effort. q0: a velocity drive's position at
  // t = 0 (f = q0 + v t). Returns the drive's index.
  // After build() (mechanism_drives.cpp): only a velocity drive, which takes the
  // coordinate's current position and velocity as its reference (q0 is ignored); the
  // System is rebuilt with one more equation, the State kept, the dependent equations
  // found again. Throws ModelError, the mechanism unchanged, when the new equation depends
  // on the others (the coordinate's motion follows from the joints, couplers and drives).
  int addDrive(int joint, int k, const DriveProfile& profile, double q0 = 0.0);
  // After build(): the drive is gone (the coordinate is free; the drives after it move
  // down by one), the State kept.
  void removeDrive(int drive);
  // These may also change after build() (the System is rebuilt, the State kept).
  void setGravity(const Vector3d& g);
  void setJointDamping(int joint, int k, double c);
  // Coulomb friction f >= 0 along coordinate k: opposes the motion with at most f, and at
  // most the effort that stops the joint within the step being taken.
  void setJointFriction(int joint, int k, double f);
  void setIntegrator(const IntegratorOptions& options);
  // Validates the model and lays out the sparse structures. Throws ModelError.
  void build();
  AssemblyReport assemble(const std::vector<CoordinateTarget>& positions = {},
                          const std::vector<CoordinateTarget>& velocities = {});

  // ---- running
  void step(double h);
  double time() const { return state_.t; }
  void setJointEffort(int joint, int k, double tau);
  void setBodyWrench(int body, const Vector3d& force, const Vector3d& torque_body);
  void setSpringActuation(int spring, double f_act);
  // A velocity drive moves to velocity v from now, at acceleration at most acc (> 0; inf:
  // at once), position and velocity continuous. Throws for a profile drive.
  void commandDriveVelocity(int drive, double v, double acc);
  // A velocity drive follows the path from now (drive.h; it should start at the drive's
  // current target, driveTarget(), for no jump). Throws for a profile drive.
  void commandDrivePath(int drive, std::shared_ptr<const DrivePath> path);
  int numDrives() const { return static_cast<int>(sys_->drives.size()); }
  // The drive of a joint coordinate, or -1.
  int driveOf(int joint, int k) const;
  // What the drive prescribes now: position, velocity, acceleration.
  void driveTarget(int drive, double* q, double* q_dot, double* q_ddot) const;
  Snapshot snapshot() const {
    completeState();
    return state_;
  }
  void restore(const Snapshot& s);

  // ---- the saturating mode (doc/actuators.md; mechanism_saturation.cpp)
  // From now on (the current state included) each actuator bounds the drive of its
  // coordinate, when that has one: at every accepted state, where the drive would need more
  // torque than torqueBounds allows at the actuator's speed, its reference falls behind its
  // profile (DriveLag) so that the actuator gives exactly its bound; a drive behind its
  // profile comes back onto it as fast as the bound and the step allow, and follows it
  // exactly again once there. Empty: the sizing mode (every drive follows its profile; one
  // behind it when its bound is lifted keeps its lag as it stands and moves with its
  // profile from there). Throws UsageError naming the actuator for a coordinate out of
  // range, a reduction zero or not finite, ratings not valid.
  void setActuatorLimits(std::vector<ActuatorLimit> limits);
  const std::vector<ActuatorLimit>& actuatorLimits() const { return actuator_limits_; }
  // How far a drive's reference is behind its profile now (profile minus reference, in the
  // coordinate's units; 0 when it follows it), and whether an actuator holds it at its bound.
  double driveLag(int drive) const;
  bool driveSaturated(int drive) const { return state_.drive.at(drive).lag.saturated; }
  // The torque actuator limit i gives now (ActuatorLimit).
  double limitedActuatorTorque(int i) const;

  // ---- the parts
  const System& system() const { return *sys_; }
  const State& state() const {
    completeState();
    return state_;
  }
  // The stepper's, plus the reaction queries' least-norm solves (jointReactions, absolute
  // formulation with dependent equations).
  SolverStats solverStats() const;

  // ---- model queries
  int numBodies() const { return sys_->numBodies(); }
  const Body& body(int b) const { return sys_->bodies.at(b); }
  int numJoints() const { return sys_->numJoints(); }
  const Joint& joint(int j) const { return *sys_->joints.at(j); }
  int jointConstraintIndex(int j) const { return sys_->joint_constraint.at(j); }
  int numConstraints() const { return sys_->numConstraints(); }
  const Constraint& constraint(int c) const { return *sys_->constraints.at(c); }
  int numEquations() const { return sys_->m_eq; }
  const DependencyReport& dependencies() const { return dependencies_; }
  const Vector3d& gravity() const { return sys_->gravity; }
  const IntegratorOptions& integrator() const { return sys_->options; }
  // The formulation that runs (after build(): "joint" or "absolute") and why, one phrase.
  const char* formulation() const { return formulationName(formulation_); }
  const std::string& formulationReason() const { return formulation_why_; }

  // ---- state queries (of the current, accepted state: computed from the State, on the
  // stepper's evaluation where that describes it, else on the queries' own)
  Vector3d position(int b) const;
  Matrix3d rotation(int b) const;
  Quaterniond orientation(int b) const;
  // Joint coordinate k: position, rate, and the effort the joint applies along it
  // (commanded effort minus damping plus friction, plus a limit's reaction and a drive's
  // effort). Joint::coordinates at the state's poses; in the joint formulation a tree
  // joint's (but a spherical one's) are the State's own q, q_dot, q_ddot (treeCoordinate),
  // which those poses were written from (the same numbers to round-off). A mimic joint
  // held by the joint formulation's tree whose limit its master's implies has no limit
  // reaction of its own: the master's limit carries the stop (doc/limitations.md).
  double jointPosition(int joint, int k) const;
  double jointVelocity(int joint, int k) const;
  double jointEffort(int joint, int k) const;
  // Its acceleration in the current state: q_x,k a - gamma_k (joint.h).
  double jointAcceleration(int joint, int k) const;
  // Where a tree joint's coordinates start in State::q (rate: in q_dot and q_ddot) in the
  // joint formulation; -1 for a loop's cut joint, a spherical joint, or in the absolute
  // formulation.
  int treeCoordinate(int joint, bool rate) const;
  Reaction reaction(int constraint) const;
  // A coupling's multiplier lambda (addCoupling): each coupled coordinate i carries the
  // effort -c_i lambda (the mesh's load, in the units of the coordinates' efforts per unit
  // coefficient). Least-norm where equations are dependent, as jointReactions.
  double couplingReaction(int constraint) const;
  // A limit's multiplier lambda (System::limits, e.g. addBacklashCoupling's): 0 while it is
  // free; while it presses, each of its coordinates i carries the effort -c_i lambda.
  double limitReaction(int limit) const;
  // Per joint: the force and torque (global, torque about the joint point B_j) that the
  // joint exerts on its body j: its constraint, its limits, its drives, its share of the
  // couplers (along its own coordinate) and the efforts applied along its coordinates
  // (command, damping, friction). Where equations are dependent the multipliers are the
  // least-norm ones (Stepper::minimumNormMultipliers): the same state gives the same
  // reactions whatever the history. In the joint formulation the tree joints' multipliers
  // come from the recursive Newton-Euler pass over the state's accelerations
  // (tree_reactions.h), the closures' from its stepper's solve.
  std::vector<Reaction> jointReactions() const;
  double positionViolation() const;  // max |Phi|
  double velocityViolation() const;  // max |Phi_q v|
  // The same over the equations a step can leave violated, cheap after a step (what run
  // loops check at every step): every equation in absolute coordinates (the step's own
  // evaluation); in joint coordinates the closures' rows (loop closures, couplers, limits,
  // drives), whose values the step computed, while the tree joints' equations hold by
  // construction there (to round-off; positionViolation() evaluates them too).
  double stepPositionViolation() const;
  double stepVelocityViolation() const;
  // The same relative to the size of each equation's terms (scale-free; what the
  // projections' tolerances bound).
  double relativePositionViolation() const;
  double relativeVelocityViolation() const;
  double kineticEnergy() const;
  double potentialEnergy() const;
  long stepsTaken() const { return state_.steps; }

 private:
  System& editable();  // the System being described, or a copy of the built one
  void requireUnbuilt(const char* what) const;
  void checkCoordinate(int joint, int k) const;
  // Rebuilds the System with these drives (drive d was old drive from[d], or new when -1)
  // and references, keeping the State; the dependent equations found again. Returns the
  // rows of the new drives that depend on the others (nothing changed then).
  int addDriveAfterBuild(int joint, int k, const DriveProfile& profile);
  std::vector<int> replaceDrives(std::vector<DriveSpec> drives, const std::vector<int>& from,
                                 std::vector<DriveRamp> references);
  // The evaluation at state_ (evaluation.h): the stepper's when its stamp describes
  // state_, else the queries' own, evaluated on demand without rates (its gamma is 0: no
  // query reads it; evaluateConstraints). Found once per state: until
  // stateChanged(), the one found (a stamp's comparison reads all of x and u, and a sample
  // of the run loop asks some 300 queries of one state).
  const Evaluation& evaluated() const;
  // Every method that may change state_, the System or the steppers' evaluations calls it
  // (step() only forgets: what it leaves pending is written when something reads it).
  void stateChanged() {
    completeState();
    forgetQueries();
  }
  // What the queries found of state_, forgotten.
  void forgetQueries() {
    described_ = nullptr;
    saturation_current_ = false;
    std::fill(rows_found_.begin(), rows_found_.end(), 0);
  }
  // What the running formulation's last step left pending in state_ (State::bodies_pending),
  // written from state_'s own state: before anything reads state_ whole or changes it.
  // (Logically const: state_ is the same state, only completed.)
  void completeState() const;
  // The multipliers of state_ and the evaluation whose Jacobian they go with: the State's
  // own (absolute formulation, independent equations), the least-norm ones from its
  // accelerations (absolute formulation, dependent equations), or in the joint formulation,
  // whose tree joints have no multipliers in the State, the closures' own and the tree
  // joints' from the recursive Newton-Euler pass (treeJointMultipliers).
  Eigen::VectorXd multipliers(const Evaluation** with) const;
  // Chooses the formulation from the System's options (chooseFormulation), with `settle`
  // bringing the State to it.
  void useFormulation(bool settle);
  const BodyKin& kin(int b) const;
  // Joint::coordinates of a joint at state_ (its rows, one per dof), computed once per state
  // like evaluated(): a sample asks each dof's position, velocity and effort.
  const Row* coordinateRows(int joint) const;

  // The saturating mode at state_: each drive an actuator bounds held within its bound, its
  // lag's way back chosen for steps of h (saturation_current_ until the state or the inputs
  // change).
  void saturate(double h);
  std::vector<ActuatorLimit> actuator_limits_;
  bool saturation_current_ = false;

  std::shared_ptr<System> sys_;
  bool built_ = false;
  State state_;
  Inputs inputs_;
  std::unique_ptr<Stepper> stepper_;     // absolute formulation (and assembly)
  std::unique_ptr<JointStepper> joint_;  // joint formulation, when it runs
  FormulationStepper* running_ = nullptr;  // the one of the two that steps
  Formulation formulation_ = Formulation::kAbsolute;
  std::string formulation_why_;
  mutable std::unique_ptr<Evaluation> query_eval_;  // the queries' own evaluation
  mutable const Evaluation* described_ = nullptr;    // evaluated()'s, until stateChanged()
  mutable std::vector<std::array<Row, kMaxJointDofs>> rows_;  // coordinateRows()' per joint,
  mutable std::vector<char> rows_found_;                      // where found, until stateChanged()
  // The reactions' solves, with their own evaluations and scratch (queries leave stepping
  // alone): the least-norm one (absolute formulation, dependent equations), the tree pass
  // (joint formulation).
  struct ReactionSolve;  // mechanism.cpp
  mutable std::unique_ptr<ReactionSolve> reactions_;
  DependencyReport dependencies_;
};

}  // namespace mechanism_sim
