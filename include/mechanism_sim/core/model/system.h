// What a mechanism is (System), where it is now (State), what acts on it from outside
// (Inputs). After Drake's System/Context and Pinocchio's Model/Data: a System is built and
// validated once and never changes; a State is a plain value (a copy is a snapshot, a
// reset is an assignment); the Stepper (stepper.h) maps (System, State, Inputs, h) to the
// next State with its own scratch space.
#pragma once
#include <array>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "mechanism_sim/core/model/drive.h"
#include "mechanism_sim/core/model/errors.h"
#include "mechanism_sim/core/model/joint.h"
#include "mechanism_sim/core/model/transmission.h"

namespace mechanism_sim {


struct Body {
  std::string name;
  double m = 0.0;                    // mass
  Matrix3d Jp = Matrix3d::Zero();    // inertia about the centre of mass, body components
  Vector3d r = Vector3d::Zero();     // centre of mass (the body's reference point)
  Quaterniond p = Quaterniond::Identity();
  Vector3d v = Vector3d::Zero();
  Vector3d w = Vector3d::Zero();     // omega', body components
};

// Linear spring-damper-actuator between point sp_i on body_i and sp_j on body_j:
// tension F = k (L - L0) + c L_dot + f_act pulls the points together when positive.
struct SpringDamper {
  std::string name;
  int body_i = 0, body_j = 0;
  Vector3d sp_i = Vector3d::Zero(), sp_j = Vector3d::Zero();
  double k = 0.0, c = 0.0, L0 = 0.0, f_act = 0.0;
  // The spring law, one for both formulations: the force on body_i at sp_i, e F with e the
  // unit vector from i's point to j's and F = k (L - L0) + c L_dot + f_act + actuation
  // (body_j gets -e F at sp_j); zero where the points coincide (L at most 1e-12 of
  // length_scale: no direction).
  Vector3d forceOnI(const BodyKin& ki, const BodyKin& kj, double actuation, double length_scale) const;
};

// Which formulation runs a mechanism (joint_stepper.h): the tree in joint coordinates
// ("joint"), every body in absolute coordinates ("absolute", the seed lecture's method and
// the reference), or per mechanism ("auto").
enum class Formulation { kAuto, kJoint, kAbsolute };
Formulation parseFormulation(const std::string& name);  // ModelError for an unknown name
const char* formulationName(Formulation f);

struct IntegratorOptions {
  // "rk4" (classical Runge-Kutta, default), "rk3" (Kutta's third order: three solves a
  // step, stable for undamped oscillation) or "rk2" (Heun).
  std::string method = "rk4";
  // Relative tolerances: of each equation against the size of its own terms (positions,
  // velocities, the equations of motion). Scale-free: metres or millimetres alike.
  double position_tol = 1e-13;
  double velocity_tol = 1e-14;
  double solve_tol = 1e-13;
  // "absolute" (default), "joint" or "auto" (Formulation; joint_stepper.h says what the
  // joint formulation runs).
  std::string formulation = "absolute";
  // Throws ModelError naming what is wrong (an unknown method, a tolerance not positive).
  void validate() const;
};

// One term c q_k of a limited sum (LimitSpec::terms): coordinate k of joint `joint`.
struct LimitTerm {
  int joint = 0, k = 0;
  double c = 1.0;
};

// Position limit lower <= s <= upper on a linear combination s = sum_i c_i q_i of joint
// coordinates: a joint coordinate's limit (one term (joint, k, 1)) or a coupling's backlash
// (the coupling's terms, bounds c_0 -+ b/2: a clearance on its sum). `constraint` is its
// LimitConstraint.
struct LimitSpec {
  int joint = 0, k = 0;  // the (first) limited coordinate
  double lower = 0.0, upper = 0.0;
  int constraint = 0;
  std::vector<LimitTerm> terms;  // empty: {(joint, k, 1)} (finalize() writes it)
  std::string name;              // a combination's own name (its coupling's); empty: the joint's
  // Whether the limit is on one coordinate alone, q_k itself.
  bool single() const { return terms.empty() || (terms.size() == 1 && terms[0].c == 1.0); }
};

// Coulomb friction of bound f on s = sum_i c_i q_i, a linear combination of joint
// coordinates (a motor's shaft behind a differential, theta = E q: doc/actuators.md): the
// joints' per-coordinate rule (coulombFriction) on the row sum_i c_i q_x,i, its effort F
// acting as c_i F along each q_i.
struct SumFriction {
  std::string name;
  std::vector<LimitTerm> terms;
  double f = 0.0;
};

// Prescribed motion of joint coordinate k; `constraint` is its DriveConstraint.
struct DriveSpec {
  int joint = 0, k = 0;
  DriveProfile profile;
  double q0 = 0.0;  // a velocity drive's position at t = 0
  int constraint = 0;
};

// Where a constraint's equations and Jacobian columns sit.
struct ConstraintLayout {
  int row = 0, size = 0;
  std::vector<int> bodies;    // moving-body index (body - 1) per slot, -1 for ground
};

class System {
 public:
  static constexpr int kGround = 0;

