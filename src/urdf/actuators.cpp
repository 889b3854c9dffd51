// An actuator's operating point from its transmission's joints (model.h, doc/actuators.md).
#include <cmath>

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
  return s;
}

}  // namespace mechanism_sim
