// Sizing an actuator: its operating points over a run against its ratings (transmission.h's
// ActuatorRatings; doc/actuators.md). The peak torque, RMS torque, peak speed, peak power
// and the work done, and each rating exceeded: when first, by how much at worst.
#pragma once
#include <string>
#include <vector>

#include "mechanism_sim/core/model/transmission.h"

namespace mechanism_sim {

// Whether any property of an actuator is given (not 0).
inline bool ratingsGiven(const ActuatorRatings& r) {
  return r.rotor_inertia > 0 || r.rated_torque > 0 || r.peak_torque > 0 || r.stall_torque > 0 || r.no_load_speed > 0 ||
         r.max_speed > 0 || r.torque_constant > 0 || r.resistance > 0 || r.friction > 0 || r.damping > 0;
}

class ActuatorSizing {
 public:
  ActuatorSizing(const std::string& name, const ActuatorRatings& ratings) : name_(name), ratings_(ratings) {}
  // The operating point (motor-side velocity, torque) at time t: the first one starts the
  // record; each later one closes an interval of length t - t_previous, over which the
  // torque's square and the power are integrated by the trapezoidal rule.
  void add(double t, double velocity, double torque);
  void reset();

  double peakTorque() const { return peak_torque_; }   // |torque|
  double rmsTorque() const;                            // over the time recorded
  double peakSpeed() const { return peak_speed_; }     // |velocity|
  double peakPower() const { return peak_power_; }     // largest torque * velocity
  double positiveWork() const { return work_pos_; }    // integral of max(P, 0)
  double negativeWork() const { return work_neg_; }    // integral of min(P, 0)
  // A rating exceeded: which (peak_torque, rated_torque (by the RMS torque), max_speed,
  // torque-speed line), the rating, the worst value and when, and when it was first exceeded.
  struct Exceeded {
    std::string rating;
    double limit = 0.0, worst = 0.0, worst_time = 0.0, first_time = 0.0;
  };
  std::vector<Exceeded> exceeded() const;
  bool withinRating() const { return exceeded().empty(); }
  // One line: "actuator 'NAME': peak torque ..., RMS ..., peak speed ..., peak power ...,
  // work ...; within rating (...)" or "; exceeds ...".
  std::string describe() const;
  // The torque the torque-speed line allows at this speed (motoring: stall (1 - |w| / w0),
  // 0 past the no-load speed; braking: stall), infinite without a line.
  double envelope(double velocity, double torque) const;

 private:
  void exceed(int which, double value, double t);

  std::string name_;
  ActuatorRatings ratings_;
  bool started_ = false;
  double t0_ = 0.0, t_ = 0.0, last_tau_ = 0.0, last_power_ = 0.0;
  double tau2_ = 0.0;  // integral of torque^2
  double peak_torque_ = 0.0, peak_torque_time_ = 0.0, peak_speed_ = 0.0, peak_power_ = 0.0;
  double work_pos_ = 0.0, work_neg_ = 0.0;
  // per pointwise rating (0 peak torque, 1 max speed, 2 torque-speed line): first time,
  // worst ratio of value to the allowed, its value and time
  struct Worst {
    bool hit = false;
    double first = 0.0, ratio = 0.0, value = 0.0, time = 0.0, limit = 0.0;
  } worst_[3];
};

}  // namespace mechanism_sim
