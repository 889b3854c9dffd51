#include "mechanism_sim/urdf/model.h"

#include <algorithm>
#include <cmath>
#include <sstream>

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

Eigen::Isometry3d MechanismModel::linkPose(int link) const {
  const Link& l = links_.at(link);
  Eigen::Isometry3d W_B = Eigen::Isometry3d::Identity();
  if (l.body != Mechanism::kGround) {
    W_B.linear() = mechanism_->rotation(l.body);
    W_B.translation() = mechanism_->position(l.body);
  }
  return W_B * l.body_T_link;
}

std::pair<Eigen::Vector3d, Eigen::Vector3d> MechanismModel::linkVelocity(int link) const {
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
  std::vector<JointReaction> out(r.size());
  for (size_t j = 0; j < r.size(); ++j) {
    const Joint& jt = mechanism_->joint(static_cast<int>(j));
    // the file's joint frame on the child (body j is the child's body)
    const Eigen::Matrix3d R = mechanism_->rotation(jt.bodyJ()) * reaction_frames_.at(j).linear();
    out[j].joint = jt.name();
    out[j].force = R.transpose() * r[j].force;
    out[j].torque = R.transpose() * r[j].torque;
  }
  return out;
}

Eigen::Isometry3d MechanismModel::reactionFrame(int joint) const {
  const Joint& jt = mechanism_->joint(joint);
  Eigen::Isometry3d W_B = Eigen::Isometry3d::Identity();
  if (jt.bodyJ() != Mechanism::kGround) {
    W_B.linear() = mechanism_->rotation(jt.bodyJ());
    W_B.translation() = mechanism_->position(jt.bodyJ());
  }
  return W_B * reaction_frames_.at(joint);
}

double MechanismModel::position(int dof) const {
  return mechanism_->jointPosition(dofs_.at(dof).joint_index, dofs_[dof].k);
}
double MechanismModel::velocity(int dof) const {
  return mechanism_->jointVelocity(dofs_.at(dof).joint_index, dofs_[dof].k);
}
double MechanismModel::effort(int dof) const {
  return mechanism_->jointEffort(dofs_.at(dof).joint_index, dofs_[dof].k);
}
double MechanismModel::acceleration(int dof) const {
  return mechanism_->jointAcceleration(dofs_.at(dof).joint_index, dofs_[dof].k);
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
  if (!dofs_[dof].actuated)
    throw UsageError(source_ + ": dof '" + dofs_[dof].name + "' is passive (the file names its actuated joints): command an actuated one");
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
  if (!d.actuated)
    throw UsageError(source_ + ": dof '" + d.name + "' is passive (the file names its actuated joints): drive an actuated one");
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
  std::fill(command_.begin(), command_.end(), 0.0);
  for (const Dof& d : dofs_) mechanism_->setJointEffort(d.joint_index, d.k, 0.0);
}

std::string MechanismModel::formulationReason() const {
  return kinematic_ ? "kinematic, in absolute coordinates (no moving body has mass)" : mechanism_->formulationReason();
}

}  // namespace mechanism_sim
