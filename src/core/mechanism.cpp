// Mechanism: the embedding facade over System, State, Inputs and the two formulations'
// steppers.
#include "mechanism_sim/core/mechanism.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "core/absolute/evaluation.h"
#include "core/absolute/solver.h"
#include "core/absolute/stepper.h"
#include "core/assembly/assembly.h"
#include "core/formulation.h"
#include "core/numerics.h"
#include "core/joint_space/joint_stepper.h"
#include "core/reaction_solve.h"
#include "mechanism_sim/core/model/couplers.h"
#include "mechanism_sim/core/model/coupling.h"

namespace mechanism_sim {

namespace {

// How far apart two poses of the bodies are: the largest of |r - r0| / L and the rotation
// angle between p and p0 (either sign of the quaternion).
double poseDistance(const System& sys, const Eigen::VectorXd& x0, const Eigen::VectorXd& x) {
  double d = 0.0;
  for (int b = 0; b < sys.nb; ++b) {
    const int i = BodyCoordinates::x(b);
    d = std::max(d, (x.segment<3>(i) - x0.segment<3>(i)).norm() / sys.length_scale);
    const double c = std::min(1.0, std::fabs(x.segment<4>(i + 3).dot(x0.segment<4>(i + 3))));
    d = std::max(d, 2.0 * std::acos(c));
  }
  return d;
}

// An input set again to the same bits (signed zeros apart): nothing to recompute.
bool sameBits(double a, double b) { return a == b && std::signbit(a) == std::signbit(b); }
bool sameBits(const Vector3d& a, const Vector3d& b) {
  for (int i = 0; i < 3; ++i)
    if (!sameBits(a(i), b(i))) return false;
  return true;
}

}  // namespace

Mechanism::Mechanism() : sys_(std::make_shared<System>()) {
  Body ground;
  ground.name = "ground";
  sys_->bodies.push_back(ground);
}

Mechanism::~Mechanism() = default;

const BodyKin& Mechanism::kin(int b) const { return evaluated().kin.at(b); }

void Mechanism::requireUnbuilt(const char* what) const {
  if (built_) throw UsageError(std::string("Mechanism::") + what + " after build()");
}

// Parameters that leave the layout alone may change after build(): copy on write, so a
// System that a Stepper or a snapshot refers to never changes under it.
System& Mechanism::editable() {
  stateChanged();
  if (built_) sys_ = std::make_shared<System>(*sys_);
  if (running_) running_->invalidate();  // (the State's accelerations were of the old System)
  state_.damping_hold.left = 0;          // (its damping classification too)
  return *sys_;
}

void Mechanism::useFormulation(bool settle) {
  stateChanged();
  const Formulation f = chooseFormulation(*sys_, parseFormulation(sys_->options.formulation), &formulation_why_);
  if (f == Formulation::kJoint) {
    if (!joint_) joint_ = std::make_unique<JointStepper>(*sys_);
    joint_->setMethod(parseMethod(sys_->options.method));
    if (settle) joint_->settle(*sys_, state_, inputs_);
    running_ = joint_.get();
  } else {
    const bool was_joint = joint_ != nullptr;
    joint_.reset();
    stepper_->adopt(*sys_, state_, inputs_);
    // the absolute stepper's accelerations and multipliers of this state
    if (settle && was_joint) stepper_->settle(*sys_, state_, inputs_);
    running_ = stepper_.get();
  }
  formulation_ = f;
}

int Mechanism::addBody(const Body& body) {
  requireUnbuilt("addBody");
  sys_->bodies.push_back(body);
  return numBodies() - 1;
}

int Mechanism::addJoint(std::unique_ptr<Joint> joint) {
  requireUnbuilt("addJoint");
  for (int b : joint->bodies())
    if (b < 0 || b >= numBodies())
      throw ModelError("joint '" + joint->name() + "': body index out of range");
  if (joint->bodyI() == joint->bodyJ())
    throw ModelError("joint '" + joint->name() + "': joins body '" +
                     sys_->bodies[joint->bodyI()].name + "' to itself");
  System& s = *sys_;
  s.joints.push_back(joint.get());
  s.joint_constraint.push_back(numConstraints());
  s.damping.push_back({0, 0, 0});
  s.friction.push_back({0, 0, 0});
  s.constraints.push_back(std::shared_ptr<Constraint>(std::move(joint)));
  return numJoints() - 1;
}

int Mechanism::addCoupler(const std::string& name, int joint_a, int k_a, int joint_b, int k_b,
                          double multiplier, double offset) {
  requireUnbuilt("addCoupler");
  auto check = [&](int j, int k) {
    if (j < 0 || j >= numJoints() || k < 0 || k >= sys_->joints[j]->dof())
      throw ModelError("coupler '" + name + "': no such joint coordinate");
    if (!sys_->joints[j]->holonomicCoordinates())
      throw ModelError("coupler '" + name + "': joint '" + sys_->joints[j]->name() +
                       "' has no position coordinate to couple");
  };
  check(joint_a, k_a);
  check(joint_b, k_b);
  if (joint_a == joint_b) throw ModelError("coupler '" + name + "': couples a joint to itself");
  if (!std::isfinite(multiplier) || !std::isfinite(offset))
    throw ModelError("coupler '" + name + "': multiplier and offset must be finite");
  sys_->constraints.push_back(std::make_shared<CoordinateCoupler>(
      name, *sys_->joints[joint_a], k_a, *sys_->joints[joint_b], k_b, multiplier, offset));
  return numConstraints() - 1;
}

namespace {

// The coupling's terms as the core takes them, or a ModelError naming what is wrong.
std::vector<CouplingTerm> couplingTerms(const System& sys, const std::string& what,
                                        const std::vector<Mechanism::CouplingCoordinate>& terms, double c0) {
  if (terms.size() < 2 || terms.size() > static_cast<size_t>(kMaxCouplingTerms))
    throw ModelError(what + "couples " + std::to_string(terms.size()) + " coordinates (2 to " +
                     std::to_string(kMaxCouplingTerms) + ")");
  if (!std::isfinite(c0)) throw ModelError(what + "its constant must be finite");
  std::vector<CouplingTerm> made;
  for (const Mechanism::CouplingCoordinate& t : terms) {
    if (t.joint < 0 || t.joint >= sys.numJoints() || t.k < 0 || t.k >= sys.joints[t.joint]->dof())
      throw ModelError(what + "no such joint coordinate");
    const Joint& joint = *sys.joints[t.joint];
    if (!joint.holonomicCoordinates())
      throw ModelError(what + "joint '" + joint.name() + "' has no position coordinate to couple");
    if (!std::isfinite(t.c) || t.c == 0.0)
      throw ModelError(what + "the coefficient of joint '" + joint.name() + "' must be finite and non-zero");
    for (const CouplingTerm& m : made)
      if (m.joint == &joint && m.k == t.k) throw ModelError(what + "joint '" + joint.name() + "' appears twice");
    made.push_back({&joint, t.k, t.c});
  }
  return made;
}

}  // namespace

int Mechanism::addCoupling(const std::string& name, const std::vector<CouplingCoordinate>& terms, double c0) {
  requireUnbuilt("addCoupling");
  std::vector<CouplingTerm> made = couplingTerms(*sys_, "coupling '" + name + "': ", terms, c0);
  sys_->constraints.push_back(std::make_shared<LinearCoupling>(name, std::move(made), c0));
  return numConstraints() - 1;
}

int Mechanism::addBacklashCoupling(const std::string& name, const std::vector<CouplingCoordinate>& terms, double c0,
                                   double backlash) {
  requireUnbuilt("addBacklashCoupling");
  const std::string what = "coupling '" + name + "': ";
  couplingTerms(*sys_, what, terms, c0);
  if (!std::isfinite(backlash) || !(backlash > 0.0)) throw ModelError(what + "its backlash must be finite and positive");
  LimitSpec limit;
  limit.joint = terms[0].joint, limit.k = terms[0].k;
  limit.lower = c0 - 0.5 * backlash, limit.upper = c0 + 0.5 * backlash;
  limit.name = name;
  for (const CouplingCoordinate& t : terms) limit.terms.push_back({t.joint, t.k, t.c});
  validateLimit(*sys_, limit);
  sys_->limits.push_back(limit);
  return static_cast<int>(sys_->limits.size()) - 1;
}

double Mechanism::couplingReaction(int ci) const {
  if (ci < 0 || ci >= numConstraints() || sys_->constraints[ci]->type() != "coupling")
    throw UsageError("constraint " + std::to_string(ci) + " is not a coupling");
  const Evaluation* ev = nullptr;
  return multipliers(&ev)[sys_->layout.at(ci).row];
}

double Mechanism::limitReaction(int l) const {
  if (l < 0 || l >= static_cast<int>(sys_->limits.size())) throw UsageError("no limit " + std::to_string(l));
  if (!state_.limit_side[l]) return 0.0;
  const Evaluation* ev = nullptr;
  return multipliers(&ev)[sys_->layout.at(sys_->limits[l].constraint).row];
}

int Mechanism::addSpring(const SpringDamper& s) {
  requireUnbuilt("addSpring");
  if (s.body_i < 0 || s.body_i >= numBodies() || s.body_j < 0 || s.body_j >= numBodies())
    throw ModelError("spring '" + s.name + "': body index out of range");
  if (!(s.k >= 0) || !(s.c >= 0) || !(s.L0 >= 0) || !std::isfinite(s.k + s.c + s.L0 + s.f_act))
    throw ModelError("spring '" + s.name + "': stiffness, damping and rest length must be "
                     "finite and non-negative");
  sys_->springs.push_back(s);
  return static_cast<int>(sys_->springs.size()) - 1;
}

void Mechanism::checkCoordinate(int joint, int k) const {
  if (joint < 0 || joint >= numJoints() || k < 0 || k >= sys_->joints[joint]->dof())
    throw UsageError("no such joint coordinate");
}

void Mechanism::setJointLimits(int joint, int k, double lower, double upper) {
  requireUnbuilt("setJointLimits");
  checkCoordinate(joint, k);
  LimitSpec limit;
  limit.joint = joint, limit.k = k, limit.lower = lower, limit.upper = upper;
  validateLimit(*sys_, limit);  // (at once, as finalize() would)
  sys_->limits.push_back(limit);
}

int Mechanism::addDrive(int joint, int k, const DriveProfile& profile, double q0) {
  if (built_) return addDriveAfterBuild(joint, k, profile);
  checkCoordinate(joint, k);
  const Joint& j = *sys_->joints[joint];
  if (!j.holonomicCoordinates())
    throw ModelError("joint '" + j.name() + "': a drive needs a position coordinate");
  for (const DriveSpec& D : sys_->drives)
    if (D.joint == joint && D.k == k) throw ModelError("joint '" + j.name() + "': the coordinate is already driven");
  if (!std::isfinite(q0)) throw ModelError("joint '" + j.name() + "': drive start position not finite");
  sys_->drives.push_back(DriveSpec{joint, k, profile, q0, 0});
  return numDrives() - 1;
}

int Mechanism::driveOf(int joint, int k) const {
  for (int d = 0; d < numDrives(); ++d)
    if (sys_->drives[d].joint == joint && sys_->drives[d].k == k) return d;
  return -1;
}

void Mechanism::driveTarget(int drive, double* q, double* q_dot, double* q_ddot) const {
  const DriveSpec& D = sys_->drives.at(drive);
  D.profile.eval(state_.t, state_.drive.at(drive), q, q_dot, q_ddot);
}

void Mechanism::commandDriveVelocity(int drive, double v, double acc) {
  if (!built_) throw UsageError("Mechanism::commandDriveVelocity before build()");
  const DriveSpec& D = sys_->drives.at(drive);
  const std::string who = "joint '" + sys_->joints[D.joint]->name() + "': ";
  if (D.profile.kind() != DriveProfile::Kind::kVelocity)
    throw UsageError(who + "its drive follows a profile; only a velocity drive takes commands");
  if (!std::isfinite(v)) throw UsageError(who + "drive velocity must be finite");
  if (!(acc > 0)) throw UsageError(who + "drive acceleration must be positive");
  double q, q_dot, q_ddot;
  driveTarget(drive, &q, &q_dot, &q_ddot);
  stateChanged();
  const DriveLag lag = state_.drive[drive].lag;  // (a drive held back stays behind the new profile)
  state_.drive[drive] = DriveRamp{state_.t, q, q_dot, v, std::isfinite(acc) ? acc : 0.0};
  state_.drive[drive].lag = lag;
}

void Mechanism::setGravity(const Vector3d& g) {
  if (!g.allFinite()) throw ModelError("gravity must be finite");
  System& sys = editable();
  sys.gravity = g;
  if (built_) sys.updateLoadScales();
}

void Mechanism::setJointDamping(int joint, int k, double c) {
  checkCoordinate(joint, k);
  if (!(c >= 0) || !std::isfinite(c))
    throw ModelError("joint '" + sys_->joints[joint]->name() + "': damping must be finite and >= 0");
  editable().damping[joint][k] = c;
  if (running_) running_->dampingChanged(*sys_);
}

void Mechanism::addRotorInertia(const RotorInertia& rotor) {
  requireUnbuilt("addRotorInertia");
  sys_->rotors.push_back(rotor);
}

void Mechanism::addSumFriction(const SumFriction& friction) {
  requireUnbuilt("addSumFriction");
  sys_->sum_friction.push_back(friction);
}

void Mechanism::setJointFriction(int joint, int k, double f) {
  checkCoordinate(joint, k);
  if (!(f >= 0) || !std::isfinite(f))
    throw ModelError("joint '" + sys_->joints[joint]->name() + "': friction must be finite and >= 0");
  editable().friction[joint][k] = f;
}

void Mechanism::setIntegrator(const IntegratorOptions& options) {
  options.validate();
  if (built_) chooseFormulation(*sys_, parseFormulation(options.formulation), nullptr);  // (throws, nothing changed)
  editable().options = options;
  if (stepper_) stepper_->setMethod(parseMethod(options.method));  // the Stepper holds the integrator
  if (built_) useFormulation(true);
}

void Mechanism::build() {
  if (built_) return;
  stateChanged();
  sys_->finalize();
  state_ = initialState(*sys_);
  inputs_ = zeroInputs(*sys_);
  stepper_ = std::make_unique<Stepper>(*sys_);
  query_eval_.reset();
  reactions_.reset();
  built_ = true;
  useFormulation(false);  // (settled by assemble(), or by the first step)
}

AssemblyReport Mechanism::assemble(const std::vector<CoordinateTarget>& positions,
                                   const std::vector<CoordinateTarget>& velocities) {
  build();
  stateChanged();
  const AssemblyReport r = mechanism_sim::assemble(*sys_, state_, *stepper_, positions, velocities, &dependencies_);
  // (past assembly's failure residual: dependent equations it accepted as disagreeing at the
  // file's precision; the steps are held to that)
  const double disagreement = r.position_residual > numerics::assembly::kAssemblyFailureResidual ? r.position_residual : 0.0;
  if (disagreement != sys_->description_residual) editable().description_residual = disagreement;
  stepper_->settle(*sys_, state_, inputs_);
  if (joint_) {  // the joint state of the assembled one
    const State assembled = state_;
    joint_->settle(*sys_, state_, inputs_);
    // Where assembly accepted dependent equations that disagree at the file's precision,
    // the joint formulation's closure projection may not hold the assembled pose (a least-norm
    // step along a direction the disagreeing rows nearly share moves it far): then the
    // absolute formulation, whose dependent rows stay dropped, runs the mechanism ("joint"
    // asked: refused).
    // So may its velocity projection stop a motion the dependent rows allow (rows the
    // rounding leaves independent there lock the mechanism).
    const double moved = poseDistance(*sys_, assembled.x, state_.x);
    const double slowed = motionScale(*sys_, assembled.u - state_.u) /
                          std::max(motionScale(*sys_, assembled.u), sys_->velocity_scale);
    if (moved > numerics::assembly::kDescriptionPrecision || slowed > numerics::assembly::kDescriptionPrecision) {
      std::ostringstream why;
      if (moved > numerics::assembly::kDescriptionPrecision)
        why << "the closures in joint coordinates move the assembled pose by " << moved
            << " (relative): its dependent equations disagree";
      else
        why << "the closures in joint coordinates change the assembled velocities by " << slowed
            << " (relative): its dependent equations disagree";
      if (parseFormulation(sys_->options.formulation) == Formulation::kJoint)
        throw ModelError("the joint formulation cannot run this mechanism: " + why.str() + "; use formulation 'absolute'");
      state_ = assembled;
      joint_.reset();
      stepper_->adopt(*sys_, state_, inputs_);
      running_ = stepper_.get();
      formulation_ = Formulation::kAbsolute;
      formulation_why_ = "absolute coordinates (auto: " + why.str() + ")";
    }
  }
  return r;
}

void Mechanism::step(double h) {
  if (!built_) throw UsageError("Mechanism::step before build() and assemble()");
  const bool saturation_current = saturation_current_;
  forgetQueries();
  // (saturating mode: the step starts within the bounds and its lags' ways back chosen for h;
  // the state it reaches is brought within them)
  if (!actuator_limits_.empty() && !saturation_current) saturate(h);
  // (a step that fails leaves the State at the last accepted step: the queries compute
  // from it, not from the stepper's evaluation, which the failed step left elsewhere)
  running_->step(*sys_, state_, inputs_, h);
  if (!actuator_limits_.empty()) saturate(h);
}

void Mechanism::setJointEffort(int joint, int k, double tau) {
  checkCoordinate(joint, k);
  if (!std::isfinite(tau)) throw UsageError("effort must be finite");
  if (!built_) throw UsageError("Mechanism::setJointEffort before build()");
  // (an unchanged input keeps the joint stepper's first stage: MechanismModel::step and the
  // node set every effort before every step, and recomputing it costs a fifth RK4 stage)
  if (sameBits(inputs_.effort[joint][k], tau)) return;
  inputs_.effort[joint][k] = tau;
  running_->invalidate();
  saturation_current_ = false;
}

void Mechanism::setBodyWrench(int body, const Vector3d& force, const Vector3d& torque_body) {
  if (!built_) throw UsageError("Mechanism::setBodyWrench before build()");
  if (!force.allFinite() || !torque_body.allFinite()) throw UsageError("wrench must be finite");
  if (sameBits(inputs_.force.at(body), force) && sameBits(inputs_.torque.at(body), torque_body)) return;
  inputs_.force.at(body) = force;
  inputs_.torque.at(body) = torque_body;
  running_->invalidate();
  saturation_current_ = false;
}

void Mechanism::setSpringActuation(int spring, double f_act) {
  if (!built_) throw UsageError("Mechanism::setSpringActuation before build()");
  if (!std::isfinite(f_act)) throw UsageError("actuation must be finite");
  const double value = f_act - sys_->springs.at(spring).f_act;
  if (sameBits(inputs_.spring_actuation.at(spring), value)) return;
  inputs_.spring_actuation.at(spring) = value;
  running_->invalidate();
  saturation_current_ = false;
}

void Mechanism::restore(const Snapshot& s) {
  if (!built_ || s.x.size() != state_.x.size() || s.tracked.size() != state_.tracked.size())
    throw UsageError("Mechanism::restore: the snapshot is of another mechanism");
  stateChanged();
  state_ = s;  // (queries compute from it; stepping goes on from it bit for bit)
  running_->invalidate();  // (recomputed at the next step: the same bits)
  running_->adopt(*sys_, state_, inputs_);  // (a snapshot of the other formulation)
}

void Mechanism::completeState() const {
  if (state_.bodies_pending && running_) running_->completeState(const_cast<State&>(state_));
}

const Evaluation& Mechanism::evaluated() const {
  completeState();
  if (described_) return *described_;
  if (stepper_ && stepper_->evaluation().stamp.describes(state_)) return *(described_ = &stepper_->evaluation());
  if (!query_eval_) query_eval_ = std::make_unique<Evaluation>(*sys_);
  // (queries read Phi, Phi_q, nu and the kinematics, never gamma: evaluated without rates)
  if (!query_eval_->stamp.describes(state_)) evaluateAt(*sys_, state_, *query_eval_, false);
  return *(described_ = query_eval_.get());
}

// ---- queries

Vector3d Mechanism::position(int b) const { return kin(b).r; }
Matrix3d Mechanism::rotation(int b) const { return kin(b).A_Oi; }
Quaterniond Mechanism::orientation(int b) const {
  if (b == kGround) return Quaterniond::Identity();
  completeState();
  const double* p = state_.x.data() + BodyCoordinates::x(b - 1) + 3;
  return Quaterniond(p[0], p[1], p[2], p[3]).normalized();
}

const Row* Mechanism::coordinateRows(int joint) const {
  if (rows_.size() != sys_->joints.size()) rows_.resize(sys_->joints.size()), rows_found_.assign(rows_.size(), 0);
  Row* rows = rows_[joint].data();
  if (!rows_found_[joint]) {
    const Joint& j = *sys_->joints[joint];
    j.coordinates(kin(j.bodyI()), kin(j.bodyJ()), state_.tracked[j.id()], rows);
    rows_found_[joint] = 1;
  }
  return rows;
}

int Mechanism::treeCoordinate(int joint, bool rate) const {
  return running_ ? running_->stateCoordinate(state_, joint, rate) : -1;
}

double Mechanism::jointPosition(int joint, int k) const {
  checkCoordinate(joint, k);
  const int i = treeCoordinate(joint, false);
  return i >= 0 ? state_.q[i + k] : coordinateRows(joint)[k].Phi;
}

double Mechanism::jointVelocity(int joint, int k) const {
  checkCoordinate(joint, k);
  const int i = treeCoordinate(joint, true);
  return i >= 0 ? state_.qdot[i + k] : coordinateRows(joint)[k].Phi_dot;
}

double Mechanism::jointEffort(int joint, int k) const {
  checkCoordinate(joint, k);
  double tau = appliedEffort(inputs_.effort[joint][k], sys_->damping[joint][k], jointVelocity(joint, k),
                             state_.friction[joint][k]);
  for (size_t l = 0; l < sys_->limits.size(); ++l)
    if (sys_->limits[l].single() && sys_->limits[l].joint == joint && sys_->limits[l].k == k && state_.limit_side[l])
      tau -= state_.lambda[sys_->layout[sys_->limits[l].constraint].row];
  const int d = driveOf(joint, k);
  if (d >= 0) tau -= state_.lambda[sys_->layout[sys_->drives[d].constraint].row];
  return tau;
}

Eigen::VectorXd Mechanism::multipliers(const Evaluation** with) const {
  const System& sys = *sys_;
  if (!reactions_) reactions_ = std::make_unique<ReactionSolve>();
  completeState();  // (the tree's reactions read the bodies' accelerations)
  Eigen::VectorXd lambda;
  if (running_->reactionMultipliers(sys, state_, inputs_, reactions_->tree, lambda, with)) return lambda;
  bool dependent = false;
  for (char d : state_.dropped) dependent = dependent || d;
  if (!dependent) {
    *with = &evaluated();
    return state_.lambda;
  }
  if (!reactions_->solver) {
    reactions_->ev = Evaluation(sys);
    reactions_->solver = makeSolver(sys, reactions_->stats);
  }
  minimumNormMultipliers(sys, state_, inputs_, reactions_->ev, *reactions_->solver, reactions_->stats, lambda);
  *with = &reactions_->ev;  // (the dependent rows' Jacobian is in this evaluation only)
  return lambda;
}

Reaction Mechanism::reaction(int ci) const {
  const ConstraintLayout& L = sys_->layout.at(ci);
  const Constraint& c = *sys_->constraints[ci];
  const Evaluation* ev = nullptr;
  const Eigen::VectorXd lambda = multipliers(&ev);
  const Eigen::MatrixXd J = ev->jacobian(*sys_, ci);
  const int k = static_cast<int>(c.bodies().size()) - 1;  // the last body (j of a joint)
  Eigen::Matrix<double, 6, 1> gen = Eigen::Matrix<double, 6, 1>::Zero();
  for (int e = 0; e < L.size; ++e) gen -= J.block<1, 6>(e, 6 * k).transpose() * lambda[L.row + e];
  const BodyKin& kb = kin(c.bodies()[k]);
  Reaction r;
  r.force = gen.head<3>();
  Vector3d arm = Vector3d::Zero();  // torque about the joint point B_j, not the centre of mass
  if (const Joint* on = c.jointOn(c.bodies()[k])) arm = kb.A_Oi * on->frameJ().sp_B;
  r.torque = kb.A_Oi * gen.tail<3>() - arm.cross(r.force);
  return r;
}

SolverStats Mechanism::solverStats() const {
  // the absolute stepper's (assembly's, at least), the joint stepper's when it runs, the
  // reaction queries'
  SolverStats s = stepper_->stats();
  if (running_ != stepper_.get()) s.add(running_->stats());
  if (reactions_) s.add(reactions_->stats);
  return s;
}

std::vector<Reaction> Mechanism::jointReactions() const {
  const System& sys = *sys_;
  const State& s = state_;
  const Evaluation* ev = nullptr;
  const Eigen::VectorXd lambda = multipliers(&ev);
  const std::vector<BodyKin>& kn = ev->kin;  // (s's kinematics, loaded with the Jacobians)
  std::vector<Reaction> out(sys.joints.size());
  // wrench of a generalized force gen = [f; n'] on body b, moved to joint point sp_B of b
  auto add = [&](int j, const Eigen::Matrix<double, 6, 1>& gen) {
    const Joint& jt = *sys.joints[j];
    const BodyKin& kb = kn[jt.bodyJ()];
    const Vector3d f = gen.head<3>();
    out[j].force += f;
    out[j].torque += kb.A_Oi * gen.tail<3>() - (kb.A_Oi * jt.frameJ().sp_B).cross(f);
  };
  // an effort tau along coordinate k of joint j acts on its body j as q_x,k,j^T tau
  Row rows[kMaxJointDofs];
  auto along = [&](int j, int k, double tau) {
    if (tau == 0.0) return;
    const Joint& jt = *sys.joints[j];
    jt.coordinates(kn[jt.bodyI()], kn[jt.bodyJ()], s.tracked[jt.id()], rows);
    add(j, rows[k].J.segment<6>(6).transpose() * tau);
  };
  std::vector<int> joint_of(sys.constraints.size(), -1);
  for (int j = 0; j < numJoints(); ++j) joint_of[sys.joint_constraint[j]] = j;
  EvalContext ctx;
  ctx.limit_side = s.limit_side.data();
  for (int ci = 0; ci < numConstraints(); ++ci) {
    const ConstraintLayout& L = sys.layout[ci];
    const Constraint& c = *sys.constraints[ci];
    if (joint_of[ci] >= 0) {  // the joint's own equations: -Phi_q^T lambda on body j
      const Eigen::MatrixXd J = ev->jacobian(sys, ci);
      Eigen::Matrix<double, 6, 1> gen = Eigen::Matrix<double, 6, 1>::Zero();
      for (int e = 0; e < L.size; ++e) gen -= J.block<1, 6>(e, 6).transpose() * lambda[L.row + e];
      add(joint_of[ci], gen);
    } else {  // limits, drives, couplers: efforts along joint coordinates
      CoordinateEffort efforts[kMaxCoordinateEfforts];
      const int n = c.coordinateEfforts(ctx, efforts);
      for (int e = 0; e < n; ++e) along(joint_of[efforts[e].joint->id()], efforts[e].k, efforts[e].sign * lambda[L.row]);
    }
  }
  for (int j = 0; j < numJoints(); ++j) {  // applied efforts: command, damping, friction
    const Joint& jt = *sys.joints[j];
    bool any = false;
    for (int k = 0; k < jt.dof(); ++k)
      any = any || inputs_.effort[j][k] != 0.0 || sys.damping[j][k] != 0.0 || s.friction[j][k] != 0.0;
    if (!any) continue;
    jt.coordinates(kn[jt.bodyI()], kn[jt.bodyJ()], s.tracked[jt.id()], rows);
    for (int k = 0; k < jt.dof(); ++k) {
      const double tau = appliedEffort(inputs_.effort[j][k], sys.damping[j][k], rows[k].Phi_dot, s.friction[j][k]);
      if (tau != 0.0) add(j, rows[k].J.segment<6>(6).transpose() * tau);
    }
  }
  // The rotors' inertial efforts -B q_ddot and the motors' coupled damping (transmission.h):
  // the drives' and commands' efforts above accelerate the rotors too and overcome their
  // damping, which the gearbox, not the child link, takes.
  for (const RotorInertia& R : sys.rotors) {
    Eigen::Vector2d q_ddot = Eigen::Vector2d::Zero();
    for (size_t c = 0; c < R.coords.size(); ++c) q_ddot[c] = jointAcceleration(R.coords[c].first, R.coords[c].second);
    Eigen::Vector2d tau = R.B * q_ddot;
    if (R.damping_coupling != 0.0) {  // the motors' coupled damping D_01 (transmission.h)
      tau[0] += R.damping_coupling * jointVelocity(R.coords[1].first, R.coords[1].second);
      tau[1] += R.damping_coupling * jointVelocity(R.coords[0].first, R.coords[0].second);
    }
    for (size_t c = 0; c < R.coords.size(); ++c) along(R.coords[c].first, R.coords[c].second, -tau[c]);
  }
  // Coulomb friction on sums of coordinates: c_i F along each (System::sum_friction)
  for (size_t r = 0; r < sys.sum_friction.size() && r < s.sum_friction.size(); ++r)
    for (const LimitTerm& t : sys.sum_friction[r].terms) along(t.joint, t.k, t.c * s.sum_friction[r]);
  return out;
}

double Mechanism::positionViolation() const { return mechanism_sim::positionViolation(evaluated()); }
double Mechanism::velocityViolation() const {
  const Evaluation& ev = evaluated();  // (completes state_)
  return mechanism_sim::velocityViolation(*sys_, ev, state_.u);
}
double Mechanism::stepPositionViolation() const {
  double p = 0.0, v = 0.0;
  return running_ && running_->stepViolation(state_, p, v) ? p : positionViolation();
}
double Mechanism::stepVelocityViolation() const {
  double p = 0.0, v = 0.0;
  return running_ && running_->stepViolation(state_, p, v) ? v : velocityViolation();
}
double Mechanism::relativePositionViolation() const { return positionResidual(*sys_, evaluated()); }
double Mechanism::relativeVelocityViolation() const {
  std::vector<std::array<double, 2>> scales(sys_->nb);
  const Evaluation& ev = evaluated();  // (completes state_)
  return velocityResidual(*sys_, ev, state_.u, scales);
}

double Mechanism::kineticEnergy() const {
  completeState();
  double T = 0;
  for (int b = 1; b < numBodies(); ++b) {
    const Body& B = sys_->bodies[b];
    const double* ub = state_.u.data() + BodyCoordinates::u(b - 1);
    const Eigen::Map<const Vector3d> v(ub), w(ub + 3);
    T += 0.5 * B.m * v.squaredNorm() + 0.5 * w.dot(B.Jp * w);
  }
  for (const RotorInertia& R : sys_->rotors) {  // 1/2 q_dot^T B q_dot
    Eigen::Vector2d q_dot = Eigen::Vector2d::Zero();
    for (size_t c = 0; c < R.coords.size(); ++c) q_dot[c] = jointVelocity(R.coords[c].first, R.coords[c].second);
    T += 0.5 * q_dot.dot(R.B * q_dot);
  }
  return T;
}

double Mechanism::potentialEnergy() const {
  double V = 0;
  for (int b = 1; b < numBodies(); ++b) V -= sys_->bodies[b].m * sys_->gravity.dot(kin(b).r);
  for (const SpringDamper& s : sys_->springs) {
    const Vector3d d = kin(s.body_j).r + kin(s.body_j).A_Oi * s.sp_j - kin(s.body_i).r -
                       kin(s.body_i).A_Oi * s.sp_i;
    V += 0.5 * s.k * (d.norm() - s.L0) * (d.norm() - s.L0);
  }
  return V;
}

}  // namespace mechanism_sim
