// Prescribed motion of one joint coordinate (a drive, ADAMS' "motion"): the rheonomic
// equation  Phi(q, t) = q_k(q) - f(t) = 0  among the other constraints. Its multiplier is
// the effort the drive must supply along q_k (tau = -lambda, as for a limit).
//   velocity:  Phi_q v = q_x,k v = f_dot(t)      (the velocity equation's right-hand side
//                                                  nu = -Phi_t = f_dot)
//   accel.:    Phi_q a = gamma_k + f_ddot(t)     (q_ddot = q_x,k a - gamma_k, joint.h)
#pragma once
#include <array>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "mechanism_sim/core/model/joint.h"

namespace mechanism_sim {

// One knot of a path: time, position, velocity, acceleration.
struct PathKnot {
  double t = 0.0, q = 0.0, v = 0.0, a = 0.0;
};

// A path for a drive to follow (a joint trajectory, doc/trajectories.md): between knots a
// quintic Hermite polynomial matching position, velocity and acceleration at both ends, so
// the path is C2 whatever the knots. Before the first knot it continues the first
// segment's polynomial; past the last knot it goes on at the last velocity (acceleration
// 0: C2 when the last knot's acceleration is 0, as through() makes it unless given).
// Immutable; a State shares it (DriveRamp::path).
class DrivePath {
 public:
  // Throws UsageError: no knot, times not increasing, a value not finite.
  explicit DrivePath(std::vector<PathKnot> knots);
  // The path from a drive's motion `start` through points (t_i > start.t, q_i), with their
  // velocities v_i and accelerations a_i where given (an empty vector: not given):
  //   - velocities not given: a C2 cubic spline through the positions, clamped at both
  //     ends (start.v; at rest, v = 0, at the last point);
  //   - accelerations not given: at an interior point the mean of the accelerations the two
  //     cubic Hermite segments beside it have there (equal for a cubic spline, so a cubic
  //     spline is kept as it is), 0 at the last point;
  //   - the first knot is `start`, its acceleration included.
  // Every segment is then the quintic Hermite through its two knots. Throws
  // UsageError as the constructor, or for arrays of different lengths.
  static DrivePath through(const PathKnot& start, const std::vector<double>& t, const std::vector<double>& q,
                           const std::vector<double>& v = {}, const std::vector<double>& a = {});
  void eval(double t, double* q, double* q_dot, double* q_ddot) const;
  const std::vector<PathKnot>& knots() const { return knots_; }

