// The saturating mode (mechanism.h, doc/actuators.md): actuators that bound their drives.
//
// A drive stays an exact equation, q_k = f(t) - d(t), its lag d a quadratic the State holds
// (DriveLag). At every accepted state the lag's acceleration d_ddot is chosen:
//  1. the actuator torques tau_0 with every lag's acceleration 0 there (the base);
//  2. the way back onto the profile each lag wants, a critically damped approach of rate
//     w = kRejoinRate / h,  d_ddot = -2 w d_dot - w^2 d  (0 while a drive follows its profile);
//  3. the torques are affine in the lags' accelerations (the multipliers of the KKT system
//     are linear in its right-hand side, and the speed is the state's): tau = tau_0 + S x, a
//     column of S per drive that wants a way back or is outside its bounds, from one solve
//     with that drive's d_ddot = 1. Where a torque at the ways back is outside its bounds
//     (torqueBounds at the actuator's speed) its drive's d_ddot becomes the one at which it
//     equals the bound; the held set grows until no other torque is outside (an active set
//     over the drives, S's square block solved for their x), and the state is solved with
//     the accelerations found.
// The motion then is the one the bounded torque produces: at a winch's steady state
// (d_ddot = 0) the motor's torque is its line's at that speed, whatever h. (Taking the base
// at 0 keeps the held torque exact: a way back asks accelerations of order d / h^2, whose
// torques would cancel to round-off of their own size.) A lag within kRejoined of the
// profile at a state (position, and rate over a step) is 0 there: the drive follows its
// profile exactly again (the lag inactive).
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
  // A drive behind its profile that no actuator bounds any more keeps its lag as it stands
  // and moves with its profile from here (its velocity onto the profile's at once).
  bool freed = false;
  for (int d = 0; built_ && d < numDrives(); ++d) {
    DriveLag& lag = state_.drive[d].lag;
    if (!lag.active) continue;
    bool bounded = false;
    for (const ActuatorLimit& L : limits) bounded = bounded || driveOf(L.joint, L.k) == d;
    if (bounded) continue;
    double x, x_dot, x_ddot;
    lag.eval(state_.t, &x, &x_dot, &x_ddot);
    lag = DriveLag{};
    lag.active = true, lag.t0 = state_.t, lag.d0 = x;
    freed = true;
  }
  actuator_limits_ = std::move(limits);
  stateChanged();
  if (freed) running_->settle(*sys_, state_, inputs_);
  // the state as it stands within the bounds (its lags' ways back are chosen by the next
  // step, which knows its h)
  if (built_ && running_ && !actuator_limits_.empty()) saturate(0.0), saturation_current_ = false;
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
  // (the motor's own damping and friction act on the motion through the transmission, so
  // the drive's effort already overcomes them: MechanismModel::actuatorState)
  return tau_q / L.reduction;
}

