// nearestPhysicalInertia (inertia.h): the result is physical, a physical inertia is left as
// it is, known answers, and it is the nearest in the Frobenius norm: against the
// projection's optimality condition over many physical inertias and against brute force.
#include <gtest/gtest.h>

#include <random>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include "mechanism_sim/core/model/inertia.h"

namespace mechanism_sim {
namespace {

using Eigen::Matrix3d;
using Eigen::Vector3d;

bool physical(const Matrix3d& J, double tol) {
  const Vector3d l = Eigen::SelfAdjointEigenSolver<Matrix3d>(J).eigenvalues();
  return l(0) >= -tol && l(2) <= l(0) + l(1) + tol;
}

Matrix3d randomRotation(std::mt19937& rng) {
  std::normal_distribution<double> n;
  return Eigen::Quaterniond(n(rng), n(rng), n(rng), n(rng)).normalized().toRotationMatrix();
}

// A random physical inertia: moments l_i = a_j + a_k (a >= 0) satisfy the triangle
// inequality, and every physical triple is of that form.
Matrix3d randomPhysical(std::mt19937& rng, double size) {
  std::uniform_real_distribution<double> u(0.0, size);
  const double a = u(rng), b = u(rng), c = u(rng);
  const Matrix3d R = randomRotation(rng);
  return R * Vector3d(b + c, a + c, a + b).asDiagonal() * R.transpose();
}

TEST(NearestPhysicalInertia, LeavesAPhysicalInertiaAsItIs) {
  std::mt19937 rng(1);
  for (int k = 0; k < 100; ++k) {
    const Matrix3d J = randomPhysical(rng, 1e-3);
    EXPECT_EQ(nearestPhysicalInertia(J), J);
  }
}

// ixx = a, iyy = izz = 0 (a finger written as a point): the moments (0, 0, a) move to the
// plane l_3 = l_1 + l_2 along its normal (-1, -1, 1): (a/3, a/3, 2a/3), a distance a/sqrt(3).
// MuJoCo's balanceinertia (all three to their mean a/3) is a distance a sqrt(6)/3 away.
TEST(NearestPhysicalInertia, ZeroMomentsAnalytic) {
  const double a = 3e-5;
  Matrix3d J = Matrix3d::Zero();
  J(0, 0) = a;
  Vector3d before, after;
  const Matrix3d P = nearestPhysicalInertia(J, &before, &after);
  EXPECT_NEAR(after(0), a / 3, 1e-15 * a);
  EXPECT_NEAR(after(1), a / 3, 1e-15 * a);
  EXPECT_NEAR(after(2), 2 * a / 3, 1e-15 * a);
  EXPECT_NEAR(P(0, 0), 2 * a / 3, 1e-15 * a);
  EXPECT_NEAR(P(1, 1), a / 3, 1e-15 * a);
  EXPECT_NEAR(P(2, 2), a / 3, 1e-15 * a);
  EXPECT_NEAR((P - J).norm(), a / std::sqrt(3.0), 1e-15 * a);
  const Matrix3d balanced = Matrix3d::Identity() * a / 3;
  EXPECT_NEAR((balanced - J).norm(), a * std::sqrt(6.0) / 3, 1e-15 * a);
}

// Moments far outside: all negative go to zero, and so does (-1, 0, 0): the nearest points
// of each face, (-2/3, -1/3, 1/3) and (-2/3, 1/3, -1/3), break the other face's inequality,
// and the cone's points (t, s, s) are at least 1 away.
TEST(NearestPhysicalInertia, NegativeMoments) {
  EXPECT_LT(nearestPhysicalMoments(Vector3d(-1, -2, -3)).norm(), 1e-15);
  EXPECT_LT(nearestPhysicalMoments(Vector3d(-1, 0, 0)).norm(), 1e-15);
}

// The projection P of J onto the convex cone K of physical inertias is characterised by
// <J - P, X - P> <= 0 for every X in K (for a cone: <J - P, P> = 0 and <J - P, X> <= 0);
// checked over random non-physical J and many random physical X. And no physical inertia
// found by brute force (random ones, and random perturbations of P kept physical) is nearer.
TEST(NearestPhysicalInertia, IsTheNearestInTheFrobeniusNorm) {
  std::mt19937 rng(7);
  std::normal_distribution<double> n;
  int non_physical = 0;
  for (int k = 0; k < 200; ++k) {
    Matrix3d J;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j <= i; ++j) J(i, j) = J(j, i) = n(rng);
    if (physical(J, 0.0)) continue;
    ++non_physical;
    const Matrix3d P = nearestPhysicalInertia(J);
    ASSERT_TRUE(physical(P, 1e-14 * J.norm())) << J;
    const Matrix3d D = J - P;
    EXPECT_NEAR((D.cwiseProduct(P)).sum(), 0.0, 1e-13 * J.squaredNorm());
    const double d = D.norm();
    for (int s = 0; s < 2000; ++s) {
      const Matrix3d X = randomPhysical(rng, 2.0);
      EXPECT_LE((D.cwiseProduct(X)).sum(), 1e-13 * J.norm() * X.norm());
      EXPECT_GE((J - X).norm(), d * (1 - 1e-14));
      Matrix3d E;  // a nearby candidate: P moved a little, kept if physical
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j <= i; ++j) E(i, j) = E(j, i) = 1e-3 * n(rng);
      if (physical(P + E, 0.0)) {
        EXPECT_GE((J - P - E).norm(), d * (1 - 1e-14));
      }
    }
  }
  EXPECT_GT(non_physical, 50);
}

}  // namespace
}  // namespace mechanism_sim
