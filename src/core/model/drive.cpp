// Drives: prescribed motion of a joint coordinate as a rheonomic constraint (drive.h).
#include "mechanism_sim/core/model/drive.h"

#include <cmath>

#include "mechanism_sim/core/model/errors.h"

namespace mechanism_sim {

void DriveRamp::eval(double t, double* f, double* f_dot, double* f_ddot) const {
  if (path) return path->eval(t, f, f_dot, f_ddot);
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

// Quintic Hermite segment on [0, h] (tau = t - t_i, dq = q1 - q0): with c0 = q0, c1 = v0,
// c2 = a0 / 2 the three end conditions q(h) = q1, q'(h) = v1, q''(h) = a1 give
//   c3 = (20 dq - (8 v1 + 12 v0) h - (3 a0 - a1) h^2) / (2 h^3)
//   c4 = (-30 dq + (14 v1 + 16 v0) h + (3 a0 - 2 a1) h^2) / (2 h^4)
//   c5 = (12 dq - 6 (v1 + v0) h + (a1 - a0) h^2) / (2 h^5)
DrivePath::DrivePath(std::vector<PathKnot> knots) : knots_(std::move(knots)) {
  if (knots_.empty()) throw UsageError("path: no knot");
  for (size_t i = 0; i < knots_.size(); ++i) {
    const PathKnot& k = knots_[i];
    if (!std::isfinite(k.t) || !std::isfinite(k.q) || !std::isfinite(k.v) || !std::isfinite(k.a))
      throw UsageError("path: knot " + std::to_string(i + 1) + " is not finite");
    if (i > 0 && !(k.t > knots_[i - 1].t))
      throw UsageError("path: times must increase (knot " + std::to_string(i + 1) + ")");
  }
  for (size_t i = 0; i + 1 < knots_.size(); ++i) {
    const PathKnot &k0 = knots_[i], &k1 = knots_[i + 1];
    const double h = k1.t - k0.t, dq = k1.q - k0.q, h2 = h * h;
    c_.push_back({k0.q, k0.v, 0.5 * k0.a,
                  (20 * dq - (8 * k1.v + 12 * k0.v) * h - (3 * k0.a - k1.a) * h2) / (2 * h2 * h),
                  (-30 * dq + (14 * k1.v + 16 * k0.v) * h + (3 * k0.a - 2 * k1.a) * h2) / (2 * h2 * h2),
                  (12 * dq - 6 * (k1.v + k0.v) * h + (k1.a - k0.a) * h2) / (2 * h2 * h2 * h)});
  }
}

// Cubic Hermite segment (q0, v0) -> (q1, v1) over h, s = (q1 - q0) / h: its accelerations
// at the start and at the end.
static double hermiteStartAcceleration(double h, double s, double v0, double v1) { return (6 * s - 4 * v0 - 2 * v1) / h; }
static double hermiteEndAcceleration(double h, double s, double v0, double v1) { return (-6 * s + 2 * v0 + 4 * v1) / h; }

DrivePath DrivePath::through(const PathKnot& start, const std::vector<double>& t, const std::vector<double>& q,
                             const std::vector<double>& v, const std::vector<double>& a) {
  const size_t n = t.size();  // segments; knots 0 (start) .. n
  if (n == 0 || q.size() != n || (!v.empty() && v.size() != n) || (!a.empty() && a.size() != n))
    throw UsageError("path: needs at least one point, and as many values as times");
  std::vector<PathKnot> k(n + 1);
  k[0] = start;
  for (size_t i = 0; i < n; ++i) {
    k[i + 1].t = t[i], k[i + 1].q = q[i];
    if (!std::isfinite(t[i]) || !std::isfinite(q[i]) || (!v.empty() && !std::isfinite(v[i])) ||
        (!a.empty() && !std::isfinite(a[i])))
      throw UsageError("path: point " + std::to_string(i + 1) + " is not finite");
    if (!(t[i] > k[i].t)) throw UsageError("path: times must increase (point " + std::to_string(i + 1) + ")");
  }
  std::vector<double> h(n), s(n);
  for (size_t i = 0; i < n; ++i) h[i] = k[i + 1].t - k[i].t, s[i] = (k[i + 1].q - k[i].q) / h[i];
  if (!v.empty()) {
    for (size_t i = 0; i < n; ++i) k[i + 1].v = v[i];
  } else if (n > 1) {
    // Clamped cubic spline (v_0 = start.v, v_n = 0): continuity of the acceleration at
    // interior knot i, multiplied by h_{i-1} h_i / 2, is
    //   h_i v_{i-1} + 2 (h_{i-1} + h_i) v_i + h_{i-1} v_{i+1} = 3 (h_i s_{i-1} + h_{i-1} s_i)
    // (de Boor, A Practical Guide to Splines, ch. IV); Thomas algorithm on v_1 .. v_{n-1}.
    const size_t m = n - 1;
    std::vector<double> lower(m), diag(m), upper(m), rhs(m);
    for (size_t r = 0; r < m; ++r) {
      const size_t i = r + 1;
      lower[r] = h[i], diag[r] = 2 * (h[i - 1] + h[i]), upper[r] = h[i - 1];
      rhs[r] = 3 * (h[i] * s[i - 1] + h[i - 1] * s[i]);
    }
    rhs[0] -= lower[0] * k[0].v;  // v_n = 0 adds nothing to the last row
    for (size_t r = 1; r < m; ++r) {
      const double w = lower[r] / diag[r - 1];
      diag[r] -= w * upper[r - 1];
      rhs[r] -= w * rhs[r - 1];
    }
    k[m].v = rhs[m - 1] / diag[m - 1];
    for (size_t r = m - 1; r-- > 0;) k[r + 1].v = (rhs[r] - upper[r] * k[r + 2].v) / diag[r];
    k[n].v = 0.0;
  } else {
    k[n].v = 0.0;
  }
  if (!a.empty()) {
    for (size_t i = 0; i < n; ++i) k[i + 1].a = a[i];
  } else {
    for (size_t i = 1; i < n; ++i)
      k[i].a = 0.5 * (hermiteEndAcceleration(h[i - 1], s[i - 1], k[i - 1].v, k[i].v) +
                      hermiteStartAcceleration(h[i], s[i], k[i].v, k[i + 1].v));
    k[n].a = 0.0;
  }
  return DrivePath(std::move(k));
}

void DrivePath::eval(double t, double* q, double* q_dot, double* q_ddot) const {
  const size_t n = knots_.size();
  if (n == 1 || t >= knots_[n - 1].t) {  // past the end: on at the last velocity
    const PathKnot& e = knots_[n - 1];
    *q = e.q + e.v * (t - e.t);
    *q_dot = e.v;
    *q_ddot = 0.0;
    return;
  }
  size_t i = 0, hi = n - 1;  // binary search: knots_[i].t <= t < knots_[i+1].t (i = 0 before)
  while (hi - i > 1) {
    const size_t mid = (i + hi) / 2;
    (knots_[mid].t <= t ? i : hi) = mid;
  }
  const std::array<double, 6>& c = c_[i];
  const double x = t - knots_[i].t;
  *q = c[0] + x * (c[1] + x * (c[2] + x * (c[3] + x * (c[4] + x * c[5]))));
  *q_dot = c[1] + x * (2 * c[2] + x * (3 * c[3] + x * (4 * c[4] + x * 5 * c[5])));
  *q_ddot = 2 * c[2] + x * (6 * c[3] + x * (12 * c[4] + x * 20 * c[5]));
}

DriveProfile DriveProfile::velocity(double v) {
  if (!std::isfinite(v)) throw UsageError("drive velocity must be finite");
  DriveProfile p;
  p.kind_ = Kind::kVelocity;
  p.v_ = v;
  return p;
}

DriveProfile DriveProfile::harmonic(double offset, double amplitude, double frequency, double phase) {
  if (!std::isfinite(offset) || !std::isfinite(amplitude) || !std::isfinite(frequency) || !std::isfinite(phase))
    throw UsageError("harmonic drive: offset, amplitude, frequency and phase must be finite");
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
  if (n < 2 || q.size() != n) throw UsageError("spline drive: needs at least 2 points");
  for (size_t i = 0; i < n; ++i) {
    if (!std::isfinite(t[i]) || !std::isfinite(q[i]))
      throw UsageError("spline drive: point " + std::to_string(i + 1) + " is not finite");
    if (i > 0 && !(t[i] > t[i - 1]))
      throw UsageError("spline drive: times must increase (point " + std::to_string(i + 1) + ")");
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

// The profile less the lag while one is active (DriveLag).
static void reference(const DriveProfile& profile, double t, const DriveRamp& ramp, double* f, double* f_dot,
                      double* f_ddot) {
  profile.eval(t, ramp, f, f_dot, f_ddot);
  if (!ramp.lag.active) return;
  double d, d_dot, d_ddot;
  ramp.lag.eval(t, &d, &d_dot, &d_ddot);
  *f -= d, *f_dot -= d_dot, *f_ddot -= d_ddot;
}

void DriveConstraint::velocityTerm(const EvalContext& ctx, double* nu) const {
  double f, f_dot, f_ddot;
  reference(profile_, ctx.t, ctx.drive[drive_], &f, &f_dot, &f_ddot);
  nu[0] = f_dot;  // nu = -Phi_t
}

// Phi = q_k - f(t); Phi_q = q_x,k; gamma = gamma_k + f_ddot (from
// q_ddot_k = q_x,k a - gamma_k).
void DriveConstraint::evaluate(const BodyKin* const* kin, const EvalContext& ctx,
                               Eigen::Ref<Eigen::VectorXd> Phi, Eigen::Ref<Eigen::MatrixXd> J,
                               Eigen::Ref<Eigen::VectorXd> gamma) const {
  Row rows[kMaxJointDofs];
  joint_.coordinates(*kin[0], *kin[1], ctx.tracked[joint_.id()], rows);
  double f, f_dot, f_ddot;
  reference(profile_, ctx.t, ctx.drive[drive_], &f, &f_dot, &f_ddot);
  Phi(0) = rows[k_].Phi - f;
  J.row(0) = rows[k_].J;
  gamma(0) = rows[k_].gamma + f_ddot;
}

}  // namespace mechanism_sim
