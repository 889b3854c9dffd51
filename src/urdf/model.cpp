#include "mechanism_sim/urdf/model.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "mechanism_sim/core/model/math.h"

namespace mechanism_sim {

int MechanismModel::dofIndex(const std::string& name) const {
  for (size_t i = 0; i < dofs_.size(); ++i)
    if (dofs_[i].name == name) return static_cast<int>(i);
  return -1;
}

int MechanismModel::linkIndex(const std::string& name) const {
  for (size_t i = 0; i < links_.size(); ++i)
    if (links_[i].name == name) return static_cast<int>(i);
  return -1;
}

int MechanismModel::numMovingBodies() const { return mechanism_->numBodies() - 1; }
int MechanismModel::numEquations() const { return mechanism_->numEquations(); }
const DependencyReport& MechanismModel::dependencies() const { return mechanism_->dependencies(); }
const Eigen::Vector3d& MechanismModel::gravity() const { return mechanism_->gravity(); }

void MechanismModel::setGravity(const Eigen::Vector3d& g) {
  if (!g.allFinite()) throw UsageError("gravity must be three finite numbers");
  mechanism_->setGravity(g);
}

double MechanismModel::time() const { return mechanism_->time(); }
double MechanismModel::kineticEnergy() const { return mechanism_->kineticEnergy(); }
double MechanismModel::potentialEnergy() const { return mechanism_->potentialEnergy(); }
double MechanismModel::positionViolation() const { return mechanism_->positionViolation(); }
double MechanismModel::velocityViolation() const { return mechanism_->velocityViolation(); }
double MechanismModel::stepPositionViolation() const { return mechanism_->stepPositionViolation(); }
double MechanismModel::stepVelocityViolation() const { return mechanism_->stepVelocityViolation(); }

namespace {

Eigen::Isometry3d turnAboutZ(double t) {
  return Eigen::Isometry3d(Eigen::AngleAxisd(t, Eigen::Vector3d::UnitZ()));
}

}  // namespace

const Angles3& MechanismModel::gimbalAngles(int gimbal) const {
  auto& [angles, at] = gimbal_angles_.at(gimbal);
  const Eigen::Vector3d now = ballVector(gimbal, &Mechanism::jointPosition);
  if (now != at) {
    angles = gimbals_[gimbal].axes.angles(expRotation(now).toRotationMatrix(), angles);
    at = now;
  }
  return angles;
}

std::string MechanismModel::whyPassive(int dof) const {
  const Dof& d = dofs_.at(dof);
  if (d.gimbal >= 0)
    return "'" + d.name + "' is one of three revolute joints through massless links that are simulated as one ball "
           "(doc/robots.md): it is reported, not commanded; name it in the file (a <transmission>, limits) to keep the "
           "chain";
  if (!d.actuated) return "'" + d.name + "' is passive (the file names its actuated joints)";
  return "";
}

Eigen::Isometry3d MechanismModel::linkPose(int link) const {
  // a gimbal's massless links turn with its angles (Gimbal), not with the ball's child
  for (size_t g = 0; g < gimbals_.size(); ++g) {
    const Gimbal& G = gimbals_[g];
    if (link != G.link1 && link != G.link2) continue;
    const Angles3& t = gimbalAngles(static_cast<int>(g));
    const Eigen::Isometry3d L1 = linkPose(G.parent_link) * G.P_J[0] * turnAboutZ(t[0]) * G.C_J[0].inverse();
    return link == G.link1 ? L1 : L1 * G.P_J[1] * turnAboutZ(t[1]) * G.C_J[1].inverse();
  }
  const Link& l = links_.at(link);
  Eigen::Isometry3d W_B = Eigen::Isometry3d::Identity();
  if (l.body != Mechanism::kGround) {
    W_B.linear() = mechanism_->rotation(l.body);
    W_B.translation() = mechanism_->position(l.body);
  }
  return W_B * l.body_T_link;
}

std::pair<Eigen::Vector3d, Eigen::Vector3d> MechanismModel::linkVelocity(int link) const {
  for (size_t g = 0; g < gimbals_.size(); ++g) {
    const Gimbal& G = gimbals_[g];
    if (link != G.link1 && link != G.link2) continue;
    // turning about the ball's centre c, fixed in the parent: v(p) = v_parent(p) + w_rel x (p - c)
    const Angles3& t = gimbalAngles(static_cast<int>(g));
    const Angles3 t_dot = gimbalRates(static_cast<int>(g));
    const Eigen::Isometry3d F = linkPose(G.parent_link) * G.P_J[0];  // J0's frame on the parent
    const Eigen::Vector3d turned(t_dot[0], link == G.link2 ? t_dot[1] : 0.0, 0.0);  // L1: t0 alone; L2: t0, t1
    const Eigen::Vector3d w_rel = F.linear() * G.axes.rateMatrix(t) * turned;
    const auto parent = linkVelocity(G.parent_link);
    const Eigen::Vector3d p = linkPose(link).translation(), from_parent = p - linkPose(G.parent_link).translation();
    return {parent.first + parent.second.cross(from_parent) + w_rel.cross(p - F.translation()), parent.second + w_rel};
  }
  const Link& l = links_.at(link);
  if (l.body == Mechanism::kGround) return {Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};
  // the body's state: v_i of its origin r_i (world), w_i in body axes
  const Eigen::Matrix3d A_Oi = mechanism_->rotation(l.body);
  const auto u_i = mechanism_->state().u.segment<6>(6 * (l.body - 1));
  const Eigen::Vector3d w = A_Oi * u_i.tail<3>();
  return {u_i.head<3>() + w.cross(A_Oi * l.body_T_link.translation()), w};
}

std::vector<double> MechanismModel::couplingReactions() const {
  std::vector<double> out;
  for (const CouplingInfo& c : couplings_)
    out.push_back(c.limit >= 0 ? mechanism_->limitReaction(c.limit) : mechanism_->couplingReaction(c.constraint));
  return out;
}

std::vector<JointReaction> MechanismModel::jointReactions() const {
  const std::vector<Reaction> r = mechanism_->jointReactions();
  std::vector<JointReaction> out(r.size() + 2 * gimbals_.size());
  auto put = [&](size_t at, const std::string& name, const Reaction& world) {
    const Eigen::Matrix3d R = reactionFrame(static_cast<int>(at)).linear();
    out[at].joint = name;
    out[at].force = R.transpose() * world.force;
    out[at].torque = R.transpose() * world.torque;
  };
  for (size_t j = 0; j < r.size(); ++j) put(j, mechanism_->joint(static_cast<int>(j)).name(), r[j]);
  // a gimbal's J1 and J2 pass the ball's wrench on at its centre (their links carry no mass)
  for (size_t g = 0; g < gimbals_.size(); ++g)
    for (int k = 1; k < 3; ++k) put(r.size() + 2 * g + k - 1, dofs_[dofOfGimbal(g, k)].name, r[gimbals_[g].joint]);
  return out;
}

int MechanismModel::dofOfGimbal(size_t gimbal, int k) const {
  for (size_t d = 0; d < dofs_.size(); ++d)
    if (dofs_[d].gimbal == static_cast<int>(gimbal) && dofs_[d].k == k) return static_cast<int>(d);
  throw InternalError("a gimbal without its dofs");
}

Eigen::Isometry3d MechanismModel::reactionFrame(int joint) const {
  const int joints = mechanism_->numJoints();
  if (joint >= joints) {  // a gimbal's J1 (on L2) or J2 (on the ball's child), at the ball's centre
    const Gimbal& G = gimbals_.at((joint - joints) / 2);
    Eigen::Isometry3d F = linkPose((joint - joints) % 2 == 0 ? G.link2 : G.child_link);
    F.translation() = reactionFrame(G.joint).translation();
    return F;
  }
  for (const Gimbal& G : gimbals_)
    if (G.joint == joint)  // J0's frame on L1, which turns with the angles
      return linkPose(G.link1) * links_[G.link1].body_T_link.inverse() * reaction_frames_.at(joint);
  const Joint& jt = mechanism_->joint(joint);
  Eigen::Isometry3d W_B = Eigen::Isometry3d::Identity();
  if (jt.bodyJ() != Mechanism::kGround) {
    W_B.linear() = mechanism_->rotation(jt.bodyJ());
    W_B.translation() = mechanism_->position(jt.bodyJ());
  }
  return W_B * reaction_frames_.at(joint);
}

// A gimbal's dof (Dof::gimbal): its angle, and the rates, efforts and accelerations of the
// angles from the ball's (davenport.h): omega = J t_dot, and by virtual work Q = J' tau.
double MechanismModel::position(int dof) const {
  const Dof& d = dofs_.at(dof);
  if (d.gimbal >= 0) return gimbalAngles(d.gimbal)[d.k];
  return mechanism_->jointPosition(d.joint_index, d.k);
}
double MechanismModel::velocity(int dof) const {
  const Dof& d = dofs_.at(dof);
  if (d.gimbal >= 0) return gimbalRates(d.gimbal)[d.k];
  return mechanism_->jointVelocity(d.joint_index, d.k);
}
double MechanismModel::effort(int dof) const {
  const Dof& d = dofs_.at(dof);
  if (d.gimbal >= 0) {
    const Eigen::Matrix3d J = gimbals_[d.gimbal].axes.rateMatrix(gimbalAngles(d.gimbal));
    return (J.transpose() * ballVector(d.gimbal, &Mechanism::jointEffort))(d.k);
  }
  return mechanism_->jointEffort(d.joint_index, d.k);
}
double MechanismModel::acceleration(int dof) const {
  const Dof& d = dofs_.at(dof);
  if (d.gimbal >= 0) {
    return gimbals_[d.gimbal].axes.accelerations(gimbalAngles(d.gimbal), gimbalRates(d.gimbal),
                                                 ballVector(d.gimbal, &Mechanism::jointAcceleration))[d.k];
  }
  return mechanism_->jointAcceleration(d.joint_index, d.k);
}

Eigen::Vector3d MechanismModel::ballVector(int gimbal, double (Mechanism::*of)(int, int) const) const {
  const Mechanism& m = *mechanism_;
  const int j = gimbals_[gimbal].joint;
  return Eigen::Vector3d((m.*of)(j, 0), (m.*of)(j, 1), (m.*of)(j, 2));
}

Angles3 MechanismModel::gimbalRates(int gimbal) const {
  return gimbals_[gimbal].axes.rates(gimbalAngles(gimbal), ballVector(gimbal, &Mechanism::jointVelocity));
}

void MechanismModel::commandDriveVelocity(int dof, double v, double acc) {
  if (dof < 0 || dof >= static_cast<int>(dofs_.size())) throw UsageError("no such degree of freedom");
  if (dofs_[dof].drive < 0) throw UsageError("dof '" + dofs_[dof].name + "' is not driven");
  mechanism_->commandDriveVelocity(dofs_[dof].drive, v, acc);
}

double MechanismModel::driveVelocity(int dof) const {
  if (dofs_.at(dof).drive < 0) throw UsageError("dof '" + dofs_[dof].name + "' is not driven");
  double q, q_dot, q_ddot;
  mechanism_->driveTarget(dofs_[dof].drive, &q, &q_dot, &q_ddot);
  return q_dot;
}

void MechanismModel::setEffort(int dof, double tau) {
  if (dof < 0 || dof >= static_cast<int>(dofs_.size())) throw UsageError("no such degree of freedom");
  if (!std::isfinite(tau)) throw UsageError("effort for '" + dofs_[dof].name + "' is not finite");
  if (!dofs_[dof].actuated) throw UsageError(source_ + ": " + whyPassive(dof) + ": command an actuated one");
  const double limit = dofs_[dof].effort_limit;
  command_[dof] = limit > 0 ? std::max(-limit, std::min(limit, tau)) : tau;
}

// A velocity limit acts like a motor's top speed: the command is cut while it pushes the
// joint faster than the limit in the direction of motion.
void MechanismModel::step(double h) {
  for (size_t d = 0; d < dofs_.size(); ++d) {
    double tau = command_[d];
    const double vmax = dofs_[d].velocity_limit;
    if (vmax > 0 && tau != 0.0) {
      const double v = velocity(static_cast<int>(d));
      if (std::fabs(v) >= vmax && tau * v > 0) tau = 0.0;
    }
    mechanism_->setJointEffort(dofs_[d].joint_index, dofs_[d].k, tau);
  }
  // Whatever stops a step reaches the caller as one line with the file and the time.
  auto where = [&] {
    std::ostringstream os;
    os << source_ << ": at t = " << time() << " s: ";
    return os.str();
  };
  try {
    mechanism_->step(h);
  } catch (const StepFailure& e) {
    throw StepFailure(where() + e.what());
  } catch (const Error& e) {  // SimulationError, UsageError (a bad h), InternalError
    throw SimulationError(where() + e.what());
  } catch (const std::exception& e) {
    throw SimulationError(where() + InternalError(e.what()).what());
  }
}

void MechanismModel::driveDof(int dof) {
  if (dof < 0 || dof >= static_cast<int>(dofs_.size())) throw UsageError("no such degree of freedom");
  Dof& d = dofs_[dof];
  if (d.drive >= 0) throw UsageError("dof '" + d.name + "' is driven already");
  if (!d.actuated) throw UsageError(source_ + ": " + whyPassive(dof) + ": drive an actuated one");
  try {
    d.drive = mechanism_->addDrive(d.joint_index, d.k, DriveProfile::velocity(0.0));
  } catch (const ModelError& e) {
    throw UsageError("dof '" + d.name + "': " + e.what());
  }
  driven_after_load_.push_back(dof);
}

void MechanismModel::undriveDof(int dof) {
  const auto it = std::find(driven_after_load_.begin(), driven_after_load_.end(), dof);
  if (it == driven_after_load_.end()) throw UsageError("dof was not driven by driveDof()");
  const int drive = dofs_[dof].drive;
  mechanism_->removeDrive(drive);
  for (Dof& d : dofs_)
    if (d.drive > drive) --d.drive;
  dofs_[dof].drive = -1;
  driven_after_load_.erase(it);
}

void MechanismModel::reset() {
  // the drives driveDof() added go (the last first); the System is the loaded one again
  while (!driven_after_load_.empty()) undriveDof(driven_after_load_.back());
  mechanism_->restore(initial_);
  for (auto& g : gimbal_angles_) g = {Angles3{0.0, 0.0, 0.0}, Eigen::Vector3d::Zero()};
  std::fill(command_.begin(), command_.end(), 0.0);
  for (const Dof& d : dofs_) mechanism_->setJointEffort(d.joint_index, d.k, 0.0);
}

std::string MechanismModel::formulationReason() const {
  return kinematic_ ? "kinematic, in absolute coordinates (no moving body has mass)" : mechanism_->formulationReason();
}

}  // namespace mechanism_sim