  // ---- description (validated in finalize())
  std::vector<Body> bodies;  // bodies[0] is ground; r, p, v, w give the initial state
  std::vector<std::shared_ptr<Constraint>> constraints;  // joints, couplers, then limits
  std::vector<const Joint*> joints;
  std::vector<int> joint_constraint;
  std::vector<SpringDamper> springs;
  std::vector<LimitSpec> limits;
  std::vector<DriveSpec> drives;
  std::vector<std::array<double, 3>> damping, friction;  // per joint coordinate
  std::vector<RotorInertia> rotors;  // reflected rotor inertias (transmission.h)
  std::vector<SumFriction> sum_friction;  // Coulomb friction on sums of coordinates
  Vector3d gravity = Vector3d(0, 0, -9.81);
  IntegratorOptions options;

  // ---- derived once by finalize()
  int nb = 0;          // moving bodies
  int n = 0;           // 6 nb velocity coordinates
  int m = 0;           // rows (limits included)
  int m_eq = 0;        // rows of the equality constraints (without limits)
  std::vector<ConstraintLayout> layout;
  std::vector<int> rheonomic;                    // constraints with a velocity term (drives)
  std::vector<int> all_constraints;              // 0, 1, ..., numConstraints() - 1
  // Per moving body: inverse masses with stand-ins (for the row weights: a massless body
  // weighs the mean mass, a body without moments the mean moment, every moment raised by
  // 1e-3 of the body's mean moment; see finalize).
  std::vector<Eigen::Matrix<double, 6, 6>> Minv;
  // Scales: a length (largest lever arm / joint offset / body distance), a mass and a
  // rotational inertia (means over bodies that have them); the stand-ins for what massless
  // bodies lack in the row weights.
  double length_scale = 1.0, mass_scale = 1.0, inertia_scale = 1.0;
  // What the loads alone would do: an acceleration (|g|, springs' k L + |f_act| over the
  // mass scale) and the velocity sqrt(a L) it gives over the length scale. Residual floors
  // use them, so a mechanism at rest is not judged on round-off divided by round-off.
  double acceleration_scale = 0.0, velocity_scale = 0.0;
  // The relative residual that the description's own round-off leaves in its dependent
  // equations (0 unless assembly accepted ones that disagree at the file's precision:
  // Mechanism::assemble sets it). No projection can hold them closer; the steps are held to
  // it (failureResidual, absolute/projection.h).
  double description_residual = 0.0;

