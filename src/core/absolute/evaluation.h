// Evaluation as data (after Pinocchio's Model / Data and MuJoCo's mjModel / mjData): what
// the equations of motion are at one state, as a plain record stamped with what it was
// computed from, and the free functions that fill it and read it. The stepper, assembly,
// the dependency analysis and the Mechanism's queries all work on such records; a query
// computes from a State (its own record when the stepper's describes another state).
//
//   * loadKinematics: the bodies' poses and velocities (BodyKin) from positions x and
//     velocities u, laid out by BodyCoordinates;
//   * evaluateConstraints: Phi, Phi_q (J per constraint), gamma, nu (doc/method.md);
//   * appliedForces: Q, the generalized forces besides the constraints';
//   * the one walk over the constraint blocks (forEachBlock) and what is built on it:
//     Phi_q v, Phi_q^T y, row weights, residuals.
#pragma once
#include <array>
#include <cmath>
#include <limits>
#include <vector>

#include <Eigen/Core>

#include "core/numerics.h"
#include "mechanism_sim/core/model/system.h"

namespace mechanism_sim {

// The layout of the absolute coordinates, in one place. Per moving body m (body m + 1 of
// the System): positions x at 7 m: r (3, global, the centre of mass), p (4, w x y z);
// velocities u (and accelerations, generalized forces) at 6 m: v (3, global), omega' (3,
// body components).
struct BodyCoordinates {
  static constexpr int kX = 7, kU = 6;
  static int x(int moving) { return kX * moving; }
  static int u(int moving) { return kU * moving; }
  static int positions(const System& sys) { return kX * sys.nb; }
};

// A constraint's Jacobian: 6 rows (zero past its size), 6 columns per body slot.
using Jacobian = Eigen::Matrix<double, 6, Eigen::Dynamic>;
using Vec6 = Eigen::Matrix<double, 6, 1>;
using Mat6 = Eigen::Matrix<double, 6, 6>;

// What an evaluation was computed from: kinematics at positions x and velocities u, the
// equations with the limits' sides, the time and the drives' references of a State. The
// level says how far it went; kSolved: the stepper solved accelerations and multipliers
// there (the State holds them).
struct EvaluationStamp {
  enum Level { kNone, kLoaded, kEvaluated, kSolved };
  Level level = kNone;
  Eigen::VectorXd x, u;
  double t = 0.0;
  std::vector<signed char> limit_side;
  std::vector<DriveRamp> drive;
  bool rates = true;  // gamma was computed (false: Phi, Phi_q and nu alone, what queries read)
  // The equations were evaluated at exactly this state (what queries need).
  bool describes(const State& s) const {
    return level >= kEvaluated && x == s.x && u == s.u && limit_side == s.limit_side && t == s.t && drive == s.drive;
  }
  // The same positions and active limits: the same Phi_q (what a factorization depends on).
  bool samePositions(const EvaluationStamp& o) const { return x == o.x && limit_side == o.limit_side; }
};

struct Evaluation {
  EvaluationStamp stamp;
  std::vector<BodyKin> kin;        // ground first
  std::vector<Jacobian> J;         // per constraint (dropped rows zeroed)
  Eigen::VectorXd Phi, nu, gamma;  // per row (Phi also of dropped rows)
  Eigen::VectorXd W;               // row weights (rowWeights)
  Eigen::VectorXd Q;               // generalized applied forces per body (appliedForces)
  std::vector<char> dropped;       // per row: left out (State::dropped when evaluated)
  std::vector<double> dropped_scale;  // per row: the size of a dropped row's terms
  // Per rotor inertia (System::rotors), per coordinate (2 r + c): its joint's row
  // (evaluateConstraints), whose G_k and gamma_k put the rotor into M and Q.
  std::vector<Row> rotor_rows;

