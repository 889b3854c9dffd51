// Sizing an actuator: its operating points over a run against its ratings (transmission.h's
// ActuatorRatings; doc/actuators.md). The peak torque, RMS torque, peak speed, peak power
// and the work done, and each rating exceeded: when first, by how much at worst.
#pragma once
#include <array>
#include <cstddef>
#include <string>
#include <vector>

#include "mechanism_sim/core/model/transmission.h"

namespace mechanism_sim {

// Whether any property of an actuator is given (not 0).
inline bool ratingsGiven(const ActuatorRatings& r) {
  return r.rotor_inertia > 0 || r.rated_torque > 0 || r.peak_torque > 0 || r.stall_torque > 0 || r.no_load_speed > 0 ||
         r.max_speed > 0 || r.torque_constant > 0 || r.resistance > 0 || r.friction > 0 || r.damping > 0;
}

// Whether an actuator's electrical quantities follow (its torque_constant is given).
inline bool electricalGiven(const ActuatorRatings& r) { return r.torque_constant > 0; }

// A DC motor's electrical operating point at a motor-side velocity omega and torque tau
// (SI, back-EMF constant k_e = k_t): current i = tau / k_t, voltage V = R i + k_t omega,
// electrical power V i = tau omega + R i^2 (the mechanical power and the copper loss).
struct ActuatorElectrical {
  double current = 0.0, voltage = 0.0, power = 0.0, copper_loss = 0.0;
};
inline ActuatorElectrical electrical(const ActuatorRatings& r, double velocity, double torque) {
  ActuatorElectrical e;
  e.current = torque / r.torque_constant;
  e.voltage = r.resistance * e.current + r.torque_constant * velocity;
  e.power = e.voltage * e.current;
  e.copper_loss = r.resistance * e.current * e.current;
  return e;
}

class ActuatorSizing {
 public:
  ActuatorSizing(const std::string& name, const ActuatorRatings& ratings) : name_(name), ratings_(ratings) {}
  // The operating point (motor-side velocity, torque) at time t: the first one starts the
  // record; each later one closes an interval of length t - t_previous, over which the
  // torque's square and the power are integrated by the trapezoidal rule.
  void add(double t, double velocity, double torque);
  void reset();  // the record starts again (keeping whether points are kept)
  // Keep the operating points (t, velocity, torque) from now on, for a plot of the
  // torque-speed plane: every one while there are fewer than max_points (>= 2), then every
  // second, every fourth, ... (the kept ones stay evenly spaced in steps). 0: keep none.
  void keepPoints(size_t max_points);
  const std::vector<std::array<double, 3>>& points() const { return points_; }

  double peakTorque() const { return peak_torque_; }   // |torque|
  double peakTorqueTime() const { return peak_torque_time_; }
  double rmsTorque() const;                            // over the time recorded
  double peakSpeed() const { return peak_speed_; }     // |velocity|
  double peakPower() const { return peak_power_; }     // largest torque * velocity
  double positiveWork() const { return work_pos_; }    // integral of max(P, 0)
  double negativeWork() const { return work_neg_; }    // integral of min(P, 0)
  // With electrical properties (electricalGiven): |current|, |voltage| and the largest
  // electrical power at any step, and the copper losses' integral (trapezoidal).
  bool electricalGiven() const { return mechanism_sim::electricalGiven(ratings_); }
  double peakCurrent() const { return peak_current_; }
  double peakVoltage() const { return peak_voltage_; }
  double peakElectricalPower() const { return peak_electrical_power_; }
  double copperEnergy() const { return copper_energy_; }
  // The saturating mode's record (Mechanism::setActuatorLimits), given after add() at each
  // operating point: how far the actuator's drive is behind its profile (its joint
  // coordinate's units) and whether the actuator is at its bound. A step is at the bound
  // when the state it starts from is (the drive's lag is chosen there for the step).
  void addLag(double t, double lag, bool saturated);
  bool saturating() const { return saturating_; }
  int boundIntervals() const { return bound_intervals_; }  // runs of points at the bound
  double boundTime() const { return bound_time_; }          // time spent at the bound
  double firstBound() const { return first_bound_; }        // when first at it (-1: never)
  double lastBound() const { return last_bound_; }          // the last point at it (-1: never)
  double largestLag() const { return max_lag_; }            // |lag|
  double largestLagTime() const { return max_lag_time_; }
  // when the drive fell behind before its largest lag, and when it was back on its profile
  // (-1: still behind at the last point)
  double largestLagBegan() const { return max_lag_began_; }
  double largestLagEnded() const { return max_lag_ended_; }
  double finalLag() const { return last_lag_; }
  const std::string& name() const { return name_; }
  const ActuatorRatings& ratings() const { return ratings_; }
  // A rating exceeded: which (peak_torque, rated_torque (by the RMS torque), max_speed,
  // torque-speed line), the rating, the worst value and when, and when it was first exceeded.
  struct Exceeded {
    std::string rating;
    double limit = 0.0, worst = 0.0, worst_time = 0.0, first_time = 0.0;
  };
  std::vector<Exceeded> exceeded() const;
  bool withinRating() const { return exceeded().empty(); }
  // Whether any rating is given to size against (peak_torque, rated_torque, max_speed, a
  // torque-speed line).
  bool rated() const {
    return ratings_.peak_torque > 0 || ratings_.rated_torque > 0 || ratings_.max_speed > 0 || ratings_.stall_torque > 0;
  }
  // One line: "actuator 'NAME': peak torque ..., RMS ..., peak speed ..., peak power ...,
  // work ...[, peak current ..., peak voltage ..., peak electrical power ..., copper energy
  // ...]; within rating (...)" or "; EXCEEDS ...".
  std::string describe() const;
  // The torque the torque-speed line allows at this speed (motoring: stall (1 - |w| / w0),
  // 0 past the no-load speed; braking: stall), infinite without a line.
  double envelope(double velocity, double torque) const;

 private:
  void exceed(int which, double value, double t);

  std::string name_;
  ActuatorRatings ratings_;
  size_t max_points_ = 0, stride_ = 1, count_ = 0;
  std::vector<std::array<double, 3>> points_;
  bool started_ = false;
  double t0_ = 0.0, t_ = 0.0, last_tau_ = 0.0, last_power_ = 0.0;
  double tau2_ = 0.0;  // integral of torque^2
  double peak_torque_ = 0.0, peak_torque_time_ = 0.0, peak_speed_ = 0.0, peak_power_ = 0.0;
  double work_pos_ = 0.0, work_neg_ = 0.0;
  double peak_current_ = 0.0, peak_voltage_ = 0.0, peak_electrical_power_ = 0.0, copper_energy_ = 0.0, last_copper_ = 0.0;
  // per pointwise rating (0 peak torque, 1 max speed, 2 torque-speed line): first time,
  // worst ratio of value to the allowed, its value and time
  struct Worst {
    bool hit = false;
    double first = 0.0, ratio = 0.0, value = 0.0, time = 0.0, limit = 0.0;
  } worst_[3];
  bool saturating_ = false, last_bound_point_ = false, behind_ = false;
  int bound_intervals_ = 0;
  double last_lag_t_ = 0.0, bound_time_ = 0.0, first_bound_ = -1.0, last_bound_ = -1.0;
  double max_lag_ = 0.0, max_lag_time_ = 0.0, max_lag_began_ = 0.0, max_lag_ended_ = -1.0, behind_since_ = 0.0;
  double last_lag_ = 0.0;
};

}  // namespace mechanism_sim
