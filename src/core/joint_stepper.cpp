// The joint-space formulation's stepper (joint_stepper.h).
#include "mechanism_sim/core/joint_stepper.h"

#include <cmath>
#include <sstream>

#include "mechanism_sim/core/evaluation.h"
#include "mechanism_sim/core/projection.h"

namespace mechanism_sim {
namespace {
constexpr int kMaxVelocityPasses = 8;  // (as the absolute formulation's velocity projection)
}  // namespace

std::string jointFormulationUnsupported(const System& sys) {
  // Couplers, drives and limits are closures on the tree (loop_closure.h); Coulomb
  // friction is not (jointSpaceUnsupported says so).
  std::string why = jointSpaceUnsupported(sys, true);
  if (!why.empty()) return why;
  // Loop closures (the spanning tree's cut joints) are not released: integrated, the
  // parallelogram four-bar was 1.7e-12 m from exact at 1 ms but 4e-3 m at 0.1 ms. Not the
  // closures' rank threshold (1e-10 to 1e-15 gave the same figures): near its flat passage,
  // where two branches cross, the equations determine the tangent only to eps / x^2 at a
  // distance x, and stages of smaller steps land closer (doc/limitations.md).
  const TreeModel tree(sys);
  if (!tree.cut_joints.empty())
    return "joint '" + sys.joints[tree.cut_joints[0]]->name() +
           "' closes a loop: the joint formulation does not integrate loop closures yet";
  // Viscous joint damping can be too stiff for explicit stages (a light link on a damped
  // joint): the absolute formulation integrates such coordinates implicitly
  // (stiff_damping.cpp); the joint formulation does not yet.
  for (int j = 0; j < sys.numJoints(); ++j)
    for (int k = 0; k < sys.joints[j]->dof(); ++k)
      if (sys.damping[j][k] != 0.0)
        return "joint '" + sys.joints[j]->name() + "': the joint formulation has no implicit joint damping yet";
  return why;
}

Formulation chooseFormulation(const System& sys, Formulation asked, std::string* why) {
  if (asked == Formulation::kAbsolute) {
    if (why) *why = "absolute coordinates, as asked";
    return Formulation::kAbsolute;
  }
  const std::string unsupported = jointFormulationUnsupported(sys);
  if (asked == Formulation::kJoint) {
    if (!unsupported.empty()) throw ModelError("the joint formulation cannot run this mechanism: " + unsupported);
    if (why) *why = "joint coordinates, as asked";
    return Formulation::kJoint;
  }
  // The cost model (bench/RESULTS.md). On a tree with no equations besides its joints'
  // the joint formulation costs 3 to 5 times less a step (pendulum 0.84 against 3.41 us,
  // the 50-link chain 68 against 203). A free limit costs it nothing (a zero row, not
  // evaluated); each equation that is always on (a coupler, a drive) costs an O(n)
  // inverse-mass pass a stage and a dense solve: with one coupler on 9 coordinates (the
  // panda of ../shared/robots) it was still the faster (real-time factor 19.9 against
  // 18.5), with 34 on 42 (nao) it was not (1.6 against 2.9). auto takes joint coordinates
  // while such equations are at most one per 8 coordinates.
  int always_on = 0;
  {
    std::vector<char> tree_joint(sys.numConstraints(), 0);
    for (int c : sys.joint_constraint) tree_joint[c] = 1;
    for (int c = 0; c < sys.numConstraints(); ++c)
      if (!tree_joint[c] && sys.constraints[c]->limit() < 0) always_on += sys.constraints[c]->size();
  }
  int nv = 0;
  if (unsupported.empty()) nv = TreeModel(sys).nv;
  if (unsupported.empty() && 8 * always_on <= nv) {
    if (why)
      *why = always_on == 0 ? "joint coordinates (auto: a tree whose other equations are limits at most, O(n) a stage)"
                            : "joint coordinates (auto: a tree with few couplers or drives, at most one per 8 coordinates)";
    return Formulation::kJoint;
  }
  if (unsupported.empty()) {
    if (why)
      *why = "absolute coordinates (auto: more than one coupler or drive per 8 coordinates cost more as joint-space "
             "closures today)";
    return Formulation::kAbsolute;
  }
  if (why) *why = "absolute coordinates (auto: " + unsupported + ")";
  return Formulation::kAbsolute;
}

JointStepper::JointStepper(const System& sys) : model_(sys), ws_(model_), closures_(model_, sys) {
  const std::string unsupported = jointFormulationUnsupported(sys);
  if (!unsupported.empty()) throw ModelError("the joint formulation cannot run this mechanism: " + unsupported);
  tableau_ = &tableau(parseMethod(sys.options.method));
  auto zeros = [](Eigen::VectorXd& v, int n) { v = Eigen::VectorXd::Zero(n); };
  zeros(tau_, model_.nv), zeros(q0_, model_.nq), zeros(v0_, model_.nv), zeros(qs_, model_.nq), zeros(vs_, model_.nv);
  for (int k = 0; k < Tableau::kMaxStages; ++k) zeros(kq_[k], model_.nq), zeros(kv_[k], model_.nv);
  zeros(sum_q_, model_.nq), zeros(sum_v_, model_.nv);
  loads_ = zeroInputs(sys);
  kin_.assign(sys.bodies.size(), BodyKin());
}

void JointStepper::accelerations(const System& sys, const State& s, const Inputs& in, double t,
                                 const Eigen::VectorXd& q, const Eigen::VectorXd& qdot, Eigen::VectorXd& qddot) {
  jointEfforts(model_, in, tau_);  // efforts along the joint coordinates
  const Inputs* loads = &in;
  if (!sys.springs.empty()) {
    // springs act between points of bodies: body loads at the tree's poses (appliedForces)
    forwardKinematics(model_, q, qdot, ws_);
    absoluteState(model_, ws_, spring_x_, spring_u_);
    loadKinematics(sys, spring_x_.data(), spring_u_.data(), kin_);
    loads_.force = in.force;
    loads_.torque = in.torque;
    for (size_t i = 0; i < sys.springs.size(); ++i) {
      const SpringDamper& sd = sys.springs[i];
      const Gap g = gap(kin_[sd.body_i], sd.sp_i, kin_[sd.body_j], sd.sp_j);
      const double L = g.d.norm();
      if (!(L > 1e-12 * sys.length_scale)) continue;  // direction undefined; no force
      const Vector3d e = g.d / L;
      const double F = sd.k * (L - sd.L0) + sd.c * e.dot(g.d_dot) + sd.f_act + in.spring_actuation[i];
      auto addForceAt = [&](int b, const Vector3d& sp, const Vector3d& f) {
        if (b == System::kGround) return;
        loads_.force[b] += f;
        loads_.torque[b] += sp.cross(kin_[b].A_Oi.transpose() * f);
      };
      addForceAt(sd.body_i, sd.sp_i, F * e);
      addForceAt(sd.body_j, sd.sp_j, -F * e);
    }
    loads = &loads_;
  }
  if (closures_.m == 0) {
    forwardDynamics(model_, sys, q, qdot, tau_, ws_, qddot, loads);
    return;
  }
  // the closures (drives, limits, couplers) read the State's context at the stage's time
  EvalContext ctx = s.context();
  ctx.t = t;
  closures_.setContext(ctx);
  constrainedForwardDynamics(model_, sys, closures_, q, qdot, tau_, ws_, qddot, loads);
}

void JointStepper::writeAbsolute(const System& sys, State& s) {
  // (ws_ holds the kinematics of s.q, s.qdot: accelerations() ran there last)
  absoluteState(model_, ws_, s.x, s.u);
  // the closures' multipliers (drives, limits, couplers) in their System rows; a free
  // limit's is 0. The tree joints' rows have none: Mechanism::multipliers() gives the
  // least-norm ones for reactions.
  if (closures_.m > 0) {
    closures_.systemMultipliers(s.lambda);
    for (size_t l = 0; l < sys.limits.size(); ++l)
      if (s.limit_side[l] == 0) s.lambda[sys.layout[sys.limits[l].constraint].row] = 0.0;
  }
  bodyAccelerations(model_, ws_, s.qddot, s.acc);
  // Tracked angles: a tree joint's are its coordinates themselves (so an angle may advance
  // by any amount in a step: a wheel at 4000 rad/s turns 4 rad a millisecond). Every
  // constraint of a System this stepper runs is a tree joint (jointFormulationUnsupported).
  for (const TreeLink& L : model_.links) {
    if (L.joint < 0 || L.kind == TreeJointKind::kSpherical) continue;
    for (int k = 0; k < L.ptr->dof(); ++k) {
      const int slot = L.ptr->trackedSlot(k);
      if (slot >= 0) s.tracked[L.ptr->id()][slot] = s.q[L.iq + k];
    }
  }
  q_end_ = s.q;
  v_end_ = s.qdot;
  fresh_ = true;
}

// After the stages (or at a new state): limits that were passed become active (an
// inelastic stop: the projections bring the coordinate to its bound and its rate to 0),
// positions and velocities are projected onto the closures, the accelerations solved, and
// limits that would pull let go (solved again), as the absolute formulation's finishStep.
void JointStepper::finish(const System& sys, State& s, const Inputs& in) {
  if (closures_.m > 0) {
    closures_.setContext(s.context());
    forwardKinematics(model_, s.q, s.qdot, ws_);
    if (!sys.limits.empty() && closures_.activateReachedLimits(sys, ws_, s.limit_side.data()) > 0)
      for (size_t l = 0; l < sys.limits.size(); ++l)
        if (s.limit_side[l] != 0)
          for (const DriveSpec& D : sys.drives)
            if (D.joint == sys.limits[l].joint && D.k == sys.limits[l].k) {
              std::ostringstream os;
              os << "at t = " << s.t << " s: the drive of joint '" << sys.joints[D.joint]->name()
                 << "' moves it past its limits [" << fmt(sys.limits[l].lower) << ", " << fmt(sys.limits[l].upper)
                 << "]; change the drive or the limits";
              throw SimulationError(os.str());
            }
    project(sys, s);
  }
  accelerations(sys, s, in, s.t, s.q, s.qdot, s.qddot);
  for (size_t pass = 0; pass < sys.limits.size() && closures_.releasePullingLimits(sys, s.limit_side.data()) > 0;
       ++pass)
    accelerations(sys, s, in, s.t, s.q, s.qdot, s.qddot);
  writeAbsolute(sys, s);
}

// Positions and velocities onto the closures (loop_closure.h), to the System's relative
// tolerances; a shortfall is counted, beyond kFailureResidual the step fails.
void JointStepper::project(const System& sys, State& s) {
  closures_.setContext(s.context());
  const ClosureProjectionReport p = projectClosurePositions(model_, sys, closures_, s.q, ws_, sys.options.position_tol);
  ++stats_.position_projections;
  if (!p.converged) {
    ++stats_.position_shortfalls;
    stats_.worst_position = std::max(stats_.worst_position, p.residual);
    if (p.residual > kFailureResidual) {
      std::ostringstream os;
      os << "at t = " << s.t << " s: the step left the constraints on the joint coordinates (relative residual "
         << fmt(p.residual) << "); try a smaller step";
      throw StepFailure(os.str());
    }
  }
  const ClosureProjectionReport v =
      projectClosureVelocities(model_, sys, closures_, s.q, s.qdot, ws_, sys.options.velocity_tol, kMaxVelocityPasses);
  ++stats_.velocity_projections;
  if (!v.converged) {
    ++stats_.velocity_shortfalls;
    stats_.worst_velocity = std::max(stats_.worst_velocity, v.residual);
    if (v.residual > kFailureResidual) {
      std::ostringstream os;
      os << "at t = " << s.t << " s: the velocities cannot be brought onto the constraints (relative residual "
         << fmt(v.residual) << ")";
      throw StepFailure(os.str());
    }
  }
}

void JointStepper::settle(const System& sys, State& s, const Inputs& in) {
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
    if (L.kind == TreeJointKind::kSpherical) {
      const Matrix3d Ri = kin_[J.bodyI()].A_Oi * J.frameI().Rp, Rj = kin_[J.bodyJ()].A_Oi * J.frameJ().Rp;
      const Quaterniond p(Ri.transpose() * Rj);
      s.q.segment<4>(L.iq) << p.w(), p.x(), p.y(), p.z();
    } else {
      for (int k = 0; k < J.dof(); ++k) s.q[L.iq + k] = rows[k].Phi;
    }
  }
  normalizeQuaternions(model_, s.q);
  finish(sys, s, in);
}

