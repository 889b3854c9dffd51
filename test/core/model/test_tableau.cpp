// The Runge-Kutta tableaus and the stage loop's sums (core/model/tableau.cpp). Oracles: the
// sums written out by hand in the tableau's order (the same bits), y0 itself where no weight
// is given, and the exactness of TwoSum (y + c = y0 + d exactly, checked in long double).
#include <gtest/gtest.h>

#include <cmath>

#include "mechanism_sim/core/model/errors.h"
#include "mechanism_sim/core/model/tableau.h"

namespace mechanism_sim {
namespace {

TEST(Tableau, MethodsByName) {
  EXPECT_EQ(parseMethod("rk4"), Method::kRk4);
  EXPECT_EQ(parseMethod("rk3"), Method::kRk3);
  EXPECT_EQ(parseMethod("rk2"), Method::kRk2);
  EXPECT_THROW(parseMethod("euler"), ModelError);
  for (Method m : {Method::kRk2, Method::kRk3, Method::kRk4}) {  // consistency: sum b = 1, c_k = sum_j a_kj
    const Tableau& T = tableau(m);
    double b = 0;
    for (int j = 0; j < T.stages; ++j) b += T.b[j];
    EXPECT_DOUBLE_EQ(b / T.b_den, 1.0) << T.name;
    for (int k = 1; k < T.stages; ++k) {
      double a = 0;
      for (int j = 0; j < k; ++j) a += T.a[k][j];
      EXPECT_DOUBLE_EQ(a / T.a_den[k], T.c[k]) << T.name << " stage " << k;
    }
  }
}

TEST(Tableau, StageSumsAreTheHandWrittenOnesBitForBit) {
  const int n = 5;
  Eigen::VectorXd y0(n), k[4];
  y0 << 1.0, -2.5, 3.25, 1e-3, 7e5;
  for (int j = 0; j < 4; ++j) k[j] = Eigen::VectorXd::LinSpaced(n, 0.1 * (j + 1), -0.37 * (j + 2)).array() + 1.0 / 3.0;
  const double* kp[4] = {k[0].data(), k[1].data(), k[2].data(), k[3].data()};
  const Tableau& T = kRk4;
  const double h = 1e-3;
  Eigen::VectorXd y;
  // the end of an RK4 step: y0 + (h / 6) (k1 + 2 k2 + 2 k3 + k4), in that order
  combineStages(h, T.b, T.stages, T.b_den, y0, kp, y);
  for (int i = 0; i < n; ++i) {
    const double sum = ((1.0 * k[0](i) + 2.0 * k[1](i)) + 2.0 * k[2](i)) + 1.0 * k[3](i);
    EXPECT_EQ(y(i), y0(i) + (h / 6.0) * sum) << i;
  }
  // stage 3 of RK4 has one weight (on k2, k1's is zero): y0 + (h / 2) k2
  combineStages(h, T.a[2], 2, T.a_den[2], y0, kp, y);
  for (int i = 0; i < n; ++i) EXPECT_EQ(y(i), y0(i) + (h / 2.0) * (1.0 * k[1](i))) << i;
  // Kutta's third stage: y0 + h (2 k2 - k1), the sum in order of j
  const Tableau& K = kKutta3;
  combineStages(h, K.a[2], 2, K.a_den[2], y0, kp, y);
  for (int i = 0; i < n; ++i) EXPECT_EQ(y(i), y0(i) + (h / 1.0) * (-1.0 * k[0](i) + 2.0 * k[1](i))) << i;
  // no weight: y0 itself
  const double zero[2] = {0.0, 0.0};
  combineStages(h, zero, 2, 1.0, y0, kp, y);
  EXPECT_EQ(y, y0);
}

TEST(Tableau, CompensatedUpdateKeepsWhatRoundingDrops) {
  const Tableau& T = kRk4;
  const int n = 4;
  Eigen::VectorXd y0(n), c0(n), k[4], y(n), c(n);
  y0 << 1.0, 16.0, -3.0, 1e8;  // large against their increments: each update rounds
  c0 << 0.0, 1e-17, -2e-16, 3e-9;
  for (int j = 0; j < 4; ++j) k[j] = Eigen::VectorXd::Constant(n, 1e-13 * (j + 1) / 3.0);
  const double* kp[4] = {k[0].data(), k[1].data(), k[2].data(), k[3].data()};
  const double h = 1e-3;
  compensatedUpdate(h, T.b, T.stages, T.b_den, y0, kp, c0, c, y);
  for (int i = 0; i < n; ++i) {
    const double sum = ((1.0 * k[0](i) + 2.0 * k[1](i)) + 2.0 * k[2](i)) + 1.0 * k[3](i);
    const double d = (h / 6.0) * sum + c0(i);
    EXPECT_EQ(y(i), y0(i) + d) << i;  // y: the rounded update
    // y + c = y0 + d exactly (TwoSum), and c is below half an ulp of y
    EXPECT_EQ(static_cast<long double>(y(i)) + c(i), static_cast<long double>(y0(i)) + d) << i;
    EXPECT_LE(std::fabs(c(i)), 0.5 * (std::nextafter(std::fabs(y(i)), INFINITY) - std::fabs(y(i)))) << i;
  }
  EXPECT_NE(c(0), 0.0);  // (the increments here are below 1's ulp: all kept in c)
  EXPECT_EQ(y(0), 1.0);
}

}  // namespace
}  // namespace mechanism_sim