 private:
  std::vector<PathKnot> knots_;
  std::vector<std::array<double, 6>> c_;  // per segment: q = sum c_k (t - t_i)^k
};

// How far a drive's reference lags behind its profile (the saturating mode, doc/actuators.md:
// an actuator that cannot give what the profile asks holds the drive back). The drive's
// equation becomes q_k = f(t) - d(t), with d a quadratic from t0,
//   d(t) = d0 + d0_dot (t - t0) + 1/2 d_ddot (t - t0)^2,
// chosen anew at every accepted state (Mechanism's saturation): the motion the bounded
// torque produces, or the way back onto the profile. Inactive (the profile exactly) unless
// an actuator held it back; `saturated`: the actuator is at its envelope at this state.
struct DriveLag {
  bool active = false, saturated = false;
  double t0 = 0.0, d0 = 0.0, d0_dot = 0.0, d_ddot = 0.0;
  // what the equation reads (saturated only says why)
  bool operator==(const DriveLag& o) const {
    return active == o.active && t0 == o.t0 && d0 == o.d0 && d0_dot == o.d0_dot && d_ddot == o.d_ddot;
  }
  void eval(double t, double* d, double* d_dot, double* d_ddot_out) const {
    const double tau = t - t0;
    *d = d0 + d0_dot * tau + 0.5 * d_ddot * tau * tau;
    *d_dot = d0_dot + d_ddot * tau;
    *d_ddot_out = d_ddot;
  }
};

// A velocity drive's reference, part of the State (it changes when a new velocity or a
// path is commanded): from t0 the coordinate leaves q0 at v0 and its velocity moves to v1
// at constant acceleration acc (acc <= 0: at once), then stays at v1. Position and
// velocity are continuous across a command; the acceleration steps by at most acc. With a
// path (Mechanism::commandDrivePath) the path is the reference instead.
struct DriveRamp {
  DriveRamp() = default;
  DriveRamp(double t0_, double q0_, double v0_, double v1_, double acc_, std::shared_ptr<const DrivePath> path_ = nullptr)
      : t0(t0_), q0(q0_), v0(v0_), v1(v1_), acc(acc_), path(std::move(path_)) {}
  double t0 = 0.0, q0 = 0.0, v0 = 0.0, v1 = 0.0, acc = 0.0;
  std::shared_ptr<const DrivePath> path;  // immutable, so a copied State may share it
  DriveLag lag;  // behind the profile (saturating mode); kept across commands
  bool operator==(const DriveRamp& o) const {
    return t0 == o.t0 && q0 == o.q0 && v0 == o.v0 && v1 == o.v1 && acc == o.acc && path == o.path && lag == o.lag;
  }
  // f(t), f_dot(t), f_ddot(t)
  void eval(double t, double* f, double* f_dot, double* f_ddot) const;
};

// What a drive prescribes: a velocity or a path (from the State's DriveRamp), a harmonic
// q = offset + amplitude sin(2 pi frequency t + phase), or a natural cubic spline through
// points (t_i, q_i) (C2; continued linearly past its ends, where its second derivative
// is zero, so it stays C2).
class DriveProfile {
 public:
  enum class Kind { kVelocity, kHarmonic, kSpline };
  static DriveProfile velocity(double v);
  static DriveProfile harmonic(double offset, double amplitude, double frequency, double phase);
  // Throws UsageError: fewer than 2 points, times not increasing, not finite.
  static DriveProfile spline(const std::vector<double>& t, const std::vector<double>& q);

  Kind kind() const { return kind_; }
  double velocity() const { return v_; }
  // f, f_dot, f_ddot at t (the velocity kind reads the ramp).
  void eval(double t, const DriveRamp& ramp, double* f, double* f_dot, double* f_ddot) const;

 private:
  Kind kind_ = Kind::kVelocity;
  double v_ = 0.0;
  double offset_ = 0.0, amplitude_ = 0.0, omega_ = 0.0, phase_ = 0.0;
  std::vector<double> t_, q_, m_;  // knots, values, second derivatives
};

// Phi = q_k - f(t) on coordinate k of a joint (one row); f - d(t) while the State's DriveLag
// is active.
class DriveConstraint : public Constraint {
 public:
  DriveConstraint(const Joint& joint, int k, int drive, DriveProfile profile)
      : Constraint(joint.name() + " drive", {joint.bodyI(), joint.bodyJ()}),
        joint_(joint), k_(k), drive_(drive), profile_(std::move(profile)) {}
  std::string type() const override { return "drive"; }
  int size() const override { return 1; }
  bool rheonomic() const override { return true; }
  void velocityTerm(const EvalContext& ctx, double* nu) const override;
  void evaluate(const BodyKin* const* kin, const EvalContext& ctx, Eigen::Ref<Eigen::VectorXd> Phi,
                Eigen::Ref<Eigen::MatrixXd> J, Eigen::Ref<Eigen::VectorXd> gamma) const override;
  const Joint& joint() const { return joint_; }
  int coordinate() const { return k_; }
  int drive() const override { return drive_; }
  const Joint* jointOn(int b) const override { return joint_.jointOn(b); }
  // -lambda along q_k
  int coordinateEfforts(const EvalContext& /*ctx*/, CoordinateEffort* out) const override {
    out[0] = {&joint_, k_, -1.0};
    return 1;
  }
  const DriveProfile& profile() const { return profile_; }

 private:
  const Joint& joint_;
  int k_, drive_;
  DriveProfile profile_;
};

}  // namespace mechanism_sim
