// The saturating mode's bound on what an actuator delivers (doc/actuators.md, "Saturating
// mode"): the torques its ratings allow at its speed, and an actuator that bounds the drive
// of a joint coordinate (Mechanism::setActuatorLimits).
#pragma once
#include <string>
#include <vector>

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
// its speed is N q_dot_k and its torque tau_q / N, tau_q the coordinate's commanded effort
// and its drive's effort (which overcomes the motor's own damping and friction).
//
// An actuator i of a two-joint transmission (differential, four-bar; transmission.h) gives
// `coords`, its transmission's coordinates in order, each with its entries of
//   speed:  E_i,     theta_dot_i = sum_c E_ic q_dot_c,
//   torque: (E^-T)_i, tau_theta_i = sum_c (E^-T)_ic tau_q,c  (tau_q = E^T tau_theta),
//   lag:    (E^-1)_ci, the joints' lags when its own coordinate falls behind by one (the
//           other actuator's coordinate following its profile);
// joint, k and reduction are then not read. It bounds its drives while every one of its
// coordinates is driven.
struct ActuatorCoordinate {
  int joint = 0, k = 0;
  double speed = 0.0, torque = 0.0, lag = 0.0;
};
struct ActuatorLimit {
  std::string name;
  int joint = 0, k = 0;
  double reduction = 1.0;  // N
  ActuatorRatings ratings;
  std::vector<ActuatorCoordinate> coords;  // empty: the simple transmission (joint, k, reduction)
};

}  // namespace mechanism_sim
