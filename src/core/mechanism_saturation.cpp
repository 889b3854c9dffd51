// The saturating mode (mechanism.h, doc/actuators.md): actuators that bound their drives.
//
// A drive stays an exact equation, q_k = f(t) - d(t), its lag d a quadratic the State holds
// (DriveLag). At every accepted state the lag's acceleration d_ddot is chosen:
//  1. the way back onto the profile, a critically damped approach of rate w = kRejoinRate / h,
//       d_ddot = -2 w d_dot - w^2 d        (0 while the drive follows its profile);
//  2. the actuator torques at those accelerations; where one is outside its bounds
//     (torqueBounds at the actuator's speed), its drive's d_ddot becomes the one at which the
//     torque equals the bound. The torques are affine in the lags' accelerations (the
//     multipliers of the KKT system are linear in its right-hand side, and the speed is the
//     state's): tau = tau_0 + S x, a column of S per bounded drive from one solve with that
//     drive's d_ddot moved. The bounded set grows until no other torque is outside
//     (an active set over the drives, S's square block solved for their x).
// The motion then is the one the bounded torque produces: at a winch's steady state
// (d_ddot = 0) the motor's torque is its line's at that speed, whatever h. A lag within
// kRejoined of the profile at a state (position, and rate over a step) is 0 there: the
// drive follows its profile exactly again (the lag inactive).
#include <cmath>
#include <limits>
#include <sstream>

#include <Eigen/Dense>

#include "core/formulation.h"
#include "mechanism_sim/core/mechanism.h"

