// The saturating mode's bound on what an actuator delivers (doc/actuators.md, "Saturating
// mode"): the torques its ratings allow at its speed, and an actuator that bounds the drive
// of a joint coordinate (Mechanism::setActuatorLimits).
#pragma once
#include <string>

#include "mechanism_sim/core/model/transmission.h"

namespace mechanism_sim {

// The torque interval [lo, hi] an actuator can give at motor speed omega: within
// +-peak_torque, and on a DC motor's line, motoring (torque and speed of one sign) at most
// stall (1 - |omega| / no_load_speed) (none past the no-load speed), braking at most the
// stall torque (ActuatorSizing::envelope's rule). Unbounded (+-inf) without either.
struct TorqueBounds {
  double lo = 0.0, hi = 0.0;
};
TorqueBounds torqueBounds(const ActuatorRatings& r, double omega);
// Whether the ratings bound the torque at all (a peak torque or a torque-speed line).
inline bool boundsTorque(const ActuatorRatings& r) { return r.peak_torque > 0 || r.stall_torque > 0; }

// An actuator behind a simple transmission theta = N (q_k - q_0) on coordinate k of a joint:
// its speed is N q_dot_k and its torque tau_q / N plus its own damping and friction at
// that speed, tau_q the coordinate's commanded effort and its drive's effort.
struct ActuatorLimit {
  std::string name;
  int joint = 0, k = 0;
  double reduction = 1.0;  // N
  ActuatorRatings ratings;
};

}  // namespace mechanism_sim
