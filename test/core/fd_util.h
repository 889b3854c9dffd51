// Finite-difference helpers for the variation and gamma checks: rotations are perturbed
// on the manifold, A <- A exp(eps tilde(e_k)) for a body-frame virtual rotation.
#pragma once
#include <functional>
#include <random>

#include <Eigen/Dense>

#include "mechanism_sim/core/model/primitives.h"

namespace mechanism_sim {
namespace test {

inline Matrix3d randomRotation(std::mt19937& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  return Quaterniond(n(rng), n(rng), n(rng), n(rng)).normalized().toRotationMatrix();
}

inline Vector3d randomVector(std::mt19937& rng, double scale = 1.0) {
  std::uniform_real_distribution<double> u(-scale, scale);
  return Vector3d(u(rng), u(rng), u(rng));
}

inline BodyKin randomBody(std::mt19937& rng) {
  BodyKin b;
  b.r = randomVector(rng);
  b.A_Oi = randomRotation(rng);
  b.v = randomVector(rng, 2.0);
  b.w = randomVector(rng, 3.0);
  return b;
}

// Moves a body along its velocity for time t with constant v and body-frame w (a = 0).
inline BodyKin advance(const BodyKin& b, double t) {
  BodyKin out = b;
  out.r = b.r + t * b.v;
  out.A_Oi = b.A_Oi * expRotation(t * b.w).toRotationMatrix();
  return out;
}

// Displaces a body by variation coordinate k (0..2 translation, 3..5 body rotation).
inline BodyKin displace(const BodyKin& b, int k, double eps) {
  BodyKin out = b;
  if (k < 3) {
    out.r(k) += eps;
  } else {
    Vector3d th = Vector3d::Zero();
    th(k - 3) = eps;
    out.A_Oi = b.A_Oi * expRotation(th).toRotationMatrix();
  }
  return out;
}

using Phis = std::function<Eigen::VectorXd(const std::vector<BodyKin>&)>;

// Central-difference Jacobian (rows x 6*bodies).
inline Eigen::MatrixXd fdJacobian(const Phis& f, const std::vector<BodyKin>& kin, double eps = 1e-6) {
  const Eigen::VectorXd f0 = f(kin);
  Eigen::MatrixXd J(f0.size(), 6 * kin.size());
  for (size_t b = 0; b < kin.size(); ++b)
    for (int k = 0; k < 6; ++k) {
      auto plus = kin, minus = kin;
      plus[b] = displace(kin[b], k, eps);
      minus[b] = displace(kin[b], k, -eps);
      J.col(6 * b + k) = (f(plus) - f(minus)) / (2 * eps);
    }
  return J;
}

// -Phi_ddot along the motion with a = 0, which is gamma (notation.h); central second
// differences with one Richardson extrapolation (error O(h^4)).
inline Eigen::VectorXd fdGamma(const Phis& f, const std::vector<BodyKin>& kin, double h = 2e-4) {
  auto at = [&](double t) {
    std::vector<BodyKin> k = kin;
    for (auto& b : k) b = advance(b, t);
    return f(k);
  };
  const Eigen::VectorXd f0 = at(0.0);
  auto second = [&](double s) -> Eigen::VectorXd { return (at(s) - 2.0 * f0 + at(-s)) / (s * s); };
  return -(4.0 * second(h / 2) - second(h)) / 3.0;
}

inline Eigen::VectorXd fdRate(const Phis& f, const std::vector<BodyKin>& kin, double h = 1e-6) {
  auto at = [&](double t) {
    std::vector<BodyKin> k = kin;
    for (auto& b : k) b = advance(b, t);
    return f(k);
  };
  return (at(h) - at(-h)) / (2 * h);
}

inline Eigen::VectorXd velocityOf(const std::vector<BodyKin>& kin) {
  Eigen::VectorXd v(6 * kin.size());
  for (size_t b = 0; b < kin.size(); ++b) v.segment<6>(6 * b) << kin[b].v, kin[b].w;
  return v;
}

inline int rankOf(const Eigen::MatrixXd& J, double tol = 1e-8) {
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(J);
  const auto s = svd.singularValues();
  int r = 0;
  for (int i = 0; i < s.size(); ++i) r += s(i) > tol * std::max(1.0, s(0));
  return r;
}

}  // namespace test
}  // namespace mechanism_sim