void Mechanism::saturate(double h) {
  stateChanged();
  const int n = static_cast<int>(actuator_limits_.size());
  std::vector<int> drive(n, -1);
  std::vector<TorqueBounds> bounds(n);
  std::vector<double> want(n, 0.0);  // each lag's acceleration of the way back
  // 1. each lag moved on to this state with acceleration 0 there (the torques' base)
  bool lagging = false;
  const double w = h > 0 ? kRejoinRate / h : 0.0;  // (h = 0: no step to choose a way back for)
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
    lag.t0 = state_.t, lag.d0 = d, lag.d0_dot = d_dot, lag.d_ddot = 0.0;
    want[i] = -(2.0 * w * d_dot + w * w * d);
    lagging = true;
  }
  if (lagging) running_->resolve(*sys_, state_, inputs_), stateChanged();
  std::vector<double> tau(n, 0.0);
  for (int i = 0; i < n; ++i)
    if (drive[i] >= 0) tau[i] = limitedActuatorTorque(i);
  // 2. column j of S: the torques' change per unit of drive j's lag acceleration (one solve
  //    from the base); needed for the drives that want a way back and those outside
  Eigen::MatrixXd S = Eigen::MatrixXd::Zero(n, n);
  std::vector<char> known(n, 0), movable(n, 0);
  bool moved = false;  // (a column's solve left the state elsewhere: solved again below)
  auto column = [&](int j) {
    known[j] = 1;
    DriveLag& lag = state_.drive[drive[j]].lag;
    const DriveLag kept = lag;
    if (!lag.active) lag = DriveLag{}, lag.active = true, lag.t0 = state_.t;
    lag.d_ddot = 1.0;
    running_->resolve(*sys_, state_, inputs_);
    stateChanged();
    moved = true;
    for (int i = 0; i < n; ++i) S(i, j) = drive[i] >= 0 ? limitedActuatorTorque(i) - tau[i] : 0.0;
    lag = kept;
    // (a drive whose acceleration does not move its torque cannot be relieved by a lag)
    movable[j] = std::isfinite(S(j, j)) && S(j, j) != 0.0;
  };
  for (int i = 0; i < n; ++i)
    if (drive[i] >= 0 && want[i] != 0.0) column(i);
  // 3. the torques at the ways back; those outside their bounds held at them (an active set)
  std::vector<double> a = want, now(n);
  std::vector<int> active;
  std::vector<double> target(n, 0.0);
  auto predict = [&]() {
    for (int i = 0; i < n; ++i) {
      now[i] = tau[i];
      for (int j = 0; j < n; ++j)
        if (known[j]) now[i] += S(i, j) * a[j];
    }
  };
  predict();
  std::vector<char> held(n, 0);
  for (int pass = 0; pass <= n; ++pass) {
    bool grew = false;
    for (int i = 0; i < n; ++i) {
      if (drive[i] < 0 || held[i] || !(now[i] > bounds[i].hi || now[i] < bounds[i].lo)) continue;
      if (!known[i]) column(i);
      if (!movable[i]) continue;
      held[i] = 1, grew = true;
      target[i] = std::min(std::max(now[i], bounds[i].lo), bounds[i].hi);
      active.push_back(i);
    }
    if (!grew) break;
    // S_AA a_A = target_A - tau_A - S_AF a_F
    const int m = static_cast<int>(active.size());
    Eigen::MatrixXd A(m, m);
    Eigen::VectorXd r(m);
    for (int p = 0; p < m; ++p) {
      const int i = active[p];
      r[p] = target[i] - tau[i];
      for (int j = 0; j < n; ++j)
        if (known[j] && !held[j]) r[p] -= S(i, j) * a[j];
      for (int q = 0; q < m; ++q) A(p, q) = S(i, active[q]);
    }
    const Eigen::VectorXd x = A.partialPivLu().solve(r);
    for (int p = 0; p < m; ++p) a[active[p]] = x[p];
    predict();
  }
  // 4. the lags' accelerations, and the state solved with them
  for (int i = 0; i < n; ++i) {
    if (drive[i] < 0) continue;
    DriveLag& lag = state_.drive[drive[i]].lag;
    lag.saturated = held[i];
    if (held[i] && !lag.active) lag = DriveLag{}, lag.active = true, lag.t0 = state_.t, lag.saturated = true;
    if (lag.active) lag.d_ddot = a[i];
    if (a[i] != 0.0) moved = true;
  }
  if (moved) running_->resolve(*sys_, state_, inputs_), stateChanged();
  // 5. a lag back on the profile and not held is none
  for (int i = 0; i < n; ++i) {
    if (drive[i] < 0) continue;
    DriveLag& lag = state_.drive[drive[i]].lag;
    if (lag.active && !lag.saturated && lag.d0 == 0.0 && lag.d0_dot == 0.0 && lag.d_ddot == 0.0) lag = DriveLag{};
  }
  saturation_current_ = true;
}

}  // namespace mechanism_sim
