// The saturating mode (mechanism.h, doc/actuators.md): actuators that bound their drives.
//
// A drive stays an exact equation, q_k = f(t) - d(t), its lag d a quadratic the State holds
// (DriveLag). An actuator's own lag is its drive's (a simple transmission) or, behind a
// differential or a four-bar, delta_i = E_i d over its two drives, the joints' lags being
// d = E^-1 delta (actuator_limits.h): a motor at its bound lets its own coordinate fall
// behind while the other follows its profile. At every accepted state the actuators' lag
// accelerations are chosen:
//  1. the actuator torques tau_0 with every lag's acceleration 0 there (the base);
//  2. the way back onto the profile each lag wants, a critically damped approach of rate
//     w = kRejoinRate / h,  d_ddot = -2 w d_dot - w^2 d  (0 while a drive follows its
//     profile; an actuator's, E_i of its drives');
//  3. the torques are affine in the lags' accelerations (the multipliers of the KKT system
//     are linear in its right-hand side, and the speed is the state's): tau = tau_0 + S x, a
//     column of S per actuator that wants a way back or is outside its bounds, from one
//     solve with that actuator's lag acceleration 1. Where a torque at the ways back is
//     outside its bounds (torqueBounds at the actuator's speed) its lag acceleration becomes
//     the one at which it equals the bound; the held set grows by the torque furthest
//     outside, one a pass, until no other torque is outside (an active set over the
//     actuators, S's square block solved for their x), and the state is solved with the
//     accelerations found.
// The motion then is the one the bounded torque produces: at a winch's steady state
// (d_ddot = 0) the motor's torque is its line's at that speed, whatever h. (Taking the base
// at 0 keeps the held torque exact: a way back asks accelerations of order d / h^2, whose
// torques would cancel to round-off of their own size.) A lag within kRejoined of the
// profile at a state (position, and rate over a step) is 0 there: the drive follows its
// profile exactly again (the lag inactive).
#include <algorithm>
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
    auto inRange = [&](int j, int k) { return j >= 0 && j < numJoints() && k >= 0 && k < joint(j).dof(); };
    if (L.coords.empty()) {
      if (!inRange(L.joint, L.k)) throw UsageError("actuator '" + L.name + "': no such joint coordinate");
      if (!std::isfinite(L.reduction) || L.reduction == 0.0)
        throw UsageError("actuator '" + L.name + "': its reduction must be finite and not zero");
    }
    for (const ActuatorCoordinate& c : L.coords) {
      if (!inRange(c.joint, c.k)) throw UsageError("actuator '" + L.name + "': no such joint coordinate");
      if (!std::isfinite(c.speed) || !std::isfinite(c.torque) || !std::isfinite(c.lag))
        throw UsageError("actuator '" + L.name + "': its transmission's rows must be finite");
    }
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
    for (const ActuatorLimit& L : limits) {
      bounded = bounded || (L.coords.empty() && driveOf(L.joint, L.k) == d);
      for (const ActuatorCoordinate& c : L.coords) bounded = bounded || driveOf(c.joint, c.k) == d;
    }
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
  // what the actuators supply at a coordinate: its command and its drive's effort (the
  // motor's own damping and friction act on the motion through the transmission, so the
  // drive's effort already overcomes them: MechanismModel::actuatorState)
  auto supplied = [&](int j, int k) {
    double tau_q = inputs_.effort[j][k];
    const int d = driveOf(j, k);
    if (d >= 0) tau_q -= state_.lambda[sys_->layout[sys_->drives[d].constraint].row];
    return tau_q;
  };
  if (L.coords.empty()) return supplied(L.joint, L.k) / L.reduction;
  double tau = 0.0;  // tau_theta_i = (E^-T)_i tau_q
  for (const ActuatorCoordinate& c : L.coords) tau += c.torque * supplied(c.joint, c.k);
  return tau;
}

namespace {
// A drive an actuator's lag moves, by `lag` per unit of the actuator's own lag.
struct LagTerm {
  int drive;
  double lag;
};
}  // namespace