  Evaluation() = default;
  explicit Evaluation(const System& sys);  // sized for sys: filling it allocates nothing
  Eigen::Ref<const Eigen::MatrixXd> jacobian(const System& sys, int c) const {
    return J[c].topRows(sys.layout[c].size);
  }
};

// Body kinematics of a state, ground first.
void loadKinematics(const System& sys, const double* x, const double* u, std::vector<BodyKin>& kin);
void loadKinematics(const System& sys, const double* x, const double* u, Evaluation& ev);
// Phi, J, gamma, nu at the loaded kinematics, with the context (tracked angles, limit
// sides, time, drives) and dropped rows of `context`. rates false: Phi, J and nu alone, the
// same bits, for less (EvalContext::rates; gamma is set to 0).
void evaluateConstraints(const System& sys, const State& context, Evaluation& ev, bool rates = true);
// Both, at the State itself.
void evaluateAt(const System& sys, const State& s, Evaluation& ev, bool rates = true);
// The loaded states of a constraint's bodies in its bodies() order.
inline void gather(const Evaluation& ev, const Constraint& c, const BodyKin** ptrs) {
  for (size_t k = 0; k < c.bodies().size(); ++k) ptrs[k] = &ev.kin[c.bodies()[k]];
}

// The effort a joint applies along one of its coordinates besides its constraint's: the
// commanded effort, viscous damping c q_dot and Coulomb friction (the one definition:
// forces, the Mechanism's jointEffort and jointReactions use it).
inline double appliedEffort(double tau, double c, double q_dot, double friction) {
  return tau - c * q_dot + friction;
}
// Coulomb friction of one joint for the step h about to be taken: the one rule of both
// formulations (Stepper::frictionFor, JointStepper::frictionFor), which differ only in how
// they get its inputs. f: the joint's friction per coordinate (0: none); rate_k = q_dot_k / h
// + q_ddot_k with q_ddot the accelerations without friction; gPg: q_x,k P q_x,l^T, P the
// constrained inverse mass (the inverse effective inertia of the coordinates with friction).
// The effort that stops coordinate k within the step, needed_k = rate_k / gPg_kk, is
// supplied up to f_k; a planar joint's two in-plane translations (planar) are taken
// together, the effort vector that stops both from their 2x2 block, clamped radially to
// the friction ellipse (Coulomb's law in the plane). out: the friction efforts (-needed);
// a coordinate with no free motion (gPg_kk = 0: a drive moves it) slides against the
// whole f (the drive overcomes it).
void coulombFriction(const std::array<double, 3>& f, bool planar, const double rate[3], const double gPg[3][3],
                     std::array<double, 3>& out);
// The coordinate rows of joint j at the loaded kinematics (Joint::coordinates).
void jointRows(const System& sys, const Evaluation& ev, const State& s, int j, Row* rows);
// Coordinate k's row of joint j (one of jointRows).
Row jointRow(const System& sys, const Evaluation& ev, const State& s, int j, int k);
// A limit's sum s = sum_i c_i q_i at the loaded kinematics (LimitSpec::terms, or its one
// coordinate before finalize() wrote them).
double limitValue(const System& sys, const Evaluation& ev, const State& s, const LimitSpec& L);
// ev.Q per body: [f (global, at the centre of mass); n' (body components)] from gravity,
// the inputs, springs, and the joints' applied efforts (damping c and friction per joint
// coordinate, and s.sum_friction on sums of coordinates).
void appliedForces(const System& sys, const State& s, const Inputs& in,
                   const std::vector<std::array<double, 3>>& damping,
                   const std::vector<std::array<double, 3>>& friction, Evaluation& ev);

// ---- the walk over the constraint blocks: f(slot, moving body, Jb) for each slot of
// constraint c on a moving body, Jb its 6 columns of J (6 rows).
template <class F>
inline void forEachBlock(const System& sys, const Evaluation& ev, int c, F&& f) {
  const ConstraintLayout& L = sys.layout[c];
  const Jacobian& J = ev.J[c];
  for (size_t s = 0; s < L.bodies.size(); ++s)
    if (L.bodies[s] >= 0) f(static_cast<int>(s), L.bodies[s], J.middleCols<6>(6 * s));
}
// The rows of constraint c, size padded to 6 with zeros.
inline Vec6 padded(const double* y, int size) {
  Vec6 v = Vec6::Zero();
  for (int e = 0; e < size; ++e) v[e] = y[e];
  return v;
}
// out = Phi_q v, out += Phi_q^T y, over the listed constraints (sys.all_constraints: all).
void mulJ(const System& sys, const Evaluation& ev, const std::vector<int>& cs, const double* v, double* out);
void addJt(const System& sys, const Evaluation& ev, const std::vector<int>& cs, const double* y, double* out);
void mulM(const System& sys, const double* v, double* out);  // out = M v
// out += sum_r q_x,r^T B_r q_x,r v: the rotor inertias' part of the mass matrix at the
// evaluation (System::rotors; the rotor's generalized force is -q_x^T B q_ddot,
// q_ddot = q_x a - gamma, whose gamma part appliedForces puts in Q).
void addRotorMass(const System& sys, const Evaluation& ev, const double* v, double* out);
// A coordinate row q_x,k (12 columns: body i, body j of joint j): out += q_x,k^T x, and
// q_x,k v.
void scatterRow(const System& sys, int joint, const Row& row, double x, double* out);
double rowDot(const System& sys, int joint, const Row& row, const double* v);

// ---- row weights and scales
// ev.W over the listed constraints: per row 1 / (J_e M~^-1 J_e^T), M~ the masses with
// stand-ins for massless bodies (System::Minv); W = kappa ev.W makes kappa dimensionless.
void rowWeights(const System& sys, Evaluation& ev, const std::vector<int>& cs);
// 1 / (row M~^-1 row^T) for a row over the bodies of a constraint.
double rowWeight(const System& sys, int constraint, const Eigen::Ref<const Eigen::MatrixXd>& row);
// The size of the terms of row e of J over the bodies of c: |J_r| (|r| + L) + |J_theta| per body.
double rowScale(const System& sys, const Evaluation& ev, const Constraint& c,
                const Eigen::Ref<const Eigen::MatrixXd>& J, int e);
// max over bodies of max(|v|, |w| L): how fast the mechanism moves (or accelerates).
double motionScale(const System& sys, const Eigen::VectorXd& u);
// Per body {max(|u_r|, |u_theta| L, floor), max(|u_theta|, |u_r| / L, floor / L)}.
void bodyScales(const System& sys, const Eigen::VectorXd& u, double floor, std::vector<std::array<double, 2>>& out);

// ---- queries (the constraints' state)
double positionViolation(const Evaluation& ev);  // max |Phi|
// max |Phi_q u - nu| (allocates: a query, not a step's)
double velocityViolation(const System& sys, const Evaluation& ev, const Eigen::VectorXd& u);
// Relative residuals: each equation against the size of its terms (scale-free), the
// dropped rows left out; droppedResidual: those of the dropped rows alone.
double positionResidual(const System& sys, const Evaluation& ev);
double droppedResidual(const System& sys, const Evaluation& ev);
// With the body scales of u (written to scales) or given ones.
double velocityResidual(const System& sys, const Evaluation& ev, const Eigen::VectorXd& u,
                        std::vector<std::array<double, 2>>& scales);
double velocityResidualAtScales(const System& sys, const Evaluation& ev, const Eigen::VectorXd& u,
                                const std::vector<std::array<double, 2>>& scales);
// |r| / scale, where scale is the size of the terms r was computed from; 0/0 = 0 (the
// residuals above, and the joint formulation's closures).
// A residual below the smallest normal double is zero whatever its scale: it is what is
// left of terms that are round-off of zero (a body held at rest with nothing in the model
// setting a speed: no gravity, no spring, so that the System's velocity scale is 0 and the
// scale of such terms says nothing).
inline double relative(double r, double scale) {
  r = std::fabs(r);
  if (r < std::numeric_limits<double>::min()) return 0.0;
  return scale > 0.0 ? r / scale : HUGE_VAL;
}
// Residual floors: kFloor times the system's largest motion (force) (numerics.h).
using numerics::kFloor;

// r += dr, p <- p (x) exp(dtheta'/2) per moving body: a displacement in variation coordinates.
void displace(const System& sys, Eigen::VectorXd& x, const double* dq);
// (x, u) -> x_dot: r_dot = v, p_dot = p (x) (0, w') / 2.
void positionRates(const System& sys, const double* x, const double* u, double* xdot);

}  // namespace mechanism_sim
