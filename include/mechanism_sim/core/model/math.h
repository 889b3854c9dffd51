// Small rotation helpers: skew matrices, Euler parameters, the exponential map.
#pragma once
#include <cmath>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace mechanism_sim {

using Eigen::Matrix3d;
using Eigen::Vector3d;
using Eigen::Vector4d;
using Eigen::Quaterniond;
using Row12 = Eigen::Matrix<double, 1, 12>;

// tilde(a) b = a x b
inline Matrix3d tilde(const Vector3d& a) {
  Matrix3d m;
  m << 0, -a.z(), a.y(), a.z(), 0, -a.x(), -a.y(), a.x(), 0;
  return m;
}

// A tilde(s), column by column: column k is A (s x e_k), two columns of A combined (the
// product with the skew matrix would multiply its zeros too).
inline Matrix3d timesTilde(const Matrix3d& A, const Vector3d& s) {
  Matrix3d m;
  m.col(0) = s.z() * A.col(1) - s.y() * A.col(2);
  m.col(1) = s.x() * A.col(2) - s.z() * A.col(0);
  m.col(2) = s.y() * A.col(0) - s.x() * A.col(1);
  return m;
}

// Rotation exp(tilde(theta)) as a unit quaternion.
inline Quaterniond expRotation(const Vector3d& theta) {
  const double angle = theta.norm();
  if (angle < 1e-12) {
    Quaterniond q(1.0, 0.5 * theta.x(), 0.5 * theta.y(), 0.5 * theta.z());
    return q.normalized();
  }
  return Quaterniond(Eigen::AngleAxisd(angle, theta / angle));
}

// Rotation vector of a unit quaternion (inverse of expRotation), angle in [0, pi].
inline Vector3d logRotation(Quaterniond q) {
  if (q.w() < 0) q.coeffs() = -q.coeffs();
  const double s = q.vec().norm();
  if (s < 1e-12) return 2.0 * q.vec();
  return 2.0 * std::atan2(s, q.w()) * q.vec() / s;
}

// Quaternion product a (x) b of Euler parameters stored (w, x, y, z), as the joint
// formulation's q keeps them.
inline Eigen::Vector4d quatProduct(const Eigen::Vector4d& a, const Eigen::Vector4d& b) {
  Eigen::Vector4d out;
  out(0) = a(0) * b(0) - a.tail<3>().dot(b.tail<3>());
  out.tail<3>() = a(0) * b.tail<3>() + b(0) * a.tail<3>() + a.tail<3>().cross(b.tail<3>());
  return out;
}

// exp of a rotation vector as a quaternion stored (w, x, y, z), as the joint formulation's
// q keeps them.
inline Eigen::Vector4d quatExp(const Vector3d& phi) {
  const double a = phi.norm();
  Eigen::Vector4d out;
  if (a < 1e-8) {
    out << 1.0 - a * a / 8, 0.5 * phi;
  } else {
    out << std::cos(a / 2), std::sin(a / 2) / a * phi;
  }
  return out;
}

// Rigid transform with rotation R and translation t.
inline Eigen::Isometry3d pose(const Matrix3d& R, const Vector3d& t) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = R;
  T.translation() = t;
  return T;
}
inline Matrix3d rotZ(double a) {
  const double c = std::cos(a), s = std::sin(a);
  Matrix3d R;
  R << c, -s, 0, s, c, 0, 0, 0, 1;
  return R;
}

// Nearest representative of angle to ref (unwrap across turns).
inline double unwrapNear(double angle, double ref) {
  constexpr double kTwoPi = 6.283185307179586476925;
  return angle + kTwoPi * std::round((ref - angle) / kTwoPi);
}

}  // namespace mechanism_sim
