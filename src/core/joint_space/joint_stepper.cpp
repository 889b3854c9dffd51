// The joint-space formulation's stepper (joint_stepper.h).
#include "core/joint_space/joint_stepper.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include <Eigen/Cholesky>

#include "mechanism_sim/core/model/couplers.h"
#include "core/absolute/evaluation.h"
#include "core/absolute/projection.h"
#include "core/numerics.h"
#include "core/joint_space/tree_reactions.h"

namespace mechanism_sim {
using numerics::kMaxVelocityPasses;

std::string jointFormulationUnsupported(const System& sys) {
  // Couplers, drives and limits are closures on the tree (loop_closure.h); joint damping
  // and Coulomb friction are efforts along the joint coordinates (step()).
  std::string why = jointSpaceUnsupported(sys, true);
  if (!why.empty()) return why;
  // Coulomb friction on a joint that closes a loop is not sized by frictionFor (tree
  // coordinates only); its damping is an effort (accelerations()).
  const TreeModel tree(sys);
  for (int j : tree.cut_joints)
    for (int k = 0; k < sys.joints[j]->dof(); ++k)
      if (j < static_cast<int>(sys.friction.size()) && sys.friction[j][k] != 0.0)
        return "joint '" + sys.joints[j]->name() + "' closes a loop: the joint formulation has no Coulomb friction on it";
  // friction on a sum of coordinates: on coordinates the tree's own (q_dot's entries)
  for (const SumFriction& F : sys.sum_friction)
    for (const LimitTerm& t : F.terms) {
      const int link = tree.joint_link[t.joint];
      if (link < 0 || tree.links[link].quaternion >= 0 || tree.links[link].tie >= 0 || tree.links[link].tie_master)
        return "friction '" + F.name + "' on joint '" + sys.joints[t.joint]->name() +
               "', which closes a loop, is coupled or is not a tree coordinate: the joint formulation has no friction "
               "on it";
    }
  // A link whose whole subtree has neither mass nor inertia (a motor's rotor of mass 0,
  // whose inertia the loader drops, turned by a coupler) has no inertia along its joint:
  // the articulated-body recursion divides by it. The absolute formulation runs it (its
  // motion comes from the closures alone).
  std::vector<char> moves_mass(tree.nb, 0);
  for (int n = tree.nb - 1; n >= 0; --n) {
    const int b = tree.order[n];
    const Body& B = sys.bodies[b];
    if (B.m > 0.0 || !B.Jp.isZero(0.0)) moves_mass[b - 1] = 1;
    const int p = tree.links[b - 1].parent;
    if (p != 0 && moves_mass[b - 1]) moves_mass[p - 1] = 1;
  }
  for (const TreeLink& L : tree.links)
    if (L.nv > 0 && !moves_mass[L.body - 1])
      return "body '" + sys.bodies[L.body].name + "' and the bodies it carries have neither mass nor inertia: " +
             (L.joint >= 0 ? "joint '" + sys.joints[L.joint]->name() + "'" : std::string("its free motion")) +
             " moves no mass, which the joint formulation's recursion cannot take";
  // A moving body that, with the bodies welded to it, has neither mass nor inertia and
  // carries a moving body on a joint of its own (a CAD exporter's spherical joint as three
  // revolutes with two massless links between them) passes its child's inertia up only
  // along the motions its child's joint does not take: where the joints' motions become
  // dependent (the middle revolute lines up the outer axes, a gimbal lock) the joint-space
  // mass matrix is singular and the articulated-body recursion divides by zero. Whether
  // such a pose is reachable depends on the whole chain, so any such body refuses the joint
  // formulation; the absolute formulation runs it (its dependent equations are solved).
  std::vector<char> inert(tree.nb + 1, 0);  // per host: the welded group has mass or inertia
  for (const TreeLink& L : tree.links) {
    const Body& B = sys.bodies[L.body];
    if (L.host > 0 && (B.m > 0.0 || !B.Jp.isZero(0.0))) inert[L.host] = 1;
  }
  for (int b : tree.order) {
    const TreeLink& L = tree.links[b - 1];
    if (L.nv == 0 || L.aparent == 0 || inert[L.aparent]) continue;
    const TreeLink& P = tree.links[L.aparent - 1];
    auto joint = [&](const TreeLink& K) {
      return K.joint >= 0 ? "joint '" + sys.joints[K.joint]->name() + "'" : std::string("its free motion");
    };
    return "body '" + sys.bodies[P.body].name + "' has neither mass nor inertia between " + joint(P) + " and " +
           joint(L) + ": the joint-space mass matrix is singular where their motions become dependent (a gimbal lock)";
  }
  return why;
}

JointStepper::JointStepper(const System& sys, bool embed_couplers)
    : model_(sys, embed_couplers),
      ws_(model_),
      closures_(model_, sys),
      damping_(model_, ws_, closures_),
      query_ws_(model_) {
  const std::string unsupported = jointFormulationUnsupported(sys);
  if (!unsupported.empty()) throw ModelError("the joint formulation cannot run this mechanism: " + unsupported);
  tableau_ = &tableau(parseMethod(sys.options.method));
  auto zeros = [](Eigen::VectorXd& v, int n) { v = Eigen::VectorXd::Zero(n); };
  zeros(stages_.tau, model_.nv), zeros(stages_.q0, model_.nq), zeros(stages_.v0, model_.nv), zeros(stages_.qs, model_.nq);
  for (int k = 0; k < Tableau::kMaxStages; ++k)
    zeros(stages_.kq[k], model_.nq), zeros(stages_.kv[k], model_.nv), zeros(stages_.vs[k], model_.nv);
  zeros(start_.q_round, model_.nq), zeros(start_.qdot_round, model_.nv);
  zeros(stages_.acc_k4, 6 * sys.nb);
  start_.backup.assign(numerics::kMaxHalvings + 1, State());
  loads_ = zeroInputs(sys);
  kin_.assign(sys.bodies.size(), BodyKin());
  setDamping(sys);
  friction_.e.setZero(model_.nv), friction_.y.setZero(model_.nv);
  friction_.r.setZero(closures_.m), friction_.mu.setZero(closures_.m);
  for (int j : model_.cut_joints) cut_constraints_.push_back(sys.joint_constraint[j]);
  for (const LimitSpec& L : sys.limits) limit_rows_.push_back(sys.layout[L.constraint].row);
  for (const TreeLink& L : model_.links) {
    if (L.joint < 0 || L.quaternion >= 0) continue;  // (a quaternion's joint tracks no angle)
    for (int k = 0; k < L.ptr->dof(); ++k) {
      const int slot = L.ptr->trackedSlot(k);
      if (slot >= 0) tracked_coordinates_.push_back({L.ptr->id(), slot, L.iq + k});
    }
  }
  closure_mode_.form_Y = false;  // (only JointDamping::implicit reads M^-1 G^T whole)
}

void JointStepper::setDamping(const System& sys) {
  closures_.rebind(sys);  // (a Mechanism's System is copied on write)
  damping_.set(sys);
  end_.fresh = false;
}

void JointStepper::accelerations(const System& sys, const State& s, const Inputs& in, double t,
                                 const Eigen::VectorXd& q, const Eigen::VectorXd& qdot, Eigen::VectorXd& qddot,
                                 bool evaluated) {
  stages_.tau = tau_in_;  // the inputs' efforts along the joint coordinates (setInputs)
  // Damping, per coordinate of q_dot: a spherical joint's are the relative angular velocity
  // in frame i, Joint::coordinates' rates (settle() reads q_dot from them), so tau_k =
  // -c_k q_dot_k is the absolute formulation's q_x,k^T (-c_k q_x,k u) (appliedForces): one power,
  // tau . q_dot = (G^T tau) . u, on the tree's coordinates and the bodies' alike.
  const std::vector<JointDamping::Damped>& damped = damping_.damped();
  for (size_t i = 0; i < damped.size(); ++i)  // damping that is not stiff: an effort
    if (!damping_.stiff()[i]) stages_.tau(damped[i].iv) -= damped[i].c * qdot(damped[i].iv);
  // Coulomb friction: the step's efforts (frictionFor), held over its stages
  if (friction_acts_) {
    for (const TreeLink& L : model_.links)
      if (L.joint >= 0)
        for (int k = 0; k < L.nv; ++k) stages_.tau(L.iv + k) += s.friction[L.joint][k];
    for (size_t r = 0; r < sys.sum_friction.size(); ++r)  // on sums of coordinates: c_i F along each
      if (s.sum_friction[r] != 0.0)
        for (const LimitTerm& t : sys.sum_friction[r].terms)
          stages_.tau(model_.links[model_.joint_link[t.joint]].iv + t.k) += t.c * s.sum_friction[r];
  }
  const Inputs* loads = &in;
  if (!sys.springs.empty() || !damping_.cutDamped().empty()) {
    // springs act between points of bodies: body loads at the tree's poses (appliedForces)
    if (!evaluated) forwardKinematics(model_, q, qdot, ws_);
    absoluteState(model_, ws_, spring_x_, spring_u_);
    loadKinematics(sys, spring_x_.data(), spring_u_.data(), kin_);
    loads_.force = in.force;
    loads_.torque = in.torque;
    loads_.effort = in.effort;  // (a cut joint's effort acts through the closures' rows)
    // A cut joint's damping: an effort -c q_dot_k along its coordinate, the rate from its two
    // bodies (Joint::coordinates, as the absolute formulation's appliedForces), acting on
    // the tree through addCutJointEfforts. Explicit only: a cut joint damped too stiffly for
    // the step fails the step (its projection), it is not integrated implicitly.
    for (int j : damping_.cutDamped()) {
      const Joint& J = *sys.joints[j];
      Row rows[kMaxJointDofs];
      J.coordinates(kin_[J.bodyI()], kin_[J.bodyJ()], s.tracked[J.id()], rows);
      for (int k = 0; k < J.dof(); ++k) loads_.effort[j][k] -= sys.damping[j][k] * rows[k].Phi_dot;
    }
    for (size_t i = 0; i < sys.springs.size(); ++i) {
      const SpringDamper& sd = sys.springs[i];
      const Vector3d f = sd.forceOnI(kin_[sd.body_i], kin_[sd.body_j], in.spring_actuation[i], sys.length_scale);
      auto addForceAt = [&](int b, const Vector3d& sp, const Vector3d& f) {
        if (b == System::kGround) return;
        loads_.force[b] += f;
        loads_.torque[b] += sp.cross(kin_[b].A_Oi.transpose() * f);
      };
      addForceAt(sd.body_i, sd.sp_i, f);
      addForceAt(sd.body_j, sd.sp_j, -f);
    }
    loads = &loads_;
  }
  if (closures_.m == 0) {
    forwardDynamics(model_, sys, q, qdot, stages_.tau, ws_, qddot, loads);
    return;
  }
  // the closures (drives, limits, couplers) read the State's context at the stage's time
  EvalContext ctx = s.context();
  ctx.t = t;
  closures_.setContext(ctx);
  constrainedForwardDynamics(model_, sys, closures_, q, qdot, stages_.tau, ws_, qddot, loads, evaluated, closure_mode_);
}

void JointStepper::writeAbsolute(const System& sys, State& s) {
  // (ws_ holds the kinematics of s.q, s.qdot: accelerations() ran there last)
  // the closures' multipliers (drives, limits, couplers) in their System rows; a free
  // limit's is 0. The tree joints' rows have none: a reactions query computes them
  // (Mechanism::multipliers(), treeJointMultipliers: tree_reactions.h).
  // (a coupler the tree holds has no multiplier of the solve: the reactions query gives it,
  // treeJointMultipliers)
  for (int k : model_.ties) s.lambda[sys.layout[model_.links[k].tie_coupler].row] = 0.0;
  if (closures_.m > 0) {
    closures_.systemMultipliers(s.lambda);
    for (size_t l = 0; l < limit_rows_.size(); ++l)
      if (s.limit_side[l] == 0) s.lambda[limit_rows_[l]] = 0.0;
  }
  s.bodies_pending = true;  // x, u, acc (completeState)
  // Tracked angles: a tree joint's are its coordinates themselves (so an angle may advance
  // by any amount in a step: a wheel at 4000 rad/s turns 4 rad a millisecond). A cut
  // joint's follow its two bodies (Constraint::track at the new kinematics, as the absolute
  // formulation tracks every joint), below. The other constraints (couplers, drives,
  // limits) keep none of their own: they read their joints'.
  for (const TrackedCoordinate& c : tracked_coordinates_) s.tracked[c.constraint][c.slot] = s.q[c.iq];
  if (!cut_constraints_.empty()) {
    closures_.setContext(s.context());
    closures_.track(ws_, cut_constraints_, s.tracked);
  }
  // the closures' violations at this state (stepViolation()): |Phi| and |G q_dot - nu|
  // of their rows, evaluated at (s.q, s.qdot) by the accelerations above
  end_.violation = {0.0, 0.0};
  // (free limits only: zero rows, nothing violated; the context is s's, as accelerations() set it)
  if (closures_.m > 0 && !closures_.allFreeLimits()) {
    end_.violation[0] = closures_.Phi.head(closures_.m).cwiseAbs().maxCoeff();
    if (end_.rate.size() != closures_.G.rows()) end_.rate.setZero(closures_.G.rows());
    closures_.timesG(s.qdot, end_.rate);
    end_.violation[1] = (end_.rate.head(closures_.m) - closures_.nu.head(closures_.m)).cwiseAbs().maxCoeff();
  }
  end_.q = s.q;
  end_.v = s.qdot;
  end_.generation = ws_.generation;
  end_.fresh = true;
}

void JointStepper::completeState(State& s) {
  if (!s.bodies_pending) return;
  // (ws_ holds the kinematics of (end_.q, end_.v) until the next step or projection moves it)
  TreeWorkspace* ws = &ws_;
  if (!(ws_.generation == end_.generation && end_.q == s.q && end_.v == s.qdot)) {
    forwardKinematics(model_, s.q, s.qdot, query_ws_);
    ws = &query_ws_;
  }
  absoluteState(model_, *ws, s.x, s.u);
  bodyAccelerations(model_, *ws, s.qddot, s.acc);
  s.bodies_pending = false;
}

bool JointStepper::stepViolation(const State& s, double& position, double& velocity) const {
  if (!end_.fresh || end_.q.size() != s.q.size() || end_.v.size() != s.qdot.size() || end_.q != s.q || end_.v != s.qdot)
    return false;
  position = end_.violation[0], velocity = end_.violation[1];
  return true;
}

// After the stages (or at a new state): limits that were passed become active (an
// inelastic stop: the projections bring the coordinate to its bound and its rate to 0),
// positions and velocities are projected onto the closures, the accelerations solved, and
// limits that would pull let go (solved again), as the absolute formulation's finishStep.
void JointStepper::finish(const System& sys, State& s, const Inputs& in) {
  // the couplers the tree holds (TreeLink::tie) exactly: the stages kept them to round-off
  // (a linear invariant of the ODE is one of every Runge-Kutta method)
  model_.holdTies(s.q, s.qdot, &s.q_round, &s.qdot_round);
  bool evaluated = false;
  if (closures_.m > 0) {
    closures_.setContext(s.context());
    if (!sys.limits.empty()) closures_.activateReachedLimits(sys, model_, s.q, s.qdot, ws_, s.limit_side.data());
    // (closures that are all free limits are zero rows: nothing to project onto)
    bool active = !closures_.onlyLimits();
    for (size_t l = 0; l < sys.limits.size() && !active; ++l) active = s.limit_side[l] != 0;
    // (the projections' last evaluation is at (q, q_dot) when they moved nothing: the
    // accelerations start from it)
    evaluated = active && project(sys, s);
  }
  accelerations(sys, s, in, s.t, s.q, s.qdot, s.qddot, evaluated);
  for (size_t pass = 0; pass < sys.limits.size() && closures_.releasePullingLimits(s.limit_side.data()) > 0;
       ++pass)
    accelerations(sys, s, in, s.t, s.q, s.qdot, s.qddot);
  if (!model_.cut_joints.empty()) s.qddot_ref = a_ref_;
  writeAbsolute(sys, s);
}

void JointStepper::setInputs(const Inputs& in, bool friction) {
  jointEfforts(model_, in, tau_in_);
  friction_acts_ = friction;
}

void JointStepper::resolve(const System& sys, State& s, const Inputs& in) {
  if (s.q.size() == 0) return settle(sys, s, in);
  setInputs(in, true);
  accelerations(sys, s, in, s.t, s.q, s.qdot, s.qddot);
  if (!model_.cut_joints.empty()) s.qddot_ref = a_ref_;
  writeAbsolute(sys, s);
  completeState(s);  // (only a step leaves it pending)
}

// Positions and velocities onto the closures (loop_closure.h), to the System's relative
// tolerances; a shortfall is counted, beyond kFailureResidual the step fails.
bool JointStepper::project(const System& sys, State& s) {
  closures_.setContext(s.context());
  // (kinematics at s.qdot: the equations do not read the rates, the accelerations after do)
  const ClosureProjectionReport p =
      projectClosurePositions(model_, sys, closures_, s.q, ws_, sys.options.position_tol, 20, &s.qdot, closure_mode_);
  stats_.countPositionProjection(p.converged, p.residual);
  if (!p.converged && p.residual > failureResidual(sys)) {
    std::ostringstream os;
    os << "the step left the constraints on the joint coordinates (relative residual "
       << fmt(p.residual) << "); try a smaller step";
    throw StepFailure(os.str());
  }
  const ClosureProjectionReport v =
      projectClosureVelocities(model_, sys, closures_, s.q, s.qdot, ws_, sys.options.velocity_tol, kMaxVelocityPasses,
                               true, p.at_rates, closure_mode_);  // (ws_ and closures_ at s.q: the position projection's last evaluation)
  stats_.countVelocityProjection(v.converged, v.residual);
  if (!v.converged && v.residual > failureResidual(sys)) {
    std::ostringstream os;
    os << "the velocities cannot be brought onto the constraints (relative residual "
       << fmt(v.residual) << ")";
    throw StepFailure(os.str());
  }
  return v.at_rates;
}

void JointStepper::settle(const System& sys, State& s, const Inputs& in) {
  closures_.rebind(sys);  // (a Mechanism's System is copied on write)
  completeState(s);  // (its source is the absolute state)
  setInputs(in, true);
  // (a new state: no round-off of a step to carry)
  s.q_round.setZero(model_.nq), s.qdot_round.setZero(model_.nv);
  s.damping_hold.left = 0;
  // A settled state has no motion before it: the closures' decomposition applies
  // (branch_passage.cpp: dependent rows dropped by geometry) but nothing is held by the motion.
  if (!model_.cut_joints.empty()) {
    a_ref_ = Eigen::VectorXd::Zero(model_.nv);
    closure_mode_.passage_ref = &a_ref_;
    closure_mode_.passage_hold = false;
  }
  // The joint coordinates of the absolute state: each link's joint reads them from its two
  // bodies (Joint::coordinates, branch references in s.tracked); a spherical joint's
  // quaternion is the rotation of frame j in frame i; a free body's are its own x, u.
  loadKinematics(sys, s.x.data(), s.u.data(), kin_);
  s.q = model_.neutralPositions(sys);
  s.qdot = Eigen::VectorXd::Zero(model_.nv);
  s.qddot = Eigen::VectorXd::Zero(model_.nv);
  Row rows[kMaxJointDofs];
  for (const TreeLink& L : model_.links) {
    if (L.joint < 0) {  // a free body
      const int b = L.body - 1;
      s.q.segment<7>(L.iq) = s.x.segment<7>(BodyCoordinates::x(b));
      s.qdot.segment<6>(L.iv) = s.u.segment<6>(BodyCoordinates::u(b));
      continue;
    }
    const Joint& J = *L.ptr;
    J.coordinates(kin_[J.bodyI()], kin_[J.bodyJ()], s.tracked[J.id()], rows);
    for (int k = 0; k < J.dof(); ++k) s.qdot[L.iv + k] = rows[k].Phi_dot;
    J.treePositions(kin_[J.bodyI()], kin_[J.bodyJ()], s.tracked[J.id()], s.q.data() + L.iq);
  }
  normalizeQuaternions(model_, s.q);
  try {
    finish(sys, s, in);
  } catch (...) {
    closure_mode_.passage_hold = true;
    throw;
  }
  completeState(s);  // (only a step leaves it pending)
  closure_mode_.passage_hold = true;
  // (a stage 1 computed again at this state holds what these accelerations have)
  if (!model_.cut_joints.empty()) s.qddot_ref = s.qddot;
  // the copies a step keeps (advance) sized now: a step allocates nothing
  start_.whole = s;
  for (State& b : start_.backup) b = s;
}

void JointStepper::step(const System& sys, State& s, const Inputs& in, double h) {
  closures_.rebind(sys);  // (a Mechanism's System is copied on write)
  if (!(h > 0) || !std::isfinite(h)) throw UsageError("step must be positive and finite");
  adopt(sys, s, in);
  if (s.q.size() != model_.nq || s.qdot.size() != model_.nv)
    throw UsageError("JointStepper::step: the State's joint state is of another mechanism");
  setInputs(in, true);
  // A step that fails leaves the State where it was (the last accepted step), not part
  // way through its substeps: stepOnce keeps what it changes (restoreStart), and the whole
  // State is copied only when the step is taken as halves.
  judged_ = tableau_->stages == 4 && damping_.damped().empty() && damping_.cutDamped().empty();
  start_.valid = false;
  try {
    advance(sys, s, in, h, 0);
  } catch (...) {
    if (start_.valid) s = start_.whole;
    end_.fresh = false;
    throw;
  }
}

// A step whose projections cannot bring it back onto the closures, or whose estimated error
// shows it leapt over what it should follow, is taken again as two half steps, each judged
// the same way, at most kMaxHalvings deep: the absolute formulation's rule
// (Stepper::advance). A tight turn of the motion (where a near-parallelogram's branches pass
// close and the motion turns from one onto the other within a fraction of a step) is then
// followed in steps that resolve it. The deepest substeps are kept unjudged; one that still
// fails stops the run saying how small the steps were.
//
// The error estimate is the absolute formulation's, on the bodies' velocities: RK4's k4
// against the derivative at the step's end (first same as last), h/6 |k4 - k5|, both as the
// bodies' accelerations at the end state (bodyAccelerations: their difference is the
// Jacobian there times the joint accelerations' difference). Not judged, as there: steps
// that change the active limits, mechanisms with joint damping, tableaus other than RK4.
void JointStepper::advance(const System& sys, State& s, const Inputs& in, double h, int depth) {
  if (depth > 0) start_.backup[depth] = s;
  if (judged_) completeState(s);
  const double scale0 = judged_ ? motionScale(sys, s.u) : 0.0;  // (the start's, for leapt)
  try {
    stepOnce(sys, s, in, h);
  } catch (const StepFailure& e) {  // (s is at the step's start)
    if (depth >= numerics::kMaxHalvings) {
      std::ostringstream os;
      os << e.what() << " (" << (1 << depth) << " substeps of " << fmt(h) << " s did not hold it either)";
      throw StepFailure(os.str());
    }
    if (depth == 0) start_.whole = s, start_.valid = true;
    halve(sys, s, in, h, depth, depth > 0 ? start_.backup[depth] : start_.whole);
    return;
  }
  if (depth >= numerics::kMaxHalvings || !leapt(sys, s, h, scale0)) return;
  if (depth == 0) {
    restoreStart(s);
    start_.whole = s, start_.valid = true;
  }
  halve(sys, s, in, h, depth, depth > 0 ? start_.backup[depth] : start_.whole);
}

void JointStepper::halve(const System& sys, State& s, const Inputs& in, double h, int depth, const State& before) {
  s = before;
  end_.fresh = false;
  ++stats_.halved_steps;
  advance(sys, s, in, 0.5 * h, depth + 1);
  advance(sys, s, in, 0.5 * h, depth + 1);
}

bool JointStepper::leapt(const System& sys, State& s, double h, double scale0) {
  if (!judged_ || s.limit_side != start_.limit_side) return false;
  // (ws_ holds the end state's kinematics: finish() solved its accelerations there)
  completeState(s);
  bodyAccelerations(model_, ws_, stages_.kv[3], stages_.acc_k4);
  const double L = sys.length_scale;
  double error = 0;
  for (int b = 0; b < sys.nb; ++b) {
    const int i = BodyCoordinates::u(b);
    error = std::max({error, (stages_.acc_k4.segment<3>(i) - s.acc.segment<3>(i)).norm(),
                      (stages_.acc_k4.segment<3>(i + 3) - s.acc.segment<3>(i + 3)).norm() * L});
  }
  error *= h / 6.0;
  const double scale = std::max({scale0, motionScale(sys, s.u), sys.velocity_scale});
  return error > numerics::kMaxStepError * scale;
}

void JointStepper::stepOnce(const System& sys, State& s, const Inputs& in, double h) {
  const Tableau& T = *tableau_;
  stages_.q0 = s.q;
  stages_.v0 = s.qdot;
  // branch passages (branch_passage.cpp): a stage 1 computed again below holds what the
  // State's own accelerations held (so a restored State steps as the run it came from)
  if (!model_.cut_joints.empty()) {
    a_ref_ = s.qddot_ref.size() == model_.nv ? s.qddot_ref : s.qddot;
    closure_mode_.passage_ref = &a_ref_;
  }
  start_.friction = s.friction;
  start_.sum_friction = s.sum_friction;
  if (!model_.cut_joints.empty()) start_.qddot_ref = s.qddot_ref;
  // stage 1: the accelerations the last step (or settle) left, when they are of this state
  // under these inputs; else computed here (with friction: without it, frictionFor's)
  const bool friction = clearFriction(sys, s);
  friction_acts_ = friction;  // (s.friction is zero over the step where no joint has friction)
  if (friction || !(end_.fresh && end_.q == s.q && end_.v == s.qdot)) accelerations(sys, s, in, s.t, stages_.q0, stages_.v0, s.qddot);
  // (ws_ holds q0's articulated factors now); stage 1 again if the stiff set changed
  if (!damping_.damped().empty()) {
    if (damping_.readsState(h, *tableau_)) completeState(s);  // (the bodies' poses)
    if (damping_.classify(sys, s, h, *tableau_)) accelerations(sys, s, in, s.t, stages_.q0, stages_.v0, s.qddot);
  }
  // Coulomb friction sized for this step from those (as the absolute formulation: after the
  // stiff set, so the stages' damping is in q_ddot), then stage 1 with it
  if (friction) {
    frictionFor(sys, s, h);
    accelerations(sys, s, in, s.t, stages_.q0, stages_.v0, s.qddot);
  }
  // branch passages of loops (branch_passage.cpp): what the stages hold across a branch is
  // the acceleration at the step's start
  if (!model_.cut_joints.empty()) a_ref_ = s.qddot;
  // the stages' position rates: q_dot itself where q has no quaternion (nq = nv), so the
  // velocities of the stages are read in place
  const bool rates_are_velocities = model_.nq == model_.nv;
  const double* kq[Tableau::kMaxStages];
  const double* kv[Tableau::kMaxStages];
  for (int k = 0; k < T.stages; ++k) {
    kq[k] = rates_are_velocities ? (k == 0 ? stages_.v0 : stages_.vs[k]).data() : stages_.kq[k].data();
    kv[k] = stages_.kv[k].data();
  }
  if (!rates_are_velocities) positionRates(model_, stages_.q0, stages_.v0, stages_.kq[0]);
  stages_.kv[0] = s.qddot;
  // (the later stages need no ordinary closure factorization where a passage's is taken:
  // only friction and damping at the step's start read it)
  closure_mode_.regular_factor = false;
  for (int k = 1; k < T.stages; ++k) {
    combineStages(h, T.a[k], k, T.a_den[k], stages_.q0, kq, stages_.qs);
    combineStages(h, T.a[k], k, T.a_den[k], stages_.v0, kv, stages_.vs[k]);
    accelerations(sys, s, in, s.t + T.c[k] * h, stages_.qs, stages_.vs[k], stages_.kv[k]);
    if (!rates_are_velocities) positionRates(model_, stages_.qs, stages_.vs[k], stages_.kq[k]);
  }
  closure_mode_.regular_factor = true;
  // The new state, its increments' round-off carried to the next step (compensated
  // summation: Higham, "Accuracy and Stability of Numerical Algorithms", 4.3; Hairer, Lubich
  // & Wanner, "Geometric Numerical Integration", VIII.5). q + h sum b_j k_j rounds to the
  // ulp of q at every step, an error a step that does not shrink with h: over 5 s at 0.1 ms
  // (5e4 steps, crank angles up to 16 rad) it random-walked the four-bars' energy by 1e-14
  // to 1e-13 of itself, which the 5 s error followed (a wheel at 1 rad/s: 1e-11 rad after
  // 1e5 steps of 0.1 ms, 6e-16 carried). The round-off is the State's
  // (q_round, qdot_round: a snapshot carries it; settle() zeroes it); a quaternion's, which
  // normalization rescales, is dropped.
  if (s.q_round.size() == model_.nq && s.qdot_round.size() == model_.nv) start_.q_round = s.q_round, start_.qdot_round = s.qdot_round;
  else start_.q_round.setZero(), start_.qdot_round.setZero(), s.q_round.setZero(model_.nq), s.qdot_round.setZero(model_.nv);
  compensatedUpdate(h, T.b, T.stages, T.b_den, stages_.q0, kq, start_.q_round, s.q_round, s.q);
  compensatedUpdate(h, T.b, T.stages, T.b_den, stages_.v0, kv, start_.qdot_round, s.qdot_round, s.qdot);
  normalizeQuaternions(model_, s.q);
  for (int i : model_.quaternions) s.q_round.segment<4>(i).setZero();
  if (damping_.anyStiff()) damping_.implicit(sys, s, h);
  start_.clock = s.clock();
  s.countStep(h);
  start_.limit_side = s.limit_side;
  try {
    finish(sys, s, in);
  } catch (...) {  // the State as it was (the last accepted step)
    restoreStart(s);
    end_.fresh = false;
    throw;
  }
  stats_.solves += T.stages;
}

void JointStepper::restoreStart(State& s) const {
  s.setClock(start_.clock);
  s.q = stages_.q0, s.qdot = stages_.v0;
  s.limit_side = start_.limit_side;
  s.friction = start_.friction;
  s.sum_friction = start_.sum_friction;
  s.q_round = start_.q_round, s.qdot_round = start_.qdot_round;
  if (!model_.cut_joints.empty()) s.qddot_ref = start_.qddot_ref;
}

bool JointStepper::clearFriction(const System& sys, State& s) const {
  bool any = false;
  for (int j = 0; j < sys.numJoints(); ++j) {
    s.friction[j] = {0.0, 0.0, 0.0};
    any = any || sys.friction[j][0] > 0.0 || sys.friction[j][1] > 0.0 || sys.friction[j][2] > 0.0;
  }
  for (size_t r = 0; r < sys.sum_friction.size(); ++r) {
    s.sum_friction[r] = 0.0;
    any = any || sys.sum_friction[r].f > 0.0;
  }
  return any;
}

// Coulomb friction for the step h about to be taken: the absolute formulation's rule
// (Stepper::frictionFor, coulombFriction) with its inputs in joint coordinates. The
// coordinate's rate after the step without friction is q_dot + h q_ddot, q_ddot the free
// accelerations at q0 (s.qddot; in joint coordinates the coordinate's own velocity term,
// the absolute formulation's -gamma, is in q_ddot itself). Its effective inertia's inverse
// is q_x,k P q_x,l^T = (P e_k)_l, P the constrained inverse mass in joint coordinates: M^-1
// from the articulated factors at q0 (ws_), less M^-1 G^T (G M^-1 G^T)^+ G M^-1 with the
// closures (their factorization at q0: stage 1 ran there), as JointDamping::classify's.
void JointStepper::frictionFor(const System& sys, State& s, double h) {
  bool mass = false;  // the joint-space inertia factored at q0 (once)
  for (const TreeLink& L : model_.links) {
    if (L.joint < 0) continue;
    const std::array<double, 3>& f = sys.friction[L.joint];
    if (!(f[0] > 0.0 || f[1] > 0.0 || f[2] > 0.0)) continue;
    double rate[3] = {0, 0, 0}, gPg[3][3] = {{0}};
    for (int k = 0; k < L.nv; ++k) {
      if (!(f[k] > 0.0)) continue;
      rate[k] = s.qdot(L.iv + k) / h + s.qddot(L.iv + k);
      friction_.y.setZero();
      friction_.y(L.iv + k) = 1.0;
      constrainedInverseMass(friction_.y, mass);
      for (int l = 0; l < L.nv; ++l)
        if (f[l] > 0.0) gPg[l][k] = friction_.y(L.iv + l);
    }
    coulombFriction(f, L.ptr->planarTranslation(), rate, gPg, s.friction[L.joint]);
  }
  // friction on sums of coordinates: the same rule on the row g = sum_i c_i e_i, its rate
  // sum_i c_i (q_dot_i / h + q_ddot_i) and inverse effective inertia g P g^T
  for (size_t r = 0; r < sys.sum_friction.size(); ++r) {
    const SumFriction& F = sys.sum_friction[r];
    if (!(F.f > 0.0)) continue;
    double rate[3] = {0, 0, 0}, gPg[3][3] = {{0}};
    friction_.y.setZero();
    for (const LimitTerm& t : F.terms) {
      const int iv = model_.links[model_.joint_link[t.joint]].iv + t.k;
      rate[0] += t.c * (s.qdot(iv) / h + s.qddot(iv));
      friction_.y(iv) += t.c;
    }
    constrainedInverseMass(friction_.y, mass);
    for (const LimitTerm& t : F.terms) gPg[0][0] += t.c * friction_.y(model_.links[model_.joint_link[t.joint]].iv + t.k);
    std::array<double, 3> out;
    coulombFriction({F.f, 0.0, 0.0}, false, rate, gPg, out);
    s.sum_friction[r] = out[0];
  }
}

void JointStepper::constrainedInverseMass(Eigen::VectorXd& y, bool& mass) {
  // (with ties the articulated passes: the factored joint-space inertia is the tree's
  // without them)
  const bool ties = !model_.ties.empty();
  if (!mass && !ties) closures_.factorMass(model_, ws_), mass = true;
  if (ties) closures_.applyInverseMass(model_, ws_, y.data(), y.data());
  else closures_.inverseMass(y.data());
  if (closures_.m == 0) return;
  closures_.timesG(y, friction_.r);
  closures_.solve(friction_.r, friction_.mu);
  if (ties) {
    const int m = closures_.m;
    friction_.e.noalias() = closures_.G.topRows(m).transpose() * friction_.mu.head(m);
    closures_.applyInverseMass(model_, ws_, friction_.e.data(), friction_.e.data());
  } else {
    closures_.inverseMassGT(friction_.mu, friction_.e);
  }
  y -= friction_.e;
}

int JointStepper::stateCoordinate(const State& s, int joint, bool rate) const {
  if (s.q.size() == 0) return -1;
  const int link = model_.joint_link[joint];
  if (link < 0) return -1;
  const TreeLink& L = model_.links[link];
  if (L.quaternion >= 0) return -1;
  return rate ? L.iv : L.iq;
}

bool JointStepper::reactionMultipliers(const System& sys, const State& s, const Inputs& in,
                                       std::unique_ptr<TreeReactionWorkspace>& scratch, Eigen::VectorXd& lambda,
                                       const Evaluation** with) const {
  if (!scratch) scratch = std::make_unique<TreeReactionWorkspace>(sys);
  lambda = s.lambda;
  treeJointMultipliers(sys, model_, s, in, *scratch, lambda);
  *with = &scratch->ev;  // (every row's Jacobian, none dropped)
  return true;
}

}  // namespace mechanism_sim