void JointStepper::step(const System& sys, State& s, const Inputs& in, double h) {
  if (!(h > 0) || !std::isfinite(h)) throw UsageError("step must be positive and finite");
  if (s.q.size() != model_.nq || s.qdot.size() != model_.nv)
    throw UsageError("JointStepper::step: the State has no joint state (settle() first)");
  const Tableau& T = *tableau_;
  q0_ = s.q;
  v0_ = s.qdot;
  // stage 1: the accelerations the last step (or settle) left, when they are of this state
  // under these inputs; else computed here
  if (!(fresh_ && q_end_ == s.q && v_end_ == s.qdot)) accelerations(sys, s, in, s.t, q0_, v0_, s.qddot);
  positionRates(model_, q0_, v0_, kq_[0]);
  kv_[0] = s.qddot;
  for (int k = 1; k < T.stages; ++k) {
    combineStages(h, T.a[k], k, T.a_den[k], q0_, kq_, sum_q_, qs_);
    combineStages(h, T.a[k], k, T.a_den[k], v0_, kv_, sum_v_, vs_);
    accelerations(sys, s, in, s.t + T.c[k] * h, qs_, vs_, kv_[k]);
    positionRates(model_, qs_, vs_, kq_[k]);
  }
  combineStages(h, T.b, T.stages, T.b_den, q0_, kq_, sum_q_, s.q);
  combineStages(h, T.b, T.stages, T.b_den, v0_, kv_, sum_v_, s.qdot);
  normalizeQuaternions(model_, s.q);
  const double t0 = s.t;
  s.t += h;
  ++s.steps;
  limit_side0_ = s.limit_side;
  try {
    finish(sys, s, in);
  } catch (...) {  // the State as it was (the last accepted step)
    s.t = t0, --s.steps;
    s.q = q0_, s.qdot = v0_;
    s.limit_side = limit_side0_;
    fresh_ = false;
    throw;
  }
  stats_.solves += T.stages;
}

}  // namespace mechanism_sim
