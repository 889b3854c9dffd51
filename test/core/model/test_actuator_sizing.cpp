// ActuatorSizing (actuator_sizing.h) on operating points with known integrals: a motor
// whose torque and speed are sinusoids in quadrature (the torque's RMS, the work each way
// and the peaks by hand), a DC motor's electrical record, and each rating exceeded when
// and by as much as the points say.
#include <gtest/gtest.h>

#include <cmath>

#include "mechanism_sim/core/model/actuator_sizing.h"

namespace mechanism_sim {
namespace {

constexpr double kPi = 3.14159265358979323846;

// tau = A sin(w t), omega = B cos(w t) over `periods` whole periods, n points a period.
void sinusoids(ActuatorSizing& s, double A, double B, double w, int periods, int n) {
  const double T = 2 * kPi / w;
  for (int k = 0; k <= periods * n; ++k) {
    const double t = k * T / n;
    s.add(t, B * std::cos(w * t), A * std::sin(w * t));
  }
}

// Over whole periods the trapezoidal rule integrates sin^2 exactly: RMS = A / sqrt(2).
// The power (A B / 2) sin(2 w t) delivers A B / w a period and takes as much back.
TEST(ActuatorSizing, SinusoidsInQuadratureByHand) {
  const double A = 3.0, B = 40.0, w = 5.0;
  ActuatorSizing s("m", ActuatorRatings{});
  sinusoids(s, A, B, w, 3, 8000);
  EXPECT_NEAR(s.rmsTorque(), A / std::sqrt(2.0), 1e-12 * A);
  EXPECT_NEAR(s.peakTorque(), A, 1e-12 * A);
  EXPECT_NEAR(std::fmod(s.peakTorqueTime(), 2 * kPi / w), kPi / (2 * w), 1e-12);  // (sin = 1 is a point)
  EXPECT_NEAR(s.peakSpeed(), B, 1e-12 * B);
  EXPECT_NEAR(s.peakPower(), A * B / 2, 1e-9 * A * B);
  // (the trapezoids over each lobe of |sin|: O(h^2) of the lobe's integral)
  EXPECT_NEAR(s.positiveWork(), 3 * A * B / w, 1e-6 * A * B / w);
  EXPECT_NEAR(s.negativeWork(), -3 * A * B / w, 1e-6 * A * B / w);
  EXPECT_TRUE(s.withinRating());
  EXPECT_FALSE(s.rated());
}

// V = R i + k omega, i = tau / k: the electrical power is the mechanical one plus R i^2.
TEST(ActuatorSizing, ElectricalRecordOfADcMotor) {
  ActuatorRatings r;
  r.torque_constant = 0.05, r.resistance = 0.4;
  const double A = 0.2, B = 300.0, w = 2.0;
  ActuatorSizing s("m", r);
  sinusoids(s, A, B, w, 2, 2000);
  ASSERT_TRUE(s.electricalGiven());
  EXPECT_NEAR(s.peakCurrent(), A / r.torque_constant, 1e-12 * A / r.torque_constant);
  // copper losses R (A/k)^2 sin^2: (R A^2 / k^2) T / 2 over each period, exact as above
  const double T = 2 * kPi / w;
  EXPECT_NEAR(s.copperEnergy(), 2 * r.resistance * A * A / (r.torque_constant * r.torque_constant) * T / 2,
              1e-12 * r.resistance * A * A / (r.torque_constant * r.torque_constant) * T);
  const ActuatorElectrical e = electrical(r, B, A);
  EXPECT_NEAR(e.power, A * B + e.copper_loss, 1e-12 * A * B);
  EXPECT_NEAR(e.voltage, r.resistance * A / r.torque_constant + r.torque_constant * B, 1e-12 * e.voltage);
}

// Each rating exceeded is named with its limit, its worst value and when, and when first:
// a peak of A against 0.9 A, first at asin(0.9) / w; a speed of B against 0.5 B, at once
// (the speed starts at B); an RMS of A / sqrt(2) against 0.6 A.
TEST(ActuatorSizing, ExceededRatingsSayWhenAndByHowMuch) {
  const double A = 2.0, B = 10.0, w = 1.0;
  const int n = 100000;
  ActuatorRatings r;
  r.peak_torque = 0.9 * A, r.rated_torque = 0.6 * A, r.max_speed = 0.5 * B;
  ActuatorSizing s("m", r);
  sinusoids(s, A, B, w, 1, n);
  ASSERT_TRUE(s.rated());
  const std::vector<ActuatorSizing::Exceeded> x = s.exceeded();
  ASSERT_EQ(x.size(), 3u);
  const double dt = 2 * kPi / w / n;
  EXPECT_EQ(x[0].rating, "peak_torque");
  EXPECT_DOUBLE_EQ(x[0].limit, 0.9 * A);
  EXPECT_NEAR(x[0].worst, A, 1e-9 * A);
  EXPECT_NEAR(x[0].first_time, std::asin(0.9) / w, dt);
  EXPECT_NEAR(x[0].worst_time, kPi / (2 * w), dt);
  EXPECT_EQ(x[1].rating, "max_speed");
  EXPECT_EQ(x[1].first_time, 0.0);
  EXPECT_NEAR(std::fabs(x[1].worst), B, 1e-9 * B);
  EXPECT_EQ(x[2].rating, "rated_torque");
  EXPECT_NEAR(x[2].worst, A / std::sqrt(2.0), 1e-12 * A);
  EXPECT_FALSE(s.withinRating());
  // within every rating once they are wide enough
  ActuatorRatings wide = r;
  wide.peak_torque = 1.01 * A, wide.rated_torque = 0.75 * A, wide.max_speed = 1.01 * B;
  ActuatorSizing ok("m", wide);
  sinusoids(ok, A, B, w, 1, 1000);
  EXPECT_TRUE(ok.withinRating());
}

// A DC motor's line: stall torque at rest, nothing at the no-load speed; a point above the
// line is over by (|tau| - allowed) / stall.
TEST(ActuatorSizing, TorqueSpeedLine) {
  ActuatorRatings r;
  r.stall_torque = 1.0, r.no_load_speed = 100.0;
  ActuatorSizing s("m", r);
  s.add(0.0, 0.0, 0.9);   // under the stall torque at rest
  s.add(0.1, 50.0, 0.4);  // under the line (0.5 allowed)
  EXPECT_TRUE(s.withinRating());
  s.add(0.2, 50.0, 0.7);  // 0.2 over the line
  s.add(0.3, 80.0, 0.3);  // 0.1 over
  const std::vector<ActuatorSizing::Exceeded> x = s.exceeded();
  ASSERT_EQ(x.size(), 1u);
  EXPECT_EQ(x[0].rating, "torque-speed line");
  EXPECT_DOUBLE_EQ(x[0].first_time, 0.2);
  EXPECT_DOUBLE_EQ(x[0].worst_time, 0.2);
  EXPECT_DOUBLE_EQ(x[0].worst, 0.7);
}

}  // namespace
}  // namespace mechanism_sim
