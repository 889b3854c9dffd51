// A mechanism: rigid bodies in absolute coordinates, joints as algebraic constraints,
// force elements, and the integration of the constrained Newton-Euler equations
//   M a + Phi_q^T lambda = Q,   Phi_q a = gamma
// with a = (v_dot, w_dot) per body (notation.h).
//
// Method (the default, "rk4"): the index-1 equations are integrated by classical RK4;
// the accelerations come from the augmented Lagrangian iteration (Bayo & Ledesma 1996)
//   (M + alpha Phi_q^T Phi_q) a_{k+1} = Q - Phi_q^T (lambda_k - alpha gamma),
//   lambda_{k+1} = lambda_k + alpha (Phi_q a_{k+1} - gamma),
// which needs no independent subset of equations (dependent and momentarily singular
// Phi_q are fine) and allows massless bodies wherever every free motion moves mass, since
// M + alpha Phi_q^T Phi_q is then positive definite. After each step the state is
// projected back onto the constraints, mass-orthogonally: positions by Newton
// iterations on Phi = 0, then velocities onto Phi_q v = 0 (coordinate projection, Hairer,
// Lubich & Roche 1989; Eich 1993). See README "Integration method" for why.
#pragma once
#include <array>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "mechanism_sim/core/joint.h"
#include "mechanism_sim/core/sparse_ldlt.h"

namespace mechanism_sim {

// A model that cannot be simulated; the message names what is at fault.
class ModelError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

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
};

// A target for one joint coordinate during assembly.
struct CoordinateTarget {
  int joint = 0, k = 0;
  double value = 0.0;
};

struct AssemblyReport {
  double position_residual = 0.0, velocity_residual = 0.0;
  int iterations = 0;
};

// Which equations depend on others, found at assembly by a pivoted elimination in
// joint order: a dependent equation belongs to the later joint.
struct DependencyReport {
  int equations = 0, dependent = 0;
  std::vector<std::pair<std::string, int>> by_constraint;  // (name, dependent count)
  std::string describe() const;
};

// Force (global) and torque (global, about B_j) that a constraint applies to its body j.
struct Reaction {
  Vector3d force = Vector3d::Zero(), torque = Vector3d::Zero();
};

struct IntegratorOptions {
  std::string method = "rk4";     // "rk4" (default) or "rk2" (Heun)
  double position_tol = 1e-12;    // projection targets, max |Phi| and max |Phi_q v|
  double velocity_tol = 1e-12;
};

class Mechanism {
 public:
  static constexpr int kGround = 0;
  Mechanism();
  Mechanism(const Mechanism&) = delete;
  Mechanism& operator=(const Mechanism&) = delete;

  // ---- model building
  int addBody(const Body& body);
  int addJoint(std::unique_ptr<Joint> joint);
  // URDF <mimic>: q_a(k_a) = multiplier * q_b(k_b) + offset, an exact constraint.
  int addCoupler(const std::string& name, int joint_a, int k_a, int joint_b, int k_b,
                 double multiplier, double offset);
  int addSpring(const SpringDamper& spring);
  void setGravity(const Vector3d& g) {
    gravity_ = g;
    acc_valid_ = false;
  }
  void setJointDamping(int joint, int k, double c);
  // Coulomb friction f >= 0 along coordinate k: opposes the motion with at most f, and at
  // most the effort that stops the joint within one step (so a joint pushed by less than
  // f stays still). Held constant over a step: never stiff.
  void setJointFriction(int joint, int k, double f);
  // Position limits of a one-dof coordinate: unilateral, activated on contact with no
  // rebound, released when the joint pulls away.
  void setJointLimits(int joint, int k, double lower, double upper);
  void setIntegrator(const IntegratorOptions& options);
  // Validates the model and lays out the sparse structures. Throws ModelError.
  void build();
  // Brings the bodies onto the constraints (positions, then velocities), holding the
  // given joint coordinates; checks mass and reports dependent equations.
  AssemblyReport assemble(const std::vector<CoordinateTarget>& positions = {},
                          const std::vector<CoordinateTarget>& velocities = {});

  // ---- running
  void step(double h);
  double time() const { return t_; }
  void setJointEffort(int joint, int k, double tau);
  void setBodyWrench(int body, const Vector3d& force, const Vector3d& torque_body);
  void setSpringActuation(int spring, double f_act);
  // A copy of the whole state (bodies, time, turn counts) to return to later.
  struct Snapshot {
    std::vector<double> x, u;
    std::vector<std::array<double, 2>> tracked;
    double t = 0;
  };
  Snapshot snapshot() const;
  void restore(const Snapshot& s);

