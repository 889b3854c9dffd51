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
    : model_(sys, embed_couplers), ws_(model_), closures_(model_, sys) {
  const std::string unsupported = jointFormulationUnsupported(sys);
  if (!unsupported.empty()) throw ModelError("the joint formulation cannot run this mechanism: " + unsupported);
  tableau_ = &tableau(parseMethod(sys.options.method));
  auto zeros = [](Eigen::VectorXd& v, int n) { v = Eigen::VectorXd::Zero(n); };
  zeros(tau_, model_.nv), zeros(q0_, model_.nq), zeros(v0_, model_.nv), zeros(qs_, model_.nq), zeros(vs_, model_.nv);
  for (int k = 0; k < Tableau::kMaxStages; ++k) zeros(kq_[k], model_.nq), zeros(kv_[k], model_.nv);
  zeros(sum_q_, model_.nq), zeros(sum_v_, model_.nv);
  zeros(comp_q_, model_.nq), zeros(comp_v_, model_.nv);
  zeros(acc_k4_, 6 * sys.nb);
  backup_.assign(numerics::kMaxHalvings + 1, State());
  loads_ = zeroInputs(sys);
  kin_.assign(sys.bodies.size(), BodyKin());
  setDamping(sys);
  fric_e_.setZero(model_.nv), fric_y_.setZero(model_.nv);
  for (int j : model_.cut_joints) cut_constraints_.push_back(sys.joint_constraint[j]);
  closures_.form_Y = false;  // (only implicitDamping reads M^-1 G^T whole)
}

void JointStepper::setDamping(const System& sys) {
  closures_.rebind(sys);  // (a Mechanism's System is copied on write)
  damped_.clear();
  cut_damped_.clear();
  for (const TreeLink& L : model_.links) {
    if (L.joint < 0) continue;
    for (int k = 0; k < L.nv; ++k)
      if (sys.damping[L.joint][k] > 0.0) damped_.push_back({L.joint, k, L.iv + k, sys.damping[L.joint][k], L.kind == TreeJointKind::kRevolute});
  }
  for (int j : model_.cut_joints)
    for (int k = 0; k < sys.joints[j]->dof(); ++k)
      if (sys.damping[j][k] > 0.0 && (cut_damped_.empty() || cut_damped_.back() != j)) cut_damped_.push_back(j);
  const int nd = static_cast<int>(damped_.size());
  link_of_v_.assign(model_.nv, 0);
  for (int k = 0; k < model_.nb; ++k)
    for (int i = 0; i < model_.links[k].nv; ++i) link_of_v_[model_.links[k].iv + i] = k;
  damp_index_of_v_.assign(model_.nv, -1);
  damp_path_.assign(nd, {});
  damp_path_v_.assign(nd, {});
  for (int i = 0; i < nd; ++i) {
    damp_index_of_v_[damped_[i].iv] = i;
    // (a master's coordinate eliminated at a common ancestor, TreeLink::pivot, is listed
    // there, not at the master's own link: every path through that ancestor has it in the
    // same place, so the shared coordinates below stay each path's tail)
    for (int k = link_of_v_[damped_[i].iv];; k = model_.links[k].parent - 1) {
      const TreeLink& L = model_.links[k];
      damp_path_[i].push_back(k);
      if (L.pivot >= 0) damp_path_v_[i].push_back(L.pivot);
      if (!(L.tie >= 0 && L.iv == model_.links[L.tie].iv))
        for (int v = 0; v < L.nv; ++v) damp_path_v_[i].push_back(L.iv + v);
      if (L.parent == 0) break;
    }
  }
  // the coordinates two paths share are their common ancestors', the tail of each path
  damp_shared_.clear();
  damp_shared_first_.assign(nd + 1, 0);
  for (int k = 0; k < nd; ++k) {
    damp_shared_first_[k] = static_cast<int>(damp_shared_.size());
    for (int l = 0; l < nd; ++l) {
      const std::vector<int>& pl = damp_path_v_[l];
      const std::vector<int>& pk = damp_path_v_[k];
      int from = static_cast<int>(pl.size());
      while (from > 0 && std::find(pk.begin(), pk.end(), pl[from - 1]) != pk.end()) --from;
      if (from < static_cast<int>(pl.size())) damp_shared_.push_back({l, from});
    }
  }
  damp_shared_first_[nd] = static_cast<int>(damp_shared_.size());
  damp_Zd_.setZero(model_.nv, nd), damp_Xd_.setZero(model_.nv, nd);  // (zero off each path, always)
  damp_Minv_.setZero(nd, nd);
  damp_Yd_.setZero(nd, closures_.m), damp_W_.setZero(nd, closures_.m);
  damp_W_lo_.assign(closures_.m, 0), damp_W_hi_.assign(closures_.m, 0);
  damp_used_.reserve(closures_.m);
  damp_x_.setZero(model_.nv);
  damp_col_.setZero(nd);
  damp_rc_.resize(nd);
  for (int i = 0; i < nd; ++i) damp_rc_(i) = std::sqrt(damped_[i].c);
  damp_filter_.assign(nd, 0.0);
  damp_rcb_.assign(nd, 0.0);
  body_inverse_.clear();  // (classifyDamping's bound: the bodies' inverses once)
  for (const Body& B : sys.bodies) body_inverse_.push_back(bodyInverse(B));
  damp_p_.assign(model_.nb, Vector6d::Zero());
  damp_mark_.assign(model_.nb, 0);
  damp_links_.reserve(model_.nb);
  damp_touched_.assign(nd, 0);
  damp_column_of_.assign(nd, -1);
  damp_direct_.assign(closures_.m, 0);
  damp_nz_.reserve(static_cast<size_t>(closures_.m) * model_.nv);
  damp_nz_first_.assign(closures_.m + 1, 0);
  damp_candidates_.reserve(nd);
  damp_need_.reserve(nd);
  stiff_.assign(nd, 0);
  stiff_list_.reserve(nd);
  damp_Y_.setZero(model_.nv, nd);
  damp_K_.setZero(nd, nd);
  damp_e_.setZero(model_.nv), damp_z_.setZero(nd), damp_du_.setZero(model_.nv);
  damp_zero_.setZero(model_.nv), damp_qdd_.setZero(model_.nv), damp_tau_.setZero(model_.nv);
  damp_v_.assign(model_.nb, Vector6d::Zero());
  damp_w_.setZero(nd), damp_c_.setZero(model_.nv);
  damp_Z_.setZero(model_.nv, closures_.m), damp_AW_.setZero(closures_.m, closures_.m);
  damp_r_.setZero(closures_.m), damp_mu_.setZero(closures_.m);
  damp_least_norm_ = ScaledLeastNorm(closures_.m);
  damp_f_.assign(model_.nb, Vector6d::Zero());
  damp_rows_.assign(kMaxJointDofs, Row());
  fresh_ = false;
}