  // Validates and lays out; throws ModelError naming what is wrong.
  void finalize();
  void updateLoadScales();  // acceleration_scale, velocity_scale (after gravity changes)
  int numBodies() const { return static_cast<int>(bodies.size()); }
  int numJoints() const { return static_cast<int>(joints.size()); }
  int numConstraints() const { return static_cast<int>(constraints.size()); }
};

// Plain value: everything that changes while a mechanism moves.
struct State {
  double t = 0.0;
  long steps = 0;
  // The time is the start of the current run of equal steps plus their count times the
  // step, t = t_run + n_run h_run, never a running sum: after any number of steps it is
  // exact to one rounding. A step of another size starts a new run where the time stands.
  double t_run = 0.0, h_run = 0.0;
  long n_run = 0;
  // The time after one more step of h (the State's t is not changed).
  double timeAfterStep(double h) const {
    return h == h_run ? t_run + static_cast<double>(n_run + 1) * h : t + h;
  }
  struct Clock {
    double t, t_run, h_run;
    long steps, n_run;
  };
  Clock clock() const { return {t, t_run, h_run, steps, n_run}; }
  void setClock(const Clock& c) { t = c.t, t_run = c.t_run, h_run = c.h_run, steps = c.steps, n_run = c.n_run; }
  // Counts one step of h taken: t becomes timeAfterStep(h), steps one more.
  void countStep(double h) {
    if (h != h_run) t_run = t, h_run = h, n_run = 0;
    ++n_run, ++steps;
    t = t_run + static_cast<double>(n_run) * h;
  }
  Eigen::VectorXd x;  // per moving body: r (3), p (4: w x y z)
  Eigen::VectorXd u;  // per moving body: v (3), w' (3)
  std::vector<Tracked> tracked;            // per constraint
  std::vector<signed char> limit_side;     // per limit: -1 lower, +1 upper, 0 free
  std::vector<char> dropped;               // per row: a dependent equation, left out of solves
  Eigen::VectorXd lambda;                  // multipliers at this state (and warm start)
  Eigen::VectorXd acc;                     // accelerations at this state
  // x, u and acc are not yet written: the joint formulation derives them from q, qdot,
  // qddot when they are read (FormulationStepper::completeState), not at every step.
  // Mechanism completes its State before any reader (Mechanism::state(), snapshot(), the
  // queries); a complete State has it false.
  bool bodies_pending = false;
  std::vector<std::array<double, 3>> friction;  // friction effort of the step that led here
  std::vector<double> sum_friction;             // per System::sum_friction: its effort F, the same
  std::vector<DriveRamp> drive;            // per drive: a velocity drive's reference
  // The joint formulation's state (joint_stepper.h; empty in the absolute formulation):
  // joint positions, rates and accelerations (x, u, acc above are written from them).
  Eigen::VectorXd q, qdot, qddot;
  // what a branch passage of a loop held when qddot was computed (branch_passage.cpp: the
  // accelerations at the start of the step that led here), so a restored State computes
  // qddot again to the same bits
  Eigen::VectorXd qddot_ref;
  // the round-off of q and qdot's last update, carried into the next step (joint_stepper.cpp:
  // compensated summation); zero after settle
  Eigen::VectorXd q_round, qdot_round;
  // The joint formulation's damping classification, held over the next steps while the
  // mechanism has not moved far from where it was found (joint_damping.cpp, classifyDamping:
  // the stiff set and the decay rates h s_k found, per damped coordinate; the positions x,
  // step h, tableau bound and limit sides it was found at; how many more steps it may serve,
  // 0: none). A snapshot carries it, so a restored State classifies as the run it came from;
  // settle() and a changed System clear it.
  struct DampingHold {
    std::vector<char> stiff;
    std::vector<double> rate;
    Eigen::VectorXd x;
    std::vector<signed char> limit_side;
    double h = 0.0, bound = 0.0;
    int left = 0;
  };
  DampingHold damping_hold;
  EvalContext context() const { return EvalContext{tracked.data(), limit_side.data(), t, drive.data()}; }
};

// What acts from outside; set between steps.
struct Inputs {
  std::vector<std::array<double, 3>> effort;  // per joint coordinate
  std::vector<Vector3d> force, torque;        // per body: global force at the centre of mass,
                                              // torque in body components
  std::vector<double> spring_actuation;       // per spring, added to its tension
};

State initialState(const System& sys);
Inputs zeroInputs(const System& sys);

// A limit reached (its coordinate at q, past a bound, at time t) on a coordinate a drive
// moves: true when q is within round-off of the bound (1e-9 of the limits' and the model's
// scale, as assembly judges an initial position): the drive holds it, the limit is not
// activated; throws SimulationError naming the joint when it is past by more (the drive's
// motion is prescribed; no stop can hold it); false for a coordinate no drive moves (a sum:
// unless drives move every one of its coordinates). Both formulations call it where they
// activate a limit.
bool drivenAtLimit(const System& sys, const LimitSpec& limit, double q, double t);
// How far past a bound a coordinate may stand and still count as on it: the round-off of
// an assembled or driven position, 1e-9 of the limits' and the model's scale
// (numerics::kLimitSlack). Assembly and drivenAtLimit judge by it alike.
double limitSlack(const System& sys, const LimitSpec& limit);
// Throws ModelError naming the joint (or the limit's name) for a limit on no joint
// coordinate, on one without a position coordinate, a term named twice or with a zero or
// non-finite coefficient, or with bounds that are not finite with lower <= upper.
void validateLimit(const System& sys, const LimitSpec& limit);
// What a limit's name is in messages: "joint 'name'" or "coupling 'name'".
std::string limitSubject(const System& sys, const LimitSpec& limit);
// Which bound a free limit's coordinate q is past: -1 (lower), +1 (upper) or 0, with a
// round-off slack of a few ulps of the bounds' size: a coordinate driven exactly onto its
// bound (q = 2 t reaching 1 at t = 0.5, t itself a sum of steps) is at it, not past it,
// in both formulations alike (one computes q from the bodies, the other integrates it).
int limitSide(const LimitSpec& limit, double q);

}  // namespace mechanism_sim