  // ---- model queries
  int numBodies() const { return static_cast<int>(bodies_.size()); }
  const Body& body(int b) const { return bodies_[b]; }
  int numJoints() const { return static_cast<int>(joints_.size()); }
  const Joint& joint(int j) const { return *joints_[j]; }
  int jointConstraintIndex(int j) const { return joint_constraint_[j]; }
  int numConstraints() const { return static_cast<int>(constraints_.size()); }
  const Constraint& constraint(int c) const { return *constraints_[c]; }
  int numEquations() const { return m_eq_; }
  const DependencyReport& dependencies() const { return dependencies_; }
  const Vector3d& gravity() const { return gravity_; }
  const IntegratorOptions& integrator() const { return options_; }

  // ---- state queries (of the current, accepted state)
  Vector3d position(int b) const;
  Matrix3d rotation(int b) const;
  Quaterniond orientation(int b) const;
  // Joint coordinate k: position, rate, and the effort the joint applies along it
  // (commanded effort minus damping, plus a limit's reaction).
  double jointPosition(int joint, int k) const;
  double jointVelocity(int joint, int k) const;
  double jointEffort(int joint, int k) const;
  Reaction reaction(int constraint) const;
  double positionViolation() const;  // max |Phi|
  double velocityViolation() const;  // max |Phi_q v|
  double kineticEnergy() const;
  double potentialEnergy() const;
  int stepsTaken() const { return steps_; }

 private:
  struct CouplerData;
  struct LimitData {
    int joint, k;
    double lower, upper;
    int active = 0;  // -1 at lower, +1 at upper, 0 free
    double lambda = 0.0;
  };
  struct ConstraintData {
    int row = 0, size = 0;
    std::vector<int> cols;                // 6*(b-1) per moving body, -1 for ground
    std::vector<const BodyKin*> kin;      // states of the constraint's bodies
    Eigen::MatrixXd J;                    // size x 6*bodies
    std::vector<int> base, stride;        // H addresses of block (k1, k2): k1*nb + k2
  };

  // state <-> kinematics
  void loadKinematics(const double* x, const double* u);
  void storeState(double* x, double* u) const;
  void evaluateConstraints();
  void computeForces();
  void assembleH(double alpha, double shift, bool mass);
  void factorH(const char* where);
  void solveAccelerations();
  void rates(const double* x, const double* u, double* xdot, double* udot);
  void positionRates(const double* x, const double* u, double* xdot) const;
  void projectPositions(bool refactor);
  void projectVelocities();
  void finishStep(bool project);
  bool updateLimits();
  void deactivateLimits();
  void setLimitSide(size_t l, int side);  // -1 at lower, +1 at upper, 0 free
  void addJtx(const double* x, double* out) const;   // out += Phi_q^T x
  void mulJ(const double* v, double* out) const;      // out = Phi_q v
  void mulM(const double* u, double* out) const;      // out = M u
  void applyDisplacement(const double* dq);
  void jointRows(int joint, std::array<Row, 3>& rows) const;
  void addJtJ(const ConstraintData& cd, const Eigen::Ref<const Eigen::MatrixXd>& J, double weight);
  void analyzeDependencies();
  Eigen::Matrix<double, 12, 1> rowVelocity(const CoordinateTarget& t) const;
  void checkMassRank();
  double maxAbs(const Eigen::VectorXd& v, int size) const;

  std::vector<Body> bodies_;
  std::vector<std::unique_ptr<Constraint>> constraints_;
  std::vector<std::unique_ptr<Joint>> joint_storage_;
  std::vector<const Joint*> joints_;
  std::vector<int> joint_constraint_;
  std::vector<SpringDamper> springs_;
  std::vector<LimitData> limits_;
  std::vector<std::array<double, 3>> joint_damping_, joint_effort_, joint_friction_, friction_effort_;
  double last_h_ = 1e-3;
  bool updateFriction();
  std::vector<Vector3d> body_force_, body_torque_;
  Vector3d gravity_ = Vector3d(0, 0, -9.81);
  IntegratorOptions options_;
  DependencyReport dependencies_;
  bool built_ = false;

  // sizes: n_ = 6 * moving bodies, m_ = rows (limits included), m_eq_ = equations
  int n_ = 0, m_ = 0, m_eq_ = 0;
  std::vector<int> diag_base_, diag_stride_, limit_constraint_;
  double alpha_ = 1.0, t_ = 0.0;
  int steps_ = 0;
  std::vector<BodyKin> kin_;
  std::vector<ConstraintData> cdata_;
  std::vector<int> Hp_, Hi_;
  std::vector<double> Hx_;
  SparseLDLT ldlt_;
  Eigen::VectorXd Phi_, gamma_, lambda_, Q_, acc_, Mdiag_;
  Eigen::VectorXd x_, u_, x0_, u0_, xs_, us_, kx_[4], ku_[4];
  Eigen::VectorXd work_n_, work_n2_, work_m_, work_m2_;
  mutable Eigen::VectorXd work_query_;  // for const queries, so that they allocate nothing
  bool acc_valid_ = false;
};

}  // namespace mechanism_sim