namespace mechanism_sim {

namespace {

// w h of the way back onto the profile: the lag's step map (exact for d_ddot held over the
// step) has real eigenvalues 0.70 and 0.18 at w h = 1/2, so the lag decays without
// overshoot, by about 1e-12 in 80 steps.
constexpr double kRejoinRate = 0.5;
// A lag this small relative to the coordinate's scale (its value plus one radian or the
// length scale) is none: far below what the projections hold the drive's equation to.
constexpr double kRejoined = 1e-12;

}  // namespace

TorqueBounds torqueBounds(const ActuatorRatings& r, double omega) {
  const double inf = std::numeric_limits<double>::infinity();
  TorqueBounds b{-inf, inf};
  if (r.peak_torque > 0) b.lo = -r.peak_torque, b.hi = r.peak_torque;
  if (r.stall_torque > 0) {
    const double motoring = r.stall_torque * std::max(0.0, 1.0 - std::fabs(omega) / r.no_load_speed);
    // motoring: torque of the speed's sign; braking: against it (at rest both are motoring)
    const double up = omega < 0 ? r.stall_torque : motoring;
    const double down = omega > 0 ? r.stall_torque : motoring;
    b.hi = std::min(b.hi, up);
    b.lo = std::max(b.lo, -down);
  }
  return b;
}

void Mechanism::setActuatorLimits(std::vector<ActuatorLimit> limits) {
  for (const ActuatorLimit& L : limits) {
    if (L.joint < 0 || L.joint >= numJoints() || L.k < 0 || L.k >= joint(L.joint).dof())
      throw UsageError("actuator '" + L.name + "': no such joint coordinate");
    if (!std::isfinite(L.reduction) || L.reduction == 0.0)
      throw UsageError("actuator '" + L.name + "': its reduction must be finite and not zero");
    try {
      L.ratings.validate(L.name);
    } catch (const ModelError& e) {
      throw UsageError(e.what());
    }
  }
  actuator_limits_ = std::move(limits);
  saturation_current_ = false;
}

double Mechanism::driveLag(int drive) const {
  const DriveLag& lag = state_.drive.at(drive).lag;
  if (!lag.active) return 0.0;
  double d, d_dot, d_ddot;
  lag.eval(state_.t, &d, &d_dot, &d_ddot);
  return d;
}

double Mechanism::limitedActuatorTorque(int i) const {
  const ActuatorLimit& L = actuator_limits_.at(i);
  double tau_q = inputs_.effort[L.joint][L.k];
  const int d = driveOf(L.joint, L.k);
  if (d >= 0) tau_q -= state_.lambda[sys_->layout[sys_->drives[d].constraint].row];
  const double omega = L.reduction * jointVelocity(L.joint, L.k);
  const double sign = omega > 0 ? 1.0 : omega < 0 ? -1.0 : 0.0;
  return tau_q / L.reduction + L.ratings.damping * omega + L.ratings.friction * sign;
}

void Mechanism::saturate(double h) {
  stateChanged();
  const int n = static_cast<int>(actuator_limits_.size());
  std::vector<int> drive(n, -1);
  std::vector<TorqueBounds> bounds(n);
  // 1. each lag moved on to this state, and its way back
  bool lagging = false;
  const double w = kRejoinRate / h;
  for (int i = 0; i < n; ++i) {
    const ActuatorLimit& L = actuator_limits_[i];
    drive[i] = driveOf(L.joint, L.k);
    if (drive[i] < 0) continue;
    bounds[i] = torqueBounds(L.ratings, L.reduction * jointVelocity(L.joint, L.k));
    DriveLag& lag = state_.drive[drive[i]].lag;
    if (!lag.active) continue;
    double d, d_dot, d_ddot;
    lag.eval(state_.t, &d, &d_dot, &d_ddot);
    const double unit = joint(L.joint).trackedSlot(L.k) >= 0 ? 1.0 : sys_->length_scale;
    const double scale = kRejoined * (std::fabs(jointPosition(L.joint, L.k)) + unit);
    if (std::fabs(d) <= scale && std::fabs(d_dot) * h <= scale) d = d_dot = 0.0;
    lag.t0 = state_.t, lag.d0 = d, lag.d0_dot = d_dot;
    lag.d_ddot = -(2.0 * w * d_dot + w * w * d);
    lagging = true;
  }
  if (lagging) running_->resolve(*sys_, state_, inputs_), stateChanged();
  // 2. the torques there, and the drives whose actuators they leave outside the bounds
  std::vector<double> tau(n, 0.0), target(n, 0.0);
  for (int i = 0; i < n; ++i)
    if (drive[i] >= 0) tau[i] = limitedActuatorTorque(i);
  std::vector<int> active;
  Eigen::MatrixXd S(n, n);
  bool moved = false;  // (a column's solve left the state at another lag: solved again below)
  // column j of S: the torques' change per unit of drive j's lag acceleration (one solve)
  auto column = [&](int j) {
    DriveLag& lag = state_.drive[drive[j]].lag;
    if (!lag.active) lag = DriveLag{}, lag.active = true, lag.t0 = state_.t;
    const double base = lag.d_ddot, delta = 1.0 + std::fabs(base);
    lag.d_ddot = base + delta;
    running_->resolve(*sys_, state_, inputs_);
    moved = true;
    stateChanged();
    for (int i = 0; i < n; ++i) S(i, j) = drive[i] >= 0 ? (limitedActuatorTorque(i) - tau[i]) / delta : 0.0;
    lag.d_ddot = base;
    // (a drive whose acceleration does not move its torque cannot be relieved by a lag)
    return std::isfinite(S(j, j)) && S(j, j) != 0.0;
  };
  std::vector<char> tried(n, 0);
  Eigen::VectorXd x;
  std::vector<double> now = tau;
  for (int pass = 0; pass <= n; ++pass) {
    bool grew = false;
    for (int i = 0; i < n; ++i) {
      const bool out = drive[i] >= 0 && (now[i] > bounds[i].hi || now[i] < bounds[i].lo);
      if (!out || tried[i]) continue;
      tried[i] = 1;
      target[i] = std::min(std::max(now[i], bounds[i].lo), bounds[i].hi);
      if (column(i)) active.push_back(i), grew = true;
    }
    if (!grew) break;
    const int m = static_cast<int>(active.size());
    Eigen::MatrixXd A(m, m);
    Eigen::VectorXd r(m);
    for (int a = 0; a < m; ++a) {
      r[a] = target[active[a]] - tau[active[a]];
      for (int b = 0; b < m; ++b) A(a, b) = S(active[a], active[b]);
    }
    x = A.partialPivLu().solve(r);
    for (int i = 0; i < n; ++i) {
      now[i] = tau[i];
      for (int a = 0; a < m; ++a) now[i] += S(i, active[a]) * x[a];
    }
  }
  for (int i = 0; i < n; ++i)
    if (drive[i] >= 0) state_.drive[drive[i]].lag.saturated = false;
  for (size_t a = 0; a < active.size(); ++a) {
    DriveLag& lag = state_.drive[drive[active[a]]].lag;
    lag.d_ddot += x[a];
    lag.saturated = true;
  }
  if (moved) running_->resolve(*sys_, state_, inputs_), stateChanged();
  // 3. a lag back on the profile and not held is none
  for (int i = 0; i < n; ++i) {
    if (drive[i] < 0) continue;
    DriveLag& lag = state_.drive[drive[i]].lag;
    if (lag.active && !lag.saturated && lag.d0 == 0.0 && lag.d0_dot == 0.0 && lag.d_ddot == 0.0) lag = DriveLag{};
  }
  saturation_current_ = true;
}

}  // namespace mechanism_sim
