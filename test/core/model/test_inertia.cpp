// nearestPhysicalInertia (inertia.h): the result is physical, a physical inertia is left as
// it is, known answers, and it is the nearest in the Frobenius norm: against the
// projection's optimality condition over many physical inertias and against brute force.
#include <gtest/gtest.h>

#include <random>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include "mechanism_sim/core/model/errors.h"
#include "mechanism_sim/core/model/inertia.h"
#include "pendulum.h"

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

// A point mass m at distance L from its revolute, its central inertia round-off of its
// own scale m L^2 (a parallel-axis sum leaves -5e-20 kg m^2 on a 0.5 kg link 3 cm from its
// joint): the body is valid at every unit scale and swings as the exact pendulum (period
// and energy of m L^2 q'' = m g L cos q), while a moment negative by 1e-6 of m L^2 is
// still refused.
TEST(BodyValidation, APointMassAwayFromItsJointTakesRoundOffOfItsOwnScaleAtEveryUnitScale) {
  std::mt19937 rng(7);
  for (double L : {1e-3, 1e-1, 1.0, 1e1, 1e3})
    for (double m : {1e-3, 1.0, 1e3}) {
      const Matrix3d R = randomRotation(rng);
      auto build = [&](Mechanism& mech, double moment) {
        const Matrix3d Jp = R * Vector3d(moment, 0.0, 0.5 * moment).asDiagonal() * R.transpose();
        const int b = mech.addBody(body("bob", m, Jp, Vector3d(L, 0, 0)));
        mech.addJoint(makeJoint("revolute", "pivot", Mechanism::kGround, models::axisY(Vector3d::Zero()), b,
                                models::axisY(Vector3d(-L, 0, 0))));
        mech.setGravity(Vector3d(0, 0, -kG));
        return b;
      };
      Mechanism mech;
      const int b = build(mech, -4e-17 * m * L * L);
      mech.build();
      mech.assemble();
      const double E0 = mech.kineticEnergy() + mech.potentialEnergy();
      const double h = 2e-3 * std::sqrt(L), T = 0.5 * std::sqrt(L);  // a quarter swing and more
      for (long k = 0, n = std::lround(T / h); k < n; ++k) mech.step(h);
      // q'' = (g / L) cos q from rest, by RK4 in 20000 steps of T / 20000
      double q = 0, v = 0;
      const double c = kG / L, he = T / 20000;
      for (int k = 0; k < 20000; ++k) {
        const double k1v = c * std::cos(q), k2v = c * std::cos(q + 0.5 * he * v);
        const double k3v = c * std::cos(q + 0.5 * he * v + 0.25 * he * he * k1v);
        const double k4v = c * std::cos(q + he * v + 0.5 * he * he * k2v);
        q += he * v + he * he / 6.0 * (k1v + k2v + k3v);
        v += he / 6.0 * (k1v + 2 * k2v + 2 * k3v + k4v);
      }
      EXPECT_LT((mech.position(b) - L * Vector3d(std::cos(q), 0, -std::sin(q))).norm(), 1e-8 * L)
          << "L = " << L << ", m = " << m;
      EXPECT_NEAR(mech.kineticEnergy() + mech.potentialEnergy(), E0, 1e-9 * m * kG * L) << "L = " << L << ", m = " << m;

      Mechanism bad;
      build(bad, -1e-6 * m * L * L);
      try {
        bad.build();
        ADD_FAILURE() << "a moment of -1e-6 m L^2 passed, L = " << L << ", m = " << m;
      } catch (const ModelError& e) {
        EXPECT_NE(std::string(e.what()).find("body 'bob': inertia has a negative principal moment"), std::string::npos)
            << e.what();
      }
    }
}

}  // namespace
}  // namespace mechanism_sim
