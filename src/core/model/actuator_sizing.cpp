// Sizing an actuator against its ratings (actuator_sizing.h).
#include "mechanism_sim/core/model/actuator_sizing.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace mechanism_sim {

namespace {
// Relative to a bound: what a torque may lie above it and still meet it (round-off).
constexpr double kBoundSlack = 1e-9;
}  // namespace

void ActuatorSizing::reset() {
  const size_t keep = max_points_;
  *this = ActuatorSizing(name_, ratings_);
  keepPoints(keep);
}

void ActuatorSizing::keepPoints(size_t max_points) {
  max_points_ = max_points == 1 ? 2 : max_points;
  stride_ = 1, count_ = 0;
  points_.clear();
}

double ActuatorSizing::envelope(double velocity, double torque) const {
  if (!(ratings_.stall_torque > 0.0)) return HUGE_VAL;
  if (torque * velocity < 0.0) return ratings_.stall_torque;  // braking
  return std::max(0.0, ratings_.stall_torque * (1.0 - std::fabs(velocity) / ratings_.no_load_speed));
}

void ActuatorSizing::exceed(int which, double value, double t) {
  Worst& w = worst_[which];
  const double ratio = w.limit > 0 ? std::fabs(value) / w.limit : HUGE_VAL;
  if (!w.hit) w.hit = true, w.first = t;
  if (ratio > w.ratio) w.ratio = ratio, w.value = value, w.time = t;
}

void ActuatorSizing::add(double t, double velocity, double torque) {
  const double power = torque * velocity;
  const bool first = !started_;
  if (!first) {
    const double dt = t - t_;
    tau2_ += 0.5 * dt * (last_tau_ * last_tau_ + torque * torque);
    work_pos_ += 0.5 * dt * (std::max(last_power_, 0.0) + std::max(power, 0.0));
    work_neg_ += 0.5 * dt * (std::min(last_power_, 0.0) + std::min(power, 0.0));
  } else {
    started_ = true, t0_ = t;
  }
  if (electricalGiven()) {
    const ActuatorElectrical e = electrical(ratings_, velocity, torque);
    if (!first) copper_energy_ += 0.5 * (t - t_) * (last_copper_ + e.copper_loss);
    last_copper_ = e.copper_loss;
    peak_current_ = std::max(peak_current_, std::fabs(e.current));
    peak_voltage_ = std::max(peak_voltage_, std::fabs(e.voltage));
    peak_electrical_power_ = std::max(peak_electrical_power_, e.power);
  }
  t_ = t, last_tau_ = torque, last_power_ = power;
  if (max_points_ > 0 && count_++ % stride_ == 0) {
    points_.push_back({t, velocity, torque});
    if (points_.size() >= max_points_) {
      // every second one of those kept (counts multiple of 2 stride) and twice the stride
      size_t j = 0;
      for (size_t i = 0; i < points_.size(); i += 2) points_[j++] = points_[i];
      points_.resize(j);
      stride_ *= 2;
    }
  }
  if (std::fabs(torque) > peak_torque_) peak_torque_ = std::fabs(torque), peak_torque_time_ = t;
  peak_speed_ = std::max(peak_speed_, std::fabs(velocity));
  peak_power_ = std::max(peak_power_, power);
  // (a torque held at a bound by the saturating mode meets it to the solves' round-off:
  // kBoundSlack above it is not over)
  if (ratings_.peak_torque > 0 && std::fabs(torque) > ratings_.peak_torque * (1 + kBoundSlack))
    worst_[0].limit = ratings_.peak_torque, exceed(0, torque, t);
  if (ratings_.max_speed > 0 && std::fabs(velocity) > ratings_.max_speed)
    worst_[1].limit = ratings_.max_speed, exceed(1, velocity, t);
  const double allowed = envelope(velocity, torque);
  if (std::fabs(torque) > allowed + kBoundSlack * ratings_.stall_torque) {
    // measured against the stall torque: past the no-load speed the line allows nothing
    worst_[2].limit = ratings_.stall_torque;
    Worst& w = worst_[2];
    const double over = (std::fabs(torque) - allowed) / ratings_.stall_torque;
    if (!w.hit) w.hit = true, w.first = t;
    if (over > w.ratio) w.ratio = over, w.value = torque, w.time = t;
  }
}

void ActuatorSizing::addLag(double t, double lag, bool saturated) {
  if (saturating_ && last_bound_point_) bound_time_ += t - last_lag_t_;
  saturating_ = true;
  if (saturated) {
    if (!last_bound_point_) ++bound_intervals_;
    if (first_bound_ < 0) first_bound_ = t;
    last_bound_ = t;
  }
  last_bound_point_ = saturated;
  last_lag_t_ = t;
  last_lag_ = lag;
  const double a = std::fabs(lag);
  if (a > 0 && !behind_) behind_ = true, behind_since_ = t;
  if (a == 0 && behind_) {
    behind_ = false;
    if (max_lag_ > 0 && max_lag_began_ == behind_since_ && max_lag_ended_ < 0) max_lag_ended_ = t;
  }
  if (a > max_lag_) max_lag_ = a, max_lag_time_ = t, max_lag_began_ = behind_since_, max_lag_ended_ = -1.0;
}