void Mechanism::saturate(double h) {
  stateChanged();
  const int n = static_cast<int>(actuator_limits_.size());
  // per actuator: the drives its lag moves (empty: it bounds none now) and its speed
  std::vector<std::vector<LagTerm>> terms(n);
  std::vector<TorqueBounds> bounds(n);
  std::vector<double> want(n, 0.0);  // each actuator's lag acceleration of the way back
  std::vector<int> used;             // the drives the actuators bound, each once
  std::vector<double> drive_want(numDrives(), 0.0);
  std::vector<char> seen(numDrives(), 0);
  for (int i = 0; i < n; ++i) {
    const ActuatorLimit& L = actuator_limits_[i];
    double omega = 0.0;
    if (L.coords.empty()) {
      const int d = driveOf(L.joint, L.k);
      if (d >= 0) terms[i].push_back({d, 1.0});
      omega = L.reduction * jointVelocity(L.joint, L.k);
    } else {
      for (const ActuatorCoordinate& c : L.coords) {
        const int d = driveOf(c.joint, c.k);
        if (d < 0) {  // (a coordinate its drives do not hold: its lag has nowhere to go)
          terms[i].clear();
          break;
        }
        terms[i].push_back({d, c.lag});
        omega += c.speed * jointVelocity(c.joint, c.k);
      }
    }
    if (terms[i].empty()) continue;
    bounds[i] = torqueBounds(L.ratings, omega);
    for (const LagTerm& t : terms[i])
      if (!seen[t.drive]) seen[t.drive] = 1, used.push_back(t.drive);
  }
  // 1. each lag moved on to this state with acceleration 0 there (the torques' base)
  bool lagging = false;
  const double w = h > 0 ? kRejoinRate / h : 0.0;  // (h = 0: no step to choose a way back for)
  for (int d : used) {
    DriveLag& lag = state_.drive[d].lag;
    if (!lag.active) continue;
    const DriveSpec& D = sys_->drives[d];
    double x, x_dot, x_ddot;
    lag.eval(state_.t, &x, &x_dot, &x_ddot);
    const double unit = joint(D.joint).trackedSlot(D.k) >= 0 ? 1.0 : sys_->length_scale;
    const double scale = kRejoined * (std::fabs(jointPosition(D.joint, D.k)) + unit);
    if (std::fabs(x) <= scale && std::fabs(x_dot) * h <= scale) x = x_dot = 0.0;
    lag.t0 = state_.t, lag.d0 = x, lag.d0_dot = x_dot, lag.d_ddot = 0.0;
    drive_want[d] = -(2.0 * w * x_dot + w * w * x);
    lagging = true;
  }
  // an actuator's way back: its own lag's, delta = E d (a simple transmission's is its drive's)
  for (int i = 0; i < n; ++i) {
    if (terms[i].empty()) continue;
    const ActuatorLimit& L = actuator_limits_[i];
    if (L.coords.empty()) {
      want[i] = drive_want[terms[i][0].drive];
      continue;
    }
    for (size_t c = 0; c < L.coords.size(); ++c) want[i] += L.coords[c].speed * drive_want[terms[i][c].drive];
  }
  if (lagging) running_->resolve(*sys_, state_, inputs_), stateChanged();
  std::vector<double> tau(n, 0.0);
  for (int i = 0; i < n; ++i)
    if (!terms[i].empty()) tau[i] = limitedActuatorTorque(i);
  // 2. column j of S: the torques' change per unit of actuator j's lag acceleration (one
  //    solve from the base); needed for the actuators that want a way back and those outside
  Eigen::MatrixXd S = Eigen::MatrixXd::Zero(n, n);
  std::vector<char> known(n, 0), movable(n, 0);
  bool moved = false;  // (a column's solve left the state elsewhere: solved again below)
  std::vector<DriveLag> kept;
  auto column = [&](int j) {
    known[j] = 1;
    kept.clear();
    for (const LagTerm& t : terms[j]) {
      DriveLag& lag = state_.drive[t.drive].lag;
      kept.push_back(lag);
      if (!lag.active) lag = DriveLag{}, lag.active = true, lag.t0 = state_.t;
      lag.d_ddot = t.lag;
    }
    running_->resolve(*sys_, state_, inputs_);
    stateChanged();
    moved = true;
    for (int i = 0; i < n; ++i) S(i, j) = terms[i].empty() ? 0.0 : limitedActuatorTorque(i) - tau[i];
    for (size_t c = 0; c < terms[j].size(); ++c) state_.drive[terms[j][c].drive].lag = kept[c];
    // (an actuator whose lag does not move its torque cannot be relieved by a lag)
    movable[j] = std::isfinite(S(j, j)) && S(j, j) != 0.0;
  };
  for (int i = 0; i < n; ++i)
    if (!terms[i].empty() && want[i] != 0.0) column(i);
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
  // One actuator joins the held set a pass, the one furthest outside its bounds (in parts
  // of its bound), and the others are predicted again: holding one moves the others'
  // torques (a differential's two motors share both joints), so one outside at the ways
  // back may be inside once another is held.
  std::vector<char> held(n, 0);
  for (int pass = 0; pass <= n; ++pass) {
    int worst = -1;
    double worst_out = 0.0;
    for (int i = 0; i < n; ++i) {
      if (terms[i].empty() || held[i] || !(now[i] > bounds[i].hi || now[i] < bounds[i].lo)) continue;
      if (!known[i]) column(i);
      if (!movable[i]) continue;
      const double out = std::max(now[i] - bounds[i].hi, bounds[i].lo - now[i]) /
                         std::max({std::fabs(bounds[i].lo), std::fabs(bounds[i].hi), std::numeric_limits<double>::min()});
      if (worst < 0 || out > worst_out) worst = i, worst_out = out;
    }
    if (worst < 0) break;
    held[worst] = 1;
    target[worst] = std::min(std::max(now[worst], bounds[worst].lo), bounds[worst].hi);
    active.push_back(worst);
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
  // 4. the drives' lag accelerations, d_ddot = sum_i a_i (E^-1)_{:,i} over their actuators,
  //    and the state solved with them
  std::vector<double> d_ddot(numDrives(), 0.0);
  std::vector<char> set(numDrives(), 0), saturated(numDrives(), 0);
  for (int i = 0; i < n; ++i)
    for (const LagTerm& t : terms[i]) {
      d_ddot[t.drive] = set[t.drive] ? d_ddot[t.drive] + t.lag * a[i] : t.lag * a[i];
      set[t.drive] = 1;
      saturated[t.drive] = saturated[t.drive] || held[i];
    }
  for (int d : used) {
    DriveLag& lag = state_.drive[d].lag;
    lag.saturated = saturated[d];
    if (saturated[d] && !lag.active) lag = DriveLag{}, lag.active = true, lag.t0 = state_.t, lag.saturated = true;
    if (lag.active) lag.d_ddot = d_ddot[d];
    if (d_ddot[d] != 0.0) moved = true;
  }
  if (moved) running_->resolve(*sys_, state_, inputs_), stateChanged();
  // 5. a lag back on the profile and not held is none
  for (int d : used) {
    DriveLag& lag = state_.drive[d].lag;
    if (lag.active && !lag.saturated && lag.d0 == 0.0 && lag.d0_dot == 0.0 && lag.d_ddot == 0.0) lag = DriveLag{};
  }
  saturation_current_ = true;
}

}  // namespace mechanism_sim
