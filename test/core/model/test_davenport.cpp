// Davenport angles (davenport.h): rotation and angles invert each other on both solutions
// and at the lock; the rate matrix and the accelerations agree with finite differences.
#include <gtest/gtest.h>

#include <random>

#include <Eigen/Geometry>

#include "mechanism_sim/core/model/davenport.h"
#include "mechanism_sim/core/model/errors.h"

using namespace mechanism_sim;
using Eigen::Matrix3d;
using Eigen::Vector3d;

namespace {

// Axes of each kind: proper Euler (e2 = e0), Tait-Bryan (e2 _|_ e0), and between, each
// turned as a whole to no particular frame.
std::vector<DavenportAxes> axesCases() {
  const Matrix3d Q = Eigen::AngleAxisd(0.7, Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  std::vector<DavenportAxes> out;
  for (const double lambda : {0.0, M_PI / 2, 0.4, -2.5, M_PI}) {
    // e1 = z; e0 = x; e2 in the x-y plane... e2 _|_ e1 at the angle lambda from e0 about e1
    const Vector3d e0 = Vector3d::UnitX(), e1 = Vector3d::UnitZ();
    const Vector3d e2 = Eigen::AngleAxisd(-lambda, e1) * e0;
    out.emplace_back(Q * e0, Q * e1, Q * e2);
  }
  return out;
}

Matrix3d randomRotation(std::mt19937& rng) {
  std::normal_distribution<double> n;
  return Eigen::Quaterniond(n(rng), n(rng), n(rng), n(rng)).normalized().toRotationMatrix();
}

}  // namespace

TEST(Davenport, AnglesInvertTheRotationNearTheGivenAngles) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-3.0, 3.0);
  for (const DavenportAxes& ax : axesCases())
    for (int i = 0; i < 200; ++i) {
      const Angles3 t{u(rng) * 3.0, u(rng), u(rng) * 3.0};  // whole turns included
      const Angles3 near{t[0] + 0.01, t[1] - 0.01, t[2] + 0.01};
      const Angles3 back = ax.angles(ax.rotation(t), near);
      // away from the lock the angles nearest `near` are t themselves
      const double across = ax.rateMatrix(t).determinant();
      if (std::fabs(across) < 1e-3) continue;
      for (int k = 0; k < 3; ++k) EXPECT_NEAR(back[k], t[k], 1e-9) << k;
    }
}

TEST(Davenport, EveryRotationHasAnglesThatRebuildIt) {
  std::mt19937 rng(6);
  for (const DavenportAxes& ax : axesCases())
    for (int i = 0; i < 200; ++i) {
      const Matrix3d R = randomRotation(rng);
      const Angles3 t = ax.angles(R, {0, 0, 0});
      EXPECT_LE((ax.rotation(t) - R).norm(), 1e-12);
    }
}

// At the lock (e0 along Rot(e1, t1) e2) only t0 + t2 or t0 - t2 shows: t0 stays where it was
// and t2 takes the rest; the rotation is rebuilt.
TEST(Davenport, AtTheLockTheFirstAngleStaysAndTheRotationIsRebuilt) {
  for (const DavenportAxes& ax : axesCases()) {
    // the middle angle at which Rot(e1, t1) e2 = e0: cos(t1 - lambda) = 1
    const double lambda = std::atan2(ax.axis(0).dot(ax.axis(1).cross(ax.axis(2))), ax.axis(0).dot(ax.axis(2)));
    const Matrix3d R = ax.rotation({0.3, lambda, 0.9});
    const Angles3 t = ax.angles(R, {0.5, lambda, 0.0});
    EXPECT_DOUBLE_EQ(t[0], 0.5);
    EXPECT_LE((ax.rotation(t) - R).norm(), 1e-12);
    EXPECT_NEAR(std::fabs(ax.rateMatrix(t).determinant()), 0.0, 1e-12);
  }
}

TEST(Davenport, RatesAndAccelerationsAgreeWithFiniteDifferences) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-2.0, 2.0);
  const double s = 1e-5;
  for (const DavenportAxes& ax : axesCases())
    for (int i = 0; i < 50; ++i) {
      const Angles3 t{u(rng), u(rng), u(rng)}, td{u(rng), u(rng), u(rng)}, tdd{u(rng), u(rng), u(rng)};
      if (std::fabs(ax.rateMatrix(t).determinant()) < 1e-2) continue;
      auto at = [&](double h) {
        Angles3 x;
        for (int k = 0; k < 3; ++k) x[k] = t[k] + h * td[k] + 0.5 * h * h * tdd[k];
        return x;
      };
      auto rate = [&](double h) {
        Vector3d x;
        for (int k = 0; k < 3; ++k) x(k) = td[k] + h * tdd[k];
        return x;
      };
      // omega: R_dot R' = tilde(omega)
      const Matrix3d W = (ax.rotation(at(s)) - ax.rotation(at(-s))) / (2 * s) * ax.rotation(t).transpose();
      const Vector3d omega(W(2, 1), W(0, 2), W(1, 0));
      const Vector3d J_td = ax.rateMatrix(t) * Eigen::Map<const Vector3d>(td.data());
      EXPECT_LE((J_td - omega).norm(), 1e-8 * (1 + omega.norm()));
      const Angles3 back = ax.rates(t, J_td);
      for (int k = 0; k < 3; ++k) EXPECT_NEAR(back[k], td[k], 1e-10 * (1 + std::fabs(td[k])));
      // omega_dot: d/dt (J t_dot) along the path
      const Vector3d omega_dot = (ax.rateMatrix(at(s)) * rate(s) - ax.rateMatrix(at(-s)) * rate(-s)) / (2 * s);
      const Angles3 acc = ax.accelerations(t, td, omega_dot);
      for (int k = 0; k < 3; ++k) EXPECT_NEAR(acc[k], tdd[k], 1e-6 * (1 + std::fabs(tdd[k]))) << k;
    }
}

TEST(Davenport, AxesThatAreNotPerpendicularAreRefused) {
  EXPECT_THROW(DavenportAxes(Vector3d::UnitX(), Vector3d(1, 1, 0).normalized(), Vector3d::UnitX()), UsageError);
  EXPECT_THROW(DavenportAxes(Vector3d::UnitX(), Vector3d::UnitY(), Vector3d(0, 2, 0)), UsageError);
}