double ActuatorSizing::rmsTorque() const {
  const double T = t_ - t0_;
  return T > 0 ? std::sqrt(tau2_ / T) : std::fabs(last_tau_);
}

std::vector<ActuatorSizing::Exceeded> ActuatorSizing::exceeded() const {
  std::vector<Exceeded> out;
  const char* names[3] = {"peak_torque", "max_speed", "torque-speed line"};
  for (int k = 0; k < 3; ++k)
    if (worst_[k].hit) out.push_back({names[k], worst_[k].limit, worst_[k].value, worst_[k].time, worst_[k].first});
  if (ratings_.rated_torque > 0 && rmsTorque() > ratings_.rated_torque)
    out.push_back({"rated_torque", ratings_.rated_torque, rmsTorque(), t_, t_});
  return out;
}

std::string ActuatorSizing::describe() const {
  char buf[512];
  std::snprintf(buf, sizeof buf,
                "actuator '%s': peak torque %.4g N m at t = %.4g s, RMS torque %.4g N m, peak speed %.4g rad/s, "
                "peak power %.4g W, work %+.4g J / %+.4g J",
                name_.c_str(), peak_torque_, peak_torque_time_, rmsTorque(), peak_speed_, peak_power_, work_pos_,
                work_neg_);
  std::string s = buf;
  if (electricalGiven()) {
    std::snprintf(buf, sizeof buf,
                  ", peak current %.4g A, peak voltage %.4g V, peak electrical power %.4g W, copper energy %.4g J",
                  peak_current_, peak_voltage_, peak_electrical_power_, copper_energy_);
    s += buf;
  }
  if (saturating_) {
    if (bound_intervals_ == 0) {
      s += "; never at its bounds";
    } else {
      std::snprintf(buf, sizeof buf, "; at its bounds %d time%s, %.4g s in all (from t = %.4g s, last at t = %.4g s)",
                    bound_intervals_, bound_intervals_ == 1 ? "" : "s", bound_time_, first_bound_, last_bound_);
      s += buf;
    }
    if (max_lag_ > 0) {
      std::snprintf(buf, sizeof buf, ", largest lag %.4g at t = %.4g s (behind from t = %.4g s, ", max_lag_,
                    max_lag_time_, max_lag_began_);
      s += buf;
      if (max_lag_ended_ >= 0) std::snprintf(buf, sizeof buf, "back on its profile at t = %.4g s)", max_lag_ended_);
      else std::snprintf(buf, sizeof buf, "still behind at the end: %.4g)", std::fabs(last_lag_));
      s += buf;
    }
  }
  const std::vector<Exceeded> ex = exceeded();
  if (!rated()) return s + "; no ratings given";
  if (ex.empty()) {
    s += "; within rating (";
    std::string list;
    auto item = [&](const char* what, double v, const char* unit) {
      if (!(v > 0)) return;
      char b[96];
      std::snprintf(b, sizeof b, "%s%s %.4g %s", list.empty() ? "" : ", ", what, v, unit);
      list += b;
    };
    item("peak_torque", ratings_.peak_torque, "N m");
    item("rated_torque", ratings_.rated_torque, "N m");
    item("max_speed", ratings_.max_speed, "rad/s");
    if (ratings_.stall_torque > 0) {
      char b[128];
      std::snprintf(b, sizeof b, "%sline %.4g N m to %.4g rad/s", list.empty() ? "" : ", ", ratings_.stall_torque,
                    ratings_.no_load_speed);
      list += b;
    }
    return s + list + ")";
  }
  for (const Exceeded& e : ex) {
    char b[256];
    if (e.rating == "rated_torque")
      std::snprintf(b, sizeof b, "; EXCEEDS rated_torque %.4g N m: RMS torque %.4g N m (%.0f%% over)", e.limit, e.worst,
                    100 * (e.worst / e.limit - 1));
    else if (e.rating == "torque-speed line")
      std::snprintf(b, sizeof b,
                    "; EXCEEDS the torque-speed line (stall %.4g N m, no-load %.4g rad/s) from t = %.4g s: worst "
                    "%.4g N m at t = %.4g s, %.0f%% of the stall torque above the line",
                    ratings_.stall_torque, ratings_.no_load_speed, e.first_time, e.worst, e.worst_time,
                    100 * worst_[2].ratio);
    else
      std::snprintf(b, sizeof b, "; EXCEEDS %s %.4g %s from t = %.4g s: worst %.4g at t = %.4g s (%.0f%% over)",
                    e.rating.c_str(), e.limit, e.rating == "max_speed" ? "rad/s" : "N m", e.first_time, e.worst,
                    e.worst_time, 100 * (std::fabs(e.worst) / e.limit - 1));
    s += b;
  }
  return s;
}

}  // namespace mechanism_sim
