// An actuator's operating point from its transmission's joints (model.h, doc/actuators.md).
#include <algorithm>
#include <cmath>

#include <Eigen/LU>

#include "mechanism_sim/core/model/actuator_limits.h"
#include "mechanism_sim/core/model/actuator_sizing.h"
#include "mechanism_sim/urdf/model.h"

namespace mechanism_sim {

ActuatorState MechanismModel::actuatorState(int actuator) const {
  const Actuator& a = actuators_.at(actuator);
  const TransmissionInfo& t = transmissions_[a.transmission];
  const int n = static_cast<int>(t.dofs.size());
  const System& sys = mechanism_->system();
  const State& st = mechanism_->state();
  Eigen::Vector2d q = Eigen::Vector2d::Zero(), q_dot = q, tau = q;
  for (int i = 0; i < n; ++i) {
    const Dof& d = dofs_[t.dofs[i]];
    q[i] = position(t.dofs[i]);
    q_dot[i] = velocity(t.dofs[i]);
    // what the actuators supply at the joint: the command and the drive's effort (its
    // multiplier with the sign of an applied effort, as Mechanism::jointEffort)
    tau[i] = command_[t.dofs[i]];
    if (d.velocity_limit > 0 && std::fabs(q_dot[i]) >= d.velocity_limit && tau[i] * q_dot[i] > 0)
      tau[i] = 0.0;  // cut at the velocity limit, as step() applies it
    const int drive = mechanism_->driveOf(d.joint_index, d.k);
    if (drive >= 0) tau[i] -= st.lambda[sys.layout[sys.drives[drive].constraint].row];
  }
  ActuatorState s;
  // theta = E (q - q_0), theta_dot = E q_dot, tau_theta = E^-T tau_q (transmission.h)
  for (int i = 0; i < n; ++i) q[i] -= t.map.joint_offset[i];
  s.position = t.E.row(a.k).dot(q);
  s.velocity = t.E.row(a.k).dot(q_dot);
  s.torque = t.E_inv_T.row(a.k).dot(tau);
  // The motor's own damping and friction act on the motion (loader_joints.cpp: through the
  // transmission onto the joints), so a drive's effort above already overcomes them and a
  // command is what the motor gives, part of which they take: nothing is added here.
  s.power = s.torque * s.velocity;
  if (electricalGiven(a.ratings)) {
    const ActuatorElectrical e = electrical(a.ratings, s.velocity, s.torque);
    s.current = e.current, s.voltage = e.voltage, s.electrical_power = e.power;
  }
  if (actuator_limits_ && n == 1) {
    const Dof& d = dofs_[t.dofs[0]];
    const int drive = mechanism_->driveOf(d.joint_index, d.k);
    if (drive >= 0) s.lag = mechanism_->driveLag(drive), s.saturated = mechanism_->driveSaturated(drive);
  } else if (actuator_limits_) {
    // a two-joint transmission's actuator: the lag of its own coordinate, E_i d (motor
    // units), and at its bound while its drives are held and its torque is there
    bool held = true;
    for (int i = 0; i < n; ++i) {
      const Dof& d = dofs_[t.dofs[i]];
      const int drive = mechanism_->driveOf(d.joint_index, d.k);
      if (drive < 0) {  // (not bounded: no lag of its own)
        s.lag = 0.0, held = false;
        break;
      }
      s.lag += t.E(a.k, i) * mechanism_->driveLag(drive);
      held = held && mechanism_->driveSaturated(drive);
    }
    if (held && boundsTorque(a.ratings)) {
      const TorqueBounds b = torqueBounds(a.ratings, s.velocity);
      const double tol = 1e-9 * std::max(std::fabs(b.lo), std::fabs(b.hi));
      s.saturated = std::fabs(s.torque - b.hi) <= tol || std::fabs(s.torque - b.lo) <= tol;
    }
  }
  return s;
}

std::string MechanismModel::setActuatorLimits(bool on) {
  std::vector<ActuatorLimit> limits;
  for (const Actuator& a : actuators_) {
    if (!on || !boundsTorque(a.ratings)) continue;
    const TransmissionInfo& t = transmissions_[a.transmission];
    ActuatorLimit L;
    L.name = a.name, L.ratings = a.ratings;
    if (t.map.type == TransmissionType::kSimple) {
      const Dof& d = dofs_[t.dofs[0]];
      L.joint = d.joint_index, L.k = d.k, L.reduction = t.E(0, 0);
    } else {  // (actuator_limits.h: E's row, E^-T's row and E^-1's column of the actuator)
      const Eigen::Matrix2d E_inv = t.E.inverse();  // (two joints: the top-left is all of E)
      for (int c = 0; c < 2; ++c) {
        const Dof& d = dofs_[t.dofs[c]];
        L.coords.push_back({d.joint_index, d.k, t.E(a.k, c), t.E_inv_T(a.k, c), E_inv(c, a.k)});
      }
    }
    limits.push_back(L);
  }
  mechanism_->setActuatorLimits(limits);
  actuator_limits_ = on;
  if (!on) return "";
  if (limits.empty()) return "actuator limits: no actuator has a peak_torque or a torque-speed line: nothing is bounded";
  return "";
}

}  // namespace mechanism_sim
