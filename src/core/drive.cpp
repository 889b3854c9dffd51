// Drives: prescribed motion of a joint coordinate as a rheonomic constraint (drive.h).
#include "mechanism_sim/core/drive.h"

#include <cmath>
#include <stdexcept>

namespace mechanism_sim {

void DriveRamp::eval(double t, double* f, double* f_dot, double* f_ddot) const {
  const double tau = t - t0;
  const double dv = v1 - v0;
  const double T = (acc > 0 && dv != 0) ? std::fabs(dv) / acc : 0.0;  // ramp duration
  const double a = dv > 0 ? acc : -acc;
  if (tau < T) {
    *f = q0 + v0 * tau + 0.5 * a * tau * tau;
    *f_dot = v0 + a * tau;
    *f_ddot = a;
  } else {
    *f = q0 + v0 * T + 0.5 * a * T * T + v1 * (tau - T);
    *f_dot = v1;
    *f_ddot = 0.0;
  }
}

DriveProfile DriveProfile::velocity(double v) {
  if (!std::isfinite(v)) throw std::invalid_argument("drive velocity must be finite");
  DriveProfile p;
  p.kind_ = Kind::kVelocity;
  p.v_ = v;
  return p;
}

DriveProfile DriveProfile::harmonic(double offset, double amplitude, double frequency, double phase) {
  if (!std::isfinite(offset) || !std::isfinite(amplitude) || !std::isfinite(frequency) || !std::isfinite(phase))
    throw std::invalid_argument("harmonic drive: offset, amplitude, frequency and phase must be finite");
  DriveProfile p;
  p.kind_ = Kind::kHarmonic;
  p.offset_ = offset, p.amplitude_ = amplitude, p.omega_ = 2.0 * M_PI * frequency, p.phase_ = phase;
  return p;
}

// Natural cubic spline (second derivatives m_i, m_0 = m_n = 0), from the tridiagonal
// system  h_{i-1} m_{i-1} + 2 (h_{i-1} + h_i) m_i + h_i m_{i+1} = 6 (s_i - s_{i-1}),
// s_i = (q_{i+1} - q_i) / h_i (de Boor, A Practical Guide to Splines, ch. IV).
DriveProfile DriveProfile::spline(const std::vector<double>& t, const std::vector<double>& q) {
  const size_t n = t.size();
  if (n < 2 || q.size() != n) throw std::invalid_argument("spline drive: needs at least 2 points");
  for (size_t i = 0; i < n; ++i) {
    if (!std::isfinite(t[i]) || !std::isfinite(q[i]))
      throw std::invalid_argument("spline drive: point " + std::to_string(i + 1) + " is not finite");
    if (i > 0 && !(t[i] > t[i - 1]))
      throw std::invalid_argument("spline drive: times must increase (point " + std::to_string(i + 1) + ")");
  }
  DriveProfile p;
  p.kind_ = Kind::kSpline;
  p.t_ = t, p.q_ = q;
  p.m_.assign(n, 0.0);
  if (n > 2) {  // Thomas algorithm on the interior unknowns m_1 .. m_{n-2}
    const size_t k = n - 2;
    std::vector<double> diag(k), upper(k), rhs(k);
    for (size_t i = 1; i + 1 < n; ++i) {
      const double h0 = t[i] - t[i - 1], h1 = t[i + 1] - t[i];
      diag[i - 1] = 2.0 * (h0 + h1);
      upper[i - 1] = h1;
      rhs[i - 1] = 6.0 * ((q[i + 1] - q[i]) / h1 - (q[i] - q[i - 1]) / h0);
    }
    for (size_t i = 1; i < k; ++i) {
      const double lower = t[i + 1] - t[i];  // h_{i} multiplies m_{i} in row i+1
      const double w = lower / diag[i - 1];
      diag[i] -= w * upper[i - 1];
      rhs[i] -= w * rhs[i - 1];
    }
    p.m_[k] = rhs[k - 1] / diag[k - 1];
    for (size_t i = k - 1; i-- > 0;) p.m_[i + 1] = (rhs[i] - upper[i] * p.m_[i + 2]) / diag[i];
  }
  return p;
}

void DriveProfile::eval(double t, const DriveRamp& ramp, double* f, double* f_dot, double* f_ddot) const {
  switch (kind_) {
    case Kind::kVelocity:
      ramp.eval(t, f, f_dot, f_ddot);
      return;
    case Kind::kHarmonic: {
      const double a = omega_ * t + phase_;
      *f = offset_ + amplitude_ * std::sin(a);
      *f_dot = amplitude_ * omega_ * std::cos(a);
      *f_ddot = -amplitude_ * omega_ * omega_ * std::sin(a);
      return;
    }
    case Kind::kSpline: {
      const size_t n = t_.size();
      if (t <= t_[0] || t >= t_[n - 1]) {  // linear continuation with the end slope
        const bool lo = t <= t_[0];
        const size_t i = lo ? 0 : n - 2;
        const double h = t_[i + 1] - t_[i];
        const double slope = (q_[i + 1] - q_[i]) / h +
                             (lo ? -h * (2 * m_[i] + m_[i + 1]) / 6.0 : h * (m_[i] + 2 * m_[i + 1]) / 6.0);
        const double t_end = lo ? t_[0] : t_[n - 1];
        *f = (lo ? q_[0] : q_[n - 1]) + slope * (t - t_end);
        *f_dot = slope;
        *f_ddot = 0.0;
        return;
      }
      size_t i = 0, hi = n - 1;  // binary search: t_[i] <= t < t_[i+1]
      while (hi - i > 1) {
        const size_t mid = (i + hi) / 2;
        (t_[mid] <= t ? i : hi) = mid;
      }
      const double h = t_[i + 1] - t_[i];
      const double A = (t_[i + 1] - t) / h, B = (t - t_[i]) / h;
      *f = A * q_[i] + B * q_[i + 1] + ((A * A * A - A) * m_[i] + (B * B * B - B) * m_[i + 1]) * h * h / 6.0;
      *f_dot = (q_[i + 1] - q_[i]) / h + (-(3 * A * A - 1) * m_[i] + (3 * B * B - 1) * m_[i + 1]) * h / 6.0;
      *f_ddot = A * m_[i] + B * m_[i + 1];
      return;
    }
  }
}

void DriveConstraint::velocityTerm(const EvalContext& ctx, double* nu) const {
  double f, f_dot, f_ddot;
  profile_.eval(ctx.t, ctx.drive[drive_], &f, &f_dot, &f_ddot);
  nu[0] = f_dot;  // nu = -Phi_t
}

// Phi = q_k - f(t); Phi_q = G_k; gamma = gamma_k + f_ddot (from q_ddot_k = G_k a - gamma_k).
void DriveConstraint::evaluate(const BodyKin* const* kin, const EvalContext& ctx,
                               Eigen::Ref<Eigen::VectorXd> Phi, Eigen::Ref<Eigen::MatrixXd> J,
                               Eigen::Ref<Eigen::VectorXd> gamma) const {
  Row rows[3];
  joint_.coordinates(*kin[0], *kin[1], ctx.tracked[joint_.id()], rows);
  double f, f_dot, f_ddot;
  profile_.eval(ctx.t, ctx.drive[drive_], &f, &f_dot, &f_ddot);
  Phi(0) = rows[k_].Phi - f;
  J.row(0) = rows[k_].J;
  gamma(0) = rows[k_].gamma + f_ddot;
}

}  // namespace mechanism_sim