void JointStepper::accelerations(const System& sys, const State& s, const Inputs& in, double t,
                                 const Eigen::VectorXd& q, const Eigen::VectorXd& qdot, Eigen::VectorXd& qddot,
                                 bool evaluated) {
  jointEfforts(model_, in, tau_);  // efforts along the joint coordinates
  // Damping, per coordinate of q_dot: a spherical joint's are the relative angular velocity
  // in frame i, Joint::coordinates' rates (settle() reads q_dot from them), so tau_k =
  // -c_k q_dot_k is the absolute formulation's q_x,k^T (-c_k q_x,k u) (appliedForces): one power,
  // tau . q_dot = (G^T tau) . u, on the tree's coordinates and the bodies' alike.
  for (size_t i = 0; i < damped_.size(); ++i)  // damping that is not stiff: an effort
    if (!stiff_[i]) tau_(damped_[i].iv) -= damped_[i].c * qdot(damped_[i].iv);
  // Coulomb friction: the step's efforts (frictionFor), held over its stages
  for (const TreeLink& L : model_.links)
    if (L.joint >= 0)
      for (int k = 0; k < L.nv; ++k) tau_(L.iv + k) += s.friction[L.joint][k];
  const Inputs* loads = &in;
  if (!sys.springs.empty() || !cut_damped_.empty()) {
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
    for (int j : cut_damped_) {
      const Joint& J = *sys.joints[j];
      Row rows[kMaxJointDofs];
      J.coordinates(kin_[J.bodyI()], kin_[J.bodyJ()], s.tracked[J.id()], rows);
      for (int k = 0; k < J.dof(); ++k) loads_.effort[j][k] -= sys.damping[j][k] * rows[k].Phi_dot;
    }
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
  constrainedForwardDynamics(model_, sys, closures_, q, qdot, tau_, ws_, qddot, loads, evaluated);
}

void JointStepper::writeAbsolute(const System& sys, State& s) {
  // (ws_ holds the kinematics of s.q, s.qdot: accelerations() ran there last)
  absoluteState(model_, ws_, s.x, s.u);
  // the closures' multipliers (drives, limits, couplers) in their System rows; a free
  // limit's is 0. The tree joints' rows have none: a reactions query computes them
  // (Mechanism::multipliers(), treeJointMultipliers: tree_reactions.h).
  // (a coupler the tree holds has no multiplier of the solve: the reactions query gives it,
  // treeJointMultipliers)
  for (int k : model_.ties) s.lambda[sys.layout[model_.links[k].tie_coupler].row] = 0.0;
  if (closures_.m > 0) {
    closures_.systemMultipliers(s.lambda);
    for (size_t l = 0; l < sys.limits.size(); ++l)
      if (s.limit_side[l] == 0) s.lambda[sys.layout[sys.limits[l].constraint].row] = 0.0;
  }
  bodyAccelerations(model_, ws_, s.qddot, s.acc);
  // Tracked angles: a tree joint's are its coordinates themselves (so an angle may advance
  // by any amount in a step: a wheel at 4000 rad/s turns 4 rad a millisecond). A cut
  // joint's follow its two bodies (Constraint::track at the new kinematics, as the absolute
  // formulation tracks every joint), below. The other constraints (couplers, drives,
  // limits) keep none of their own: they read their joints'.
  for (const TreeLink& L : model_.links) {
    if (L.joint < 0 || L.kind == TreeJointKind::kSpherical) continue;
    for (int k = 0; k < L.ptr->dof(); ++k) {
      const int slot = L.ptr->trackedSlot(k);
      if (slot >= 0) s.tracked[L.ptr->id()][slot] = s.q[L.iq + k];
    }
  }
  if (!cut_constraints_.empty()) {
    closures_.setContext(s.context());
    closures_.track(ws_, cut_constraints_, s.tracked);
  }
  // the closures' violations at this state (stepViolation()): |Phi| and |G q_dot - nu|
  // of their rows, evaluated at (s.q, s.qdot) by the accelerations above
  end_violation_ = {0.0, 0.0};
  if (closures_.m > 0) {
    end_violation_[0] = closures_.Phi.head(closures_.m).cwiseAbs().maxCoeff();
    if (end_rate_.size() != closures_.G.rows()) end_rate_.setZero(closures_.G.rows());
    closures_.timesG(s.qdot, end_rate_);
    end_violation_[1] = (end_rate_.head(closures_.m) - closures_.nu.head(closures_.m)).cwiseAbs().maxCoeff();
  }
  q_end_ = s.q;
  v_end_ = s.qdot;
  fresh_ = true;
}

bool JointStepper::stepViolation(const State& s, double& position, double& velocity) const {
  if (!fresh_ || q_end_.size() != s.q.size() || v_end_.size() != s.qdot.size() || q_end_ != s.q || v_end_ != s.qdot)
    return false;
  position = end_violation_[0], velocity = end_violation_[1];
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
  for (size_t pass = 0; pass < sys.limits.size() && closures_.releasePullingLimits(sys, s.limit_side.data()) > 0;
       ++pass)
    accelerations(sys, s, in, s.t, s.q, s.qdot, s.qddot);
  if (!model_.cut_joints.empty()) s.qddot_ref = a_ref_;
  writeAbsolute(sys, s);
}

// Positions and velocities onto the closures (loop_closure.h), to the System's relative
// tolerances; a shortfall is counted, beyond kFailureResidual the step fails.
bool JointStepper::project(const System& sys, State& s) {
  closures_.setContext(s.context());
  // (kinematics at s.qdot: the equations do not read the rates, the accelerations after do)
  const ClosureProjectionReport p =
      projectClosurePositions(model_, sys, closures_, s.q, ws_, sys.options.position_tol, 20, &s.qdot);
  stats_.countPositionProjection(p.converged, p.residual);
  if (!p.converged && p.residual > failureResidual(sys)) {
    std::ostringstream os;
    os << "the step left the constraints on the joint coordinates (relative residual "
       << fmt(p.residual) << "); try a smaller step";
    throw StepFailure(os.str());
  }
  const ClosureProjectionReport v =
      projectClosureVelocities(model_, sys, closures_, s.q, s.qdot, ws_, sys.options.velocity_tol, kMaxVelocityPasses,
                               true, p.at_rates);  // (ws_ and closures_ at s.q: the position projection's last evaluation)
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
  // (a new state: no round-off of a step to carry)
  s.q_round.setZero(model_.nq), s.qdot_round.setZero(model_.nv);
  s.damping_hold.left = 0;
  // A settled state has no motion before it: the closures' decomposition applies
  // (branch_passage.cpp: dependent rows dropped by geometry) but nothing is held by the motion.
  if (!model_.cut_joints.empty()) {
    a_ref_ = Eigen::VectorXd::Zero(model_.nv);
    closures_.passage_ref = &a_ref_;
    closures_.passage_hold = false;
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
    if (L.kind == TreeJointKind::kSpherical) {
      const Matrix3d Ri = kin_[J.bodyI()].A_Oi * J.frameI().Rp, Rj = kin_[J.bodyJ()].A_Oi * J.frameJ().Rp;
      const Quaterniond p(Ri.transpose() * Rj);
      s.q.segment<4>(L.iq) << p.w(), p.x(), p.y(), p.z();
    } else {
      for (int k = 0; k < J.dof(); ++k) s.q[L.iq + k] = rows[k].Phi;
    }
  }
  normalizeQuaternions(model_, s.q);
  try {
    finish(sys, s, in);
  } catch (...) {
    closures_.passage_hold = true;
    throw;
  }
  closures_.passage_hold = true;
  // (a stage 1 computed again at this state holds what these accelerations have)
  if (!model_.cut_joints.empty()) s.qddot_ref = s.qddot;
  // the copies a step keeps (advance) sized now: a step allocates nothing
  start_ = s;
  for (State& b : backup_) b = s;
}

namespace {

// y = y0 + (w sum + c0) split into y (rounded) and its round-off c, carried to the next
// step (Knuth's TwoSum: exact in binary floating point without a test of magnitudes).
void compensatedUpdate(double w, const Eigen::VectorXd& y0, const Eigen::VectorXd& sum, const Eigen::VectorXd& c0,
                       Eigen::VectorXd& c, Eigen::VectorXd& y) {
  for (Eigen::Index i = 0; i < y.size(); ++i) {
    const double d = w * sum(i) + c0(i);
    const double t = y0(i) + d;
    const double dd = t - y0(i);
    c(i) = (y0(i) - (t - dd)) + (d - dd);
    y(i) = t;
  }
}

}  // namespace

void JointStepper::step(const System& sys, State& s, const Inputs& in, double h) {
  closures_.rebind(sys);  // (a Mechanism's System is copied on write)
  if (!(h > 0) || !std::isfinite(h)) throw UsageError("step must be positive and finite");
  adopt(sys, s, in);
  if (s.q.size() != model_.nq || s.qdot.size() != model_.nv)
    throw UsageError("JointStepper::step: the State's joint state is of another mechanism");
  // A step that fails leaves the State where it was (the last accepted step), not part
  // way through its substeps: stepOnce keeps what it changes (restoreStart), and the whole
  // State is copied only when the step is taken as halves.
  judged_ = tableau_->stages == 4 && damped_.empty() && cut_damped_.empty();
  start_valid_ = false;
  try {
    advance(sys, s, in, h, 0);
  } catch (...) {
    if (start_valid_) s = start_;
    fresh_ = false;
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
  if (depth > 0) backup_[depth] = s;
  const double scale0 = judged_ ? motionScale(sys, s.u) : 0.0;  // (the start's, for leapt)
  try {
    stepOnce(sys, s, in, h);
  } catch (const StepFailure& e) {  // (s is at the step's start)
    if (depth >= numerics::kMaxHalvings) {
      std::ostringstream os;
      os << e.what() << " (" << (1 << depth) << " substeps of " << fmt(h) << " s did not hold it either)";
      throw StepFailure(os.str());
    }
    if (depth == 0) start_ = s, start_valid_ = true;
    halve(sys, s, in, h, depth, depth > 0 ? backup_[depth] : start_);
    return;
  }
  if (depth >= numerics::kMaxHalvings || !leapt(sys, s, h, scale0)) return;
  if (depth == 0) {
    restoreStart(s);
    start_ = s, start_valid_ = true;
  }
  halve(sys, s, in, h, depth, depth > 0 ? backup_[depth] : start_);
}

void JointStepper::halve(const System& sys, State& s, const Inputs& in, double h, int depth, const State& before) {
  s = before;
  fresh_ = false;
  ++stats_.halved_steps;
  advance(sys, s, in, 0.5 * h, depth + 1);
  advance(sys, s, in, 0.5 * h, depth + 1);
}

bool JointStepper::leapt(const System& sys, const State& s, double h, double scale0) {
  if (!judged_ || s.limit_side != limit_side0_) return false;
  // (ws_ holds the end state's kinematics: finish() solved its accelerations there)
  bodyAccelerations(model_, ws_, kv_[3], acc_k4_);
  const double L = sys.length_scale;
  double error = 0;
  for (int b = 0; b < sys.nb; ++b) {
    const int i = BodyCoordinates::u(b);
    error = std::max({error, (acc_k4_.segment<3>(i) - s.acc.segment<3>(i)).norm(),
                      (acc_k4_.segment<3>(i + 3) - s.acc.segment<3>(i + 3)).norm() * L});
  }
  error *= h / 6.0;
  const double scale = std::max({scale0, motionScale(sys, s.u), sys.velocity_scale});
  return error > numerics::kMaxStepError * scale;
}

void JointStepper::stepOnce(const System& sys, State& s, const Inputs& in, double h) {
  const Tableau& T = *tableau_;
  q0_ = s.q;
  v0_ = s.qdot;
  // branch passages (branch_passage.cpp): a stage 1 computed again below holds what the
  // State's own accelerations held (so a restored State steps as the run it came from)
  if (!model_.cut_joints.empty()) {
    a_ref_ = s.qddot_ref.size() == model_.nv ? s.qddot_ref : s.qddot;
    closures_.passage_ref = &a_ref_;
  }
  friction0_ = s.friction;
  if (!model_.cut_joints.empty()) qddot_ref0_ = s.qddot_ref;
  // stage 1: the accelerations the last step (or settle) left, when they are of this state
  // under these inputs; else computed here (with friction: without it, frictionFor's)
  const bool friction = clearFriction(sys, s);
  if (friction || !(fresh_ && q_end_ == s.q && v_end_ == s.qdot)) accelerations(sys, s, in, s.t, q0_, v0_, s.qddot);
  // (ws_ holds q0's articulated factors now); stage 1 again if the stiff set changed
  if (!damped_.empty() && classifyDamping(sys, s, h)) accelerations(sys, s, in, s.t, q0_, v0_, s.qddot);
  // Coulomb friction sized for this step from those (as the absolute formulation: after the
  // stiff set, so the stages' damping is in q_ddot), then stage 1 with it
  if (friction) {
    frictionFor(sys, s, h);
    accelerations(sys, s, in, s.t, q0_, v0_, s.qddot);
  }
  // branch passages of loops (branch_passage.cpp): what the stages hold across a branch is
  // the acceleration at the step's start
  if (!model_.cut_joints.empty()) a_ref_ = s.qddot;
  positionRates(model_, q0_, v0_, kq_[0]);
  kv_[0] = s.qddot;
  // (the later stages need no ordinary closure factorization where a passage's is taken:
  // only friction and damping at the step's start read it)
  closures_.regular_factor = false;
  for (int k = 1; k < T.stages; ++k) {
    combineStages(h, T.a[k], k, T.a_den[k], q0_, kq_, sum_q_, qs_);
    combineStages(h, T.a[k], k, T.a_den[k], v0_, kv_, sum_v_, vs_);
    accelerations(sys, s, in, s.t + T.c[k] * h, qs_, vs_, kv_[k]);
    positionRates(model_, qs_, vs_, kq_[k]);
  }
  closures_.regular_factor = true;
  // The new state, its increments' round-off carried to the next step (compensated
  // summation: Higham, "Accuracy and Stability of Numerical Algorithms", 4.3; Hairer, Lubich
  // & Wanner, "Geometric Numerical Integration", VIII.5). q + h sum b_j k_j rounds to the
  // ulp of q at every step, an error a step that does not shrink with h: over 5 s at 0.1 ms
  // (5e4 steps, crank angles up to 16 rad) it random-walked the four-bars' energy by 1e-14
  // to 1e-13 of itself, which the 5 s error followed (a wheel at 1 rad/s: 1e-11 rad after
  // 1e5 steps of 0.1 ms, 6e-16 carried). The round-off is the State's
  // (q_round, qdot_round: a snapshot carries it; settle() zeroes it); a quaternion's, which
  // normalization rescales, is dropped. (combineStages forms the sums; the update is here.)
  if (s.q_round.size() == model_.nq && s.qdot_round.size() == model_.nv) comp_q_ = s.q_round, comp_v_ = s.qdot_round;
  else comp_q_.setZero(), comp_v_.setZero(), s.q_round.setZero(model_.nq), s.qdot_round.setZero(model_.nv);
  combineStages(h, T.b, T.stages, T.b_den, q0_, kq_, sum_q_, s.q);
  combineStages(h, T.b, T.stages, T.b_den, v0_, kv_, sum_v_, s.qdot);
  compensatedUpdate(h / T.b_den, q0_, sum_q_, comp_q_, s.q_round, s.q);
  compensatedUpdate(h / T.b_den, v0_, sum_v_, comp_v_, s.qdot_round, s.qdot);
  normalizeQuaternions(model_, s.q);
  for (const TreeLink& L : model_.links) {
    if (L.kind == TreeJointKind::kSpherical) s.q_round.segment<4>(L.iq).setZero();
    if (L.kind == TreeJointKind::kFree) s.q_round.segment<4>(L.iq + 3).setZero();
  }
  if (!stiff_list_.empty()) implicitDamping(sys, s, h);
  clock0_ = s.clock();
  s.countStep(h);
  limit_side0_ = s.limit_side;
  try {
    finish(sys, s, in);
  } catch (...) {  // the State as it was (the last accepted step)
    restoreStart(s);
    fresh_ = false;
    throw;
  }
  stats_.solves += T.stages;
}

void JointStepper::restoreStart(State& s) const {
  s.setClock(clock0_);
  s.q = q0_, s.qdot = v0_;
  s.limit_side = limit_side0_;
  s.friction = friction0_;
  s.q_round = comp_q_, s.qdot_round = comp_v_;
  if (!model_.cut_joints.empty()) s.qddot_ref = qddot_ref0_;
}

bool JointStepper::clearFriction(const System& sys, State& s) const {
  bool any = false;
  for (int j = 0; j < sys.numJoints(); ++j) {
    s.friction[j] = {0.0, 0.0, 0.0};
    any = any || sys.friction[j][0] > 0.0 || sys.friction[j][1] > 0.0 || sys.friction[j][2] > 0.0;
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
// closures (their factorization at q0: stage 1 ran there), as classifyDamping's.
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
      // (with ties the articulated passes: the factored joint-space inertia is the tree's
      // without them)
      const bool ties = !model_.ties.empty();
      if (!mass && !ties) closures_.factorMass(model_, ws_), mass = true;
      fric_y_.setZero();
      fric_y_(L.iv + k) = 1.0;
      if (ties) closures_.applyInverseMass(model_, ws_, fric_y_.data(), fric_y_.data());
      else closures_.inverseMass(fric_y_.data());
      if (closures_.m > 0) {
        closures_.timesG(fric_y_, damp_r_);
        closures_.solve(damp_r_, damp_mu_);
        if (ties) {
          const int m = closures_.m;
          fric_e_.noalias() = closures_.G.topRows(m).transpose() * damp_mu_.head(m);
          closures_.applyInverseMass(model_, ws_, fric_e_.data(), fric_e_.data());
        } else {
          closures_.inverseMassGT(damp_mu_, fric_e_);
        }
        fric_y_ -= fric_e_;
      }
      for (int l = 0; l < L.nv; ++l)
        if (f[l] > 0.0) gPg[l][k] = fric_y_(L.iv + l);
    }
    coulombFriction(f, L.ptr->planarTranslation(), rate, gPg, s.friction[L.joint]);
  }
}

BodyInverse bodyInverse(const Body& B) {
  BodyInverse out;
  if (B.m > 0.0) out.inv_m = 1.0 / B.m;
  const Eigen::LLT<Matrix3d> llt(B.Jp);
  if (llt.info() == Eigen::Success && llt.matrixLLT().diagonal().minCoeff() > 0.0) {
    out.inv_J = llt.solve(Matrix3d::Identity());
    out.has_J = true;
  }
  return out;
}

double coordinateInverseMassBound(const Joint& J, const Row& row, const BodyInverse& bi, const BodyInverse& bj) {
  // (M^-1)_kk = 1 / min { x^T M x : x_k = 1 } for M SPD (the minimum is taken at
  // x = M^-1 e_k / (M^-1)_kk). x^T M x is twice the kinetic energy, sum_b u_b^T M_b u_b over
  // the bodies' velocities u = J(q) x (u_b = [v; omega'], M_b = diag(m, J'): the bodies' own
  // masses and central inertias, of which the tree's are composed), and x_k = row u (the
  // coordinate's rate is its row times the bodies' velocities: settle() reads q_dot so). Leaving
  // out every condition on u but row u = 1 (that the joints hold the bodies together, that u
  // comes from joint rates) and the energies of all bodies but the row's two can only lower
  // the minimum:
  //   min { x^T M x : x_k = 1 } >= min { sum_{b = i, j} u_b^T M_b u_b : row u = 1 } = 1 / (row M_b^-1 row^T),
  // so (M^-1)_kk <= row M_b^-1 row^T = sum_b |g_b,r|^2 / m_b + g_b,theta J'_b^-1 g_b,theta^T.
  // (System::Minv is not used: its stand-ins raise every moment, which would make the bound
  // fall short by up to 1e-3.) A body the row moves where it has no mass or no inertia (a
  // massless link) leaves the minimum at 0: no bound.
  double sum = 0.0;
  for (int slot = 0; slot < 2; ++slot) {
    if ((slot == 0 ? J.bodyI() : J.bodyJ()) == System::kGround) continue;
    const BodyInverse& inv = slot == 0 ? bi : bj;
    const Vector3d gr = row.J.segment<3>(6 * slot).transpose(), gt = row.J.segment<3>(6 * slot + 3).transpose();
    if (!gr.isZero(0.0)) sum += gr.squaredNorm() * inv.inv_m;
    if (!gt.isZero(0.0)) {
      if (!inv.has_J) return HUGE_VAL;
      sum += gt.dot(inv.inv_J * gt);
    }
  }
  return std::isfinite(sum) ? sum : HUGE_VAL;
}

double coordinateInverseMassBound(const System& sys, const Joint& J, const Row& row) {
  return coordinateInverseMassBound(J, row, bodyInverse(sys.bodies[J.bodyI()]), bodyInverse(sys.bodies[J.bodyJ()]));
}

// Which damped coordinates are stiff at this step, by stiff_damping.cpp's rule (see there):
// s_k = h sum_l sqrt(c_k c_l) |P_lk| over the damped coordinates l (Gershgorin on
// h C^1/2 P C^1/2, the damped modes' decay rates; P the constrained inverse mass), stiff
// above the tableau's stiff_bound. Three tests, cheapest first:
//  1. An upper bound on every s_k at once, from a bound beta_l >= (M^-1)_ll per damped
//     coordinate (coordinateInverseMassBound; for a revolute joint independent of the
//     configuration, so kept): P is positive semidefinite and P <= M^-1 (the closures'
//     term M^-1 G^T (G M^-1 G^T)^+ G M^-1 is positive semidefinite), so
//        |P_lk| <= sqrt(P_ll P_kk) <= sqrt((M^-1)_ll (M^-1)_kk) <= sqrt(beta_l beta_k),
//        s_k <= h sqrt(c_k beta_k) sum_l sqrt(c_l beta_l) =: u_k.
//     A coordinate with u_k within stiff_bound is not stiff (the heavy links of a 7-dof
//     arm: there nothing more is computed).
//  2. Else the absolute formulation's bound with the joint's own damped coordinates, the
//     rows on their two bodies and System::Minv: a filter, not a bound (it leaves out the
//     other joints' terms), so only where it is below stiff_bound / 4 is the coordinate
//     taken as not stiff (it finds the same stiff coordinates as 3. would).
//  3. Else P_lk itself, at the damped l only (dampedInverseMass: O(depth) an entry, where a
//     column of P costs passes over the tree).
// (1. decides only where 3. would decide the same: u_k >= s_k.)
//
// The set found is held for the next steps (s.damping_hold), as stiff solvers keep their
// Jacobian over steps while it serves (Hairer & Wanner, "Solving ODEs II", IV.8): for at
// most kHoldSteps, while no body has turned by more than kHoldMotion rad or moved by more
// than kHoldMotion of the length scale from where it was found, under the same step, bound
// and limit sides. Only where every coordinate's h s_k was at least kHoldMargin away from
// the bound (above or below), and ln(h s_k) changed since the classification before at a
// pace that over kHoldMotion would cover at most half its distance to ln(bound): P is a
// smooth function of the configuration, but a nearly singular mass matrix (a light link
// carrying a heavy one) can make it change by half within 0.2 rad, so the pace is
// measured, not assumed. A coordinate near the bound, or nearing it fast, is classified
// again every step. A set held gives the stages every bit the classification itself would
// have given them (the test HeldClassificationSwitchesWhereEachStepsWould), and one whose
// s_k crossed the bound unseen would still be stable: RK4's limit, 2.785, is 1.39 times its
// bound of 2.
namespace {
using numerics::joint_space::kHoldSteps;
using numerics::joint_space::kHoldMotion;
using numerics::joint_space::kHoldMargin;

// How far the bodies are from their positions x0 (State::x): the largest of |r - r0| / L
// and 2 |p - p0| (the rotation angle to first order; a quaternion's sign flip counts as far).
double motionSince(const System& sys, const Eigen::VectorXd& x0, const Eigen::VectorXd& x) {
  double d = 0.0;
  for (int b = 0; b < sys.nb; ++b) {
    const int o = BodyCoordinates::x(b);
    d = std::max({d, (x.segment<3>(o) - x0.segment<3>(o)).norm() / sys.length_scale,
                  2.0 * (x.segment<4>(o + 3) - x0.segment<4>(o + 3)).norm()});
  }
  return d;
}
}  // namespace

bool JointStepper::classifyDamping(const System& sys, State& s, double h) {
  const double bound = tableau_->stiff_bound;
  const int nd = static_cast<int>(damped_.size());
  State::DampingHold& hold = s.damping_hold;
  // (whether the hold was found under this step, bound and limit sides, and how far the
  // bodies have moved since: both for holding it and for the pace below)
  const bool before = hold.rate.size() == static_cast<size_t>(nd) && hold.stiff.size() == static_cast<size_t>(nd) &&
                      hold.h == h && hold.bound == bound && hold.limit_side == s.limit_side &&
                      hold.x.size() == s.x.size();
  const double moved = before ? motionSince(sys, hold.x, s.x) : 0.0;
  if (before && hold.left > 0 && moved <= kHoldMotion) {
    --hold.left;
    bool changed = false;
    stiff_list_.clear();
    for (int i = 0; i < nd; ++i) {
      if (stiff_[i] != hold.stiff[i]) changed = true;
      stiff_[i] = hold.stiff[i];
      if (stiff_[i]) stiff_list_.push_back(i);
    }
    return changed;
  }
  bool kinematics = false;
  damp_candidates_.clear();
  double spread = 0.0;  // sum_l sqrt(c_l beta_l) (1.)
  for (int i = 0; i < nd; ++i) {
    Damped& d = damped_[i];
    const Joint& J = *sys.joints[d.j];
    double sum = d.bound;  // the filter (2.): sum over the damped coordinates of the same joint
    double beta = d.beta;
    if (sum < 0.0) {
      if (!kinematics) loadKinematics(sys, s.x.data(), s.u.data(), kin_), kinematics = true;
      J.coordinates(kin_[J.bodyI()], kin_[J.bodyJ()], s.tracked[J.id()], damp_rows_.data());
      sum = 0.0;
      for (const Damped& o : damped_) {
        if (o.j != d.j) continue;
        for (int slot = 0; slot < 2; ++slot) {
          const int b = slot == 0 ? J.bodyI() : J.bodyJ();
          if (b == System::kGround) continue;
          const auto& Mi = sys.Minv[b - 1];
          const Vector6d gk = damp_rows_[d.k].J.segment<6>(6 * slot).transpose();
          const Vector6d gl = damp_rows_[o.k].J.segment<6>(6 * slot).transpose();
          sum += std::sqrt(d.c * o.c) * std::fabs(Mi(0, 0) * gk.head<3>().dot(gl.head<3>()) +
                                                  gk.tail<3>().dot(Mi.bottomRightCorner<3, 3>() * gl.tail<3>()));
        }
      }
      beta = coordinateInverseMassBound(J, damp_rows_[d.k], body_inverse_[J.bodyI()], body_inverse_[J.bodyJ()]);
      if (d.revolute) d.bound = sum, d.beta = beta;
    }
    damp_filter_[i] = sum;
    damp_rcb_[i] = std::sqrt(d.c * beta);
    spread += damp_rcb_[i];
  }
  // (u_k NaN or infinite: no bound. 1 - 1e-9: where u_k = s_k, as for a body turning about
  // a principal axis through its centre on the ground, the two may differ by round-off.)
  const double below = bound * (1.0 - 1e-9);
  // (the set may be held: every coordinate kHoldMargin from the bound, changing slowly)
  bool margin = true;
  hold.rate.resize(nd);
  for (int i = 0; i < nd; ++i) {
    const double upper = h * damp_rcb_[i] * spread, filter = h * damp_filter_[i];
    if (!(upper <= below) && filter > bound / 4) {
      damp_candidates_.push_back(i);
      continue;
    }
    margin = margin && (upper <= bound / kHoldMargin || filter <= bound / (4 * kHoldMargin));
    hold.rate[i] = std::nan("");  // (no exact rate: the margin is the bound's or the filter's)
  }
  if (!damp_candidates_.empty()) dampedInverseMass();
  bool changed = false;
  stiff_list_.clear();
  for (int i = 0, next = 0; i < nd; ++i) {
    bool stiff = false;
    if (next < static_cast<int>(damp_candidates_.size()) && damp_candidates_[next] == i) {
      // P e_k at the damped coordinates: with closures, P = M^-1 - M^-1 G^T (G M^-1 G^T)^+
      // G M^-1 (the absolute formulation's P): a finger coupled to its hand is not stiff
      // when the hand carries it. G M^-1 e_k is row k of M^-1 G^T.
      damp_col_ = damp_Minv_.col(next++);
      if (damp_touched_[i])  // (by columns: Eigen's product kernels cost more at these sizes)
        // (a row on other branches of the closures has Yd 0 here: skipped, the same bits;
        // so are the entries where W's column is zero, which would change at most the sign
        // of a zero entry, and |P_lk| is read)
        for (int e : damp_used_)
          if (damp_Yd_(i, e) != 0.0) {
            const int lo = damp_W_lo_[e], n = damp_W_hi_[e] - lo;
            damp_col_.segment(lo, n) -= damp_W_.col(e).segment(lo, n) * damp_Yd_(i, e);
          }
      const double exact = damp_rc_(i) * damp_rc_.dot(damp_col_.cwiseAbs());  // sum_l sqrt(c_k c_l) |P_lk|
      const double rate = h * exact;
      stiff = !(rate <= bound);
      // the pace since the classification before, per unit of motion, of ln(rate) (below
      // 1e-3 of the bound as at it: a rate that far below is not near it, and a coordinate
      // a limit holds has a rate of round-off): kHoldMotion at that pace may use at most
      // half the distance to the bound, and that at least ln(kHoldMargin)
      const double distance = std::fabs(std::log(rate / bound)), floor = 1e-3 * bound;
      const double change =
          !before ? HUGE_VAL : std::fabs(std::log(std::max(rate, floor) / std::max(hold.rate[i], floor)));
      margin = margin && distance >= std::log(kHoldMargin) &&
               (change == 0.0 || change * kHoldMotion <= 0.5 * distance * moved);
      hold.rate[i] = rate;
    }
    if (stiff != static_cast<bool>(stiff_[i])) changed = true;
    stiff_[i] = stiff;
    if (stiff) stiff_list_.push_back(i);
  }
  hold.left = margin ? kHoldSteps : 0;
  hold.stiff = stiff_, hold.x = s.x, hold.limit_side = s.limit_side, hold.h = h, hold.bound = bound;
  return changed;
}

// What classifyDamping's entries of P are made of, at ws_'s articulated factors (q0), by the
// sparse factorization of closure_solver.h (RBDA 8.5): with M = L^T D L as the
// articulated-body algorithm factors it (D_k = S_k^T I^A_k S_k, ws_.Dinv), L^-T x is its
// inward pass with zero velocity on x (inverseMassInward), which for a unit vector e_l or a
// closure row touches only the links on its paths to the root; then
//   (M^-1)_lk = z_l^T D^-1 z_k  (z_l = L^-T e_l: over the coordinates the two paths share),
//   (M^-1 G^T)_le = z_l^T D^-1 L^-T G_e^T, or sum_c G_ec (M^-1)_lc for a row on damped
//   coordinates c (a coupler's, a limit's),
// and with closures W = (M^-1 G^T)_D (G M^-1 G^T)^+ from closures_' factorization at q0
// (stage 1 ran there), so that P_Dk = (M^-1)_Dk - W (M^-1 G^T)_k^T.
void JointStepper::dampedInverseMass() {
  auto scaleByDinv = [&](int k, const double* z, double* x) {  // x = D_k^-1 z on link k
    const TreeLink& L = model_.links[k];
    if (L.pivot >= 0) x[L.pivot] = ws_.tie_Dinv[k] * z[L.pivot];  // (TreeLink::pivot)
    if (L.tie >= 0) return;  // (no pivot of its own; its entry is 0, or its master's pivot's)
    if (L.nv == 1) {
      x[L.iv] = ws_.Dinv[k](0, 0) * z[L.iv];
    } else if (L.nv > 0) {
      const SmallVector u = Eigen::Map<const SmallVector>(z + L.iv, L.nv);
      Eigen::Map<SmallVector>(x + L.iv, L.nv) = ws_.Dinv[k] * u;
    }
  };
  const int nd = static_cast<int>(damped_.size());
  for (int i = 0; i < nd; ++i) {
    double* z = damp_Zd_.col(i).data();
    for (int v : damp_path_v_[i]) z[v] = 0.0;
    z[damped_[i].iv] = 1.0;
    for (int k : damp_path_[i]) damp_p_[k].setZero();
    for (int k : damp_path_[i]) inverseMassInward(model_, ws_, k, z, z, damp_p_);
    for (int k : damp_path_[i]) scaleByDinv(k, z, damp_Xd_.col(i).data());
  }
  // (M^-1)_Dk: the candidates' columns, then those of the damped coordinates that closure
  // rows on damped coordinates only touch
  damp_need_ = damp_candidates_;
  std::fill(damp_touched_.begin(), damp_touched_.end(), 0);
  std::fill(damp_column_of_.begin(), damp_column_of_.end(), -1);
  for (size_t a = 0; a < damp_need_.size(); ++a) damp_column_of_[damp_need_[a]] = static_cast<int>(a);
  const int m = closures_.m;
  damp_nz_.clear();  // per closure row its nonzero entries' coordinates (a free limit's: none)
  for (int e = 0; e < m; ++e) {
    damp_nz_first_[e] = static_cast<int>(damp_nz_.size());
    damp_direct_[e] = 1;
    for (int v : closures_.rowColumns(e))  // (G is zero off them)
      if (closures_.G(e, v) != 0.0) {
        damp_nz_.push_back(v);
        if (damp_index_of_v_[v] < 0) damp_direct_[e] = 0;
      }
    damp_nz_first_[e + 1] = static_cast<int>(damp_nz_.size());
    if (!damp_direct_[e]) continue;
    for (int p = damp_nz_first_[e]; p < damp_nz_first_[e + 1]; ++p) {
      const int c = damp_index_of_v_[damp_nz_[p]];
      if (damp_column_of_[c] < 0) damp_column_of_[c] = static_cast<int>(damp_need_.size()), damp_need_.push_back(c);
    }
  }
  for (size_t a = 0; a < damp_need_.size(); ++a) {
    const int k = damp_need_[a];
    // over the coordinates the two paths share (none: 0): X_k is zero off k's path, so the
    // terms left out are zeros, and the sum of the others, in the same order, has every
    // bit it had over the whole path
    damp_Minv_.col(a).setZero();
    for (int p = damp_shared_first_[k]; p < damp_shared_first_[k + 1]; ++p) {
      const int l = damp_shared_[p].l;
      const std::vector<int>& path = damp_path_v_[l];
      double y = 0.0;
      for (size_t r = damp_shared_[p].from; r < path.size(); ++r) y += damp_Zd_(path[r], l) * damp_Xd_(path[r], k);
      damp_Minv_(l, a) = y;
    }
  }
  if (m == 0) return;
  // (M^-1 G^T)_D by columns: a row on damped coordinates from those columns, another by its
  // own inward pass over the links on the paths of its nonzero entries
  damp_used_.clear();
  for (int e = 0; e < m; ++e) {
    if (damp_nz_first_[e] == damp_nz_first_[e + 1]) continue;  // a zero row: reaches nothing
    damp_used_.push_back(e);
    if (damp_direct_[e]) {
      damp_Yd_.col(e).setZero();
      for (int p = damp_nz_first_[e]; p < damp_nz_first_[e + 1]; ++p) {
        const int v = damp_nz_[p];
        damp_Yd_.col(e) += closures_.G(e, v) * damp_Minv_.col(damp_column_of_[damp_index_of_v_[v]]);
      }
      continue;
    }
    for (int p = damp_nz_first_[e]; p < damp_nz_first_[e + 1]; ++p)
      for (int k = link_of_v_[damp_nz_[p]]; k >= 0 && !damp_mark_[k]; k = model_.links[k].parent - 1) damp_mark_[k] = 1;
    damp_links_.clear();
    for (auto it = model_.order.rbegin(); it != model_.order.rend(); ++it)
      if (damp_mark_[*it - 1]) damp_links_.push_back(*it - 1), damp_mark_[*it - 1] = 0;
    damp_e_ = closures_.G.row(e).transpose();
    double* z = damp_e_.data();
    damp_x_.setZero();
    for (int k : damp_links_) damp_p_[k].setZero();
    for (int k : damp_links_) inverseMassInward(model_, ws_, k, z, z, damp_p_);
    for (int k : damp_links_) scaleByDinv(k, z, damp_x_.data());
    for (int l = 0; l < nd; ++l) {
      double y = 0.0;
      for (int v : damp_path_v_[l]) y += damp_Zd_(v, l) * damp_x_(v);
      damp_Yd_(l, e) = y;
    }
  }
  // only the rows that reach a damped coordinate count (a free limit's row is zero)
  size_t kept = 0;
  for (int e : damp_used_)
    if (!damp_Yd_.col(e).isZero(0.0)) damp_used_[kept++] = e;
  damp_used_.resize(kept);
  for (int l = 0; l < nd; ++l) {
    damp_touched_[l] = 0;
    for (int e : damp_used_)
      if (damp_Yd_(l, e) != 0.0) {
        damp_touched_[l] = 1;
        break;
      }
  }
  // (G M^-1 G^T)^+ by the columns of those rows (the closures' own solve: dropped rows 0,
  // least norm where rows depend), then W over them
  for (int f : damp_used_) {
    damp_r_.setZero();
    damp_r_(f) = 1.0;
    closures_.solve(damp_r_, damp_mu_);
    damp_W_.col(f).setZero();
    for (int e : damp_used_)  // (rows on other branches than f's have mu 0 exactly: skipped)
      if (damp_mu_(e) != 0.0) damp_W_.col(f) += damp_Yd_.col(e) * damp_mu_(e);
    // where the column is not zero (classifyDamping reads it there only)
    int lo = 0, hi = nd;
    while (lo < hi && damp_W_(lo, f) == 0.0) ++lo;
    while (hi > lo && damp_W_(hi - 1, f) == 0.0) --hi;
    damp_W_lo_[f] = lo, damp_W_hi_[f] = hi;
  }
}

// u' = argmin 1/2 |u' - u|_M^2 + 1/2 h sum_stiff c_k u'_k^2, i.e. (M + h E C E^T) u' = M u
// (E the stiff coordinates), by Woodbury with Y = M^-1 E (at the positions the stages
// reached) and B = E^T Y:  u' - u = -Y (C^-1 / h + B)^-1 E^T u, a small SPD solve. The
// impulse held over the step moves the positions by h (u' - u) / 2 (stiff_damping.cpp,
// items 3-4). It never adds energy: |u'|_M <= |u|_M.
void JointStepper::implicitDamping(const System& sys, State& s, double h) {
  const int ns = static_cast<int>(stiff_list_.size());
  // Y at the positions the stages reached (the metric the kinetic energy is measured in
  // there): articulated factors at s.q, one inverse-mass pass per stiff coordinate
  forwardDynamics(model_, sys, s.q, damp_zero_, damp_zero_, ws_, damp_qdd_);
  for (int a = 0; a < ns; ++a) {
    damp_e_.setZero();
    damp_e_(damped_[stiff_list_[a]].iv) = 1.0;
    closures_.applyInverseMass(model_, ws_, damp_e_.data(), damp_Y_.col(stiff_list_[a]).data());
  }
  for (int a = 0; a < ns; ++a) {
    const int ia = stiff_list_[a];
    for (int b = 0; b < ns; ++b) damp_K_(a, b) = damp_Y_(damped_[ia].iv, stiff_list_[b]);
    damp_K_(a, a) += 1.0 / (h * damped_[ia].c);
    damp_z_(a) = s.qdot(damped_[ia].iv);
  }
  // K = C^-1 / h + E^T M^-1 E is SPD (a positive diagonal plus an inverse mass): its
  // Cholesky factor in place on the leading ns x ns block (no allocation)
  Eigen::Ref<Eigen::MatrixXd> K = damp_K_.topLeftCorner(ns, ns);
  const Eigen::LLT<Eigen::Ref<Eigen::MatrixXd>> llt(K);
  auto solveK = [&](Eigen::VectorXd& z) { llt.solveInPlace(z.head(ns)); };  // z = K^-1 z
  solveK(damp_z_);
  damp_du_.setZero();
  for (int a = 0; a < ns; ++a) damp_du_ -= damp_Y_.col(stiff_list_[a]) * damp_z_(a);
  s.qdot += damp_du_;
  if (closures_.m > 0) {
    // With closures (couplers, drives, active limits) the same minimum subject to
    // G u' = nu at the end of the step: u' = u_free - Z mu with Z = W^-1 G^T, W = M + h E C E^T
    // (Z = M^-1 G^T - Y K^-1 Y^T G^T by Woodbury), (G Z) mu = G u_free - nu: the absolute
    // formulation's KKT in the metric M + h G^T C G (stiff_damping.cpp, item 3).
    EvalContext ctx = s.context();
    ctx.t = s.timeAfterStep(h);
    closures_.setContext(ctx);
    closures_.evaluate(model_, sys, ws_, s.q);  // G and nu at s.q (ws_: s.q at rest)
    closures_.form_Y = true;
    closures_.factor(model_, ws_);         // closures_.Y = M^-1 G^T
    closures_.form_Y = false;
    const int m = closures_.m;
    damp_Z_ = closures_.Y;
    for (int e = 0; e < m; ++e) {
      for (int a = 0; a < ns; ++a) damp_w_(a) = closures_.G.row(e).dot(damp_Y_.col(stiff_list_[a]));
      solveK(damp_w_);
      for (int a = 0; a < ns; ++a) damp_Z_.col(e) -= damp_Y_.col(stiff_list_[a]) * damp_w_(a);
    }
    damp_AW_.noalias() = closures_.G * damp_Z_;
    damp_r_.noalias() = closures_.G * s.qdot;
    damp_r_ -= closures_.nu;
    // as the closures' own solve: zero rows (free limits) held at mu = 0, least norm for
    // dependent rows
    damp_least_norm_.factor(damp_AW_);
    damp_least_norm_.solve(damp_r_, damp_mu_);
    damp_c_.noalias() = damp_Z_ * damp_mu_;
    s.qdot -= damp_c_;
    damp_du_ -= damp_c_;
  }
  damp_du_ *= 0.5 * h;
  // The positions move by h (u' - u) / 2 with each body keeping its absolute velocity (v
  // global, omega' body: the absolute formulation's u, which the move leaves as they are):
  // in joint coordinates the rates are then the M-nearest to those body velocities at the
  // new positions, u'' = M(q')^-1 J(q')^T M_b V (V the bodies' velocities at (q, u'), M_b
  // their own inertias). That is a projection: the kinetic energy does not rise (keeping
  // u' itself raised it by 6e-11 a step on a light chain of a tumbling base).
  forwardKinematics(model_, s.q, s.qdot, ws_);
  for (int k = 0; k < model_.nb; ++k) {
    damp_v_[k].head<3>() = ws_.v[k].head<3>();              // omega' (body)
    damp_v_[k].tail<3>() = ws_.A[k] * ws_.v[k].tail<3>();   // v (global)
  }
  retract(model_, s.q, damp_du_);
  forwardDynamics(model_, sys, s.q, damp_zero_, damp_zero_, ws_, damp_qdd_);  // factors at q'
  for (int k = 0; k < model_.nb; ++k) {  // momenta at the centres, body components
    const Body& B = sys.bodies[k + 1];
    damp_f_[k].head<3>() = B.Jp * damp_v_[k].head<3>();
    damp_f_[k].tail<3>() = B.m * (ws_.A[k].transpose() * damp_v_[k].tail<3>());
  }
  damp_tau_.setZero();
  for (auto it = model_.order.rbegin(); it != model_.order.rend(); ++it) {  // J^T f, leaves first
    const int k = *it - 1;
    const TreeLink& L = model_.links[k];
    damp_tau_.segment(L.iv, L.nv) = ws_.S[k].transpose() * damp_f_[k];
    if (L.parent != 0) damp_f_[L.parent - 1] += transformForceBack(ws_.E[k], ws_.rho[k], damp_f_[k]);
  }
  closures_.applyInverseMass(model_, ws_, damp_tau_.data(), s.qdot.data());
}

}  // namespace mechanism_sim
