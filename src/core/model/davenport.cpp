#include "mechanism_sim/core/model/davenport.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Geometry>
#include <Eigen/QR>

#include "mechanism_sim/core/model/errors.h"

namespace mechanism_sim {

using Eigen::Matrix3d;
using Eigen::Vector3d;

namespace {

// Axes this far from perpendicular (|cos|), or from unit length, are refused.
constexpr double kAxisTolerance = 1e-9;

Matrix3d turn(const Vector3d& e, double t) { return Eigen::AngleAxisd(t, e).toRotationMatrix(); }

// The angle about the unit axis e that takes a to b (both perpendicular to e), or `fallback`
// where a or b has no length across e.
double angleAbout(const Vector3d& e, Vector3d a, Vector3d b, double fallback) {
  a -= e * e.dot(a);
  b -= e * e.dot(b);
  if (a.norm() < 1e-12 || b.norm() < 1e-12) return fallback;
  return std::atan2(e.dot(a.cross(b)), a.dot(b));
}

// t shifted by whole turns to lie nearest `near`.
double nearest(double t, double near) { return t + 2.0 * M_PI * std::round((near - t) / (2.0 * M_PI)); }

}  // namespace

DavenportAxes::DavenportAxes(const Vector3d& e0, const Vector3d& e1, const Vector3d& e2) {
  for (const Vector3d* e : {&e0, &e1, &e2})
    if (!(std::fabs(e->norm() - 1.0) <= kAxisTolerance)) throw UsageError("Davenport angles need unit axes");
  e_ = {e0.normalized(), e1.normalized(), e2.normalized()};
  if (std::fabs(e_[0].dot(e_[1])) > kAxisTolerance || std::fabs(e_[1].dot(e_[2])) > kAxisTolerance)
    throw UsageError("Davenport angles need each axis perpendicular to the next");
  lambda_ = std::atan2(e_[0].dot(e_[1].cross(e_[2])), e_[0].dot(e_[2]));
}

Matrix3d DavenportAxes::rotation(const Angles3& t) const {
  return turn(e_[0], t[0]) * turn(e_[1], t[1]) * turn(e_[2], t[2]);
}

Angles3 DavenportAxes::angles(const Matrix3d& R, const Angles3& near) const {
  // e0' R e2 = e0' Rot(e1, t1) e2 = cos(t1 - lambda) (Rot(e0) and Rot(e2) leave e0 and e2)
  const double a = std::acos(std::max(-1.0, std::min(1.0, e_[0].dot(R * e_[2]))));
  Angles3 best{};
  double best_distance = INFINITY;
  for (const double t1_raw : {lambda_ + a, lambda_ - a}) {
    Angles3 t;
    t[1] = nearest(t1_raw, near[1]);
    const Matrix3d R1 = turn(e_[1], t[1]);
    // Rot(e0, t0) takes Rot(e1, t1) e2 to R e2
    t[0] = nearest(angleAbout(e_[0], R1 * e_[2], R * e_[2], near[0]), near[0]);
    // what is left is Rot(e2, t2)
    const Matrix3d R2 = (turn(e_[0], t[0]) * R1).transpose() * R;
    const Vector3d across = e_[2].unitOrthogonal();
    t[2] = nearest(angleAbout(e_[2], across, R2 * across, near[2]), near[2]);
    double distance = 0.0;
    for (int k = 0; k < 3; ++k) distance += (t[k] - near[k]) * (t[k] - near[k]);
    if (distance < best_distance) best_distance = distance, best = t;
  }
  return best;
}

Matrix3d DavenportAxes::rateMatrix(const Angles3& t) const {
  const Matrix3d R0 = turn(e_[0], t[0]);
  Matrix3d J;
  J.col(0) = e_[0];
  J.col(1) = R0 * e_[1];
  J.col(2) = R0 * turn(e_[1], t[1]) * e_[2];
  return J;
}

Angles3 DavenportAxes::rates(const Angles3& t, const Vector3d& omega) const {
  const Vector3d t_dot = rateMatrix(t).completeOrthogonalDecomposition().solve(omega);
  return {t_dot(0), t_dot(1), t_dot(2)};
}

Angles3 DavenportAxes::accelerations(const Angles3& t, const Angles3& t_dot, const Vector3d& omega_dot) const {
  const Matrix3d J = rateMatrix(t);
  // J_dot t_dot: d/dt (R0 e1) = t0_dot e0 x R0 e1; d/dt (R0 R1 e2) = (t0_dot e0 + t1_dot R0 e1) x R0 R1 e2
  const Vector3d w01 = t_dot[0] * J.col(0) + t_dot[1] * J.col(1);
  const Vector3d Jdot_tdot = t_dot[1] * t_dot[0] * J.col(0).cross(J.col(1)) + t_dot[2] * w01.cross(J.col(2));
  const Vector3d t_ddot = J.completeOrthogonalDecomposition().solve(omega_dot - Jdot_tdot);
  return {t_ddot(0), t_ddot(1), t_ddot(2)};
}

}  // namespace mechanism_sim
