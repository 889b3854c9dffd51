// The damping classification both formulations call (core/damping/stiff_damping_rule.h).
// Known answers: the Gershgorin rate h s_k of a given inverse mass P and the stiffness
// test at the tableau's bound; a body's block-diagonal inverse mass; and, through both
// steppers, a damped disc (P = 1/I, h s = h c / I) that the classification keeps in RK4's
// stages at h c / I = 1.5 and sends to implicit Euler at 3 when the step (or the damping)
// changes after steps that found nothing stiff: the velocity follows RK4's amplification,
// then 1 / (1 + h c / I) per step.
#include <gtest/gtest.h>

#include "bodies.h"

#include <cmath>

#include "core/damping/stiff_damping_rule.h"
#include "mechanism_sim/core/mechanism.h"
#include "mechanism_sim/core/model/tableau.h"

namespace mechanism_sim {
namespace {

using test_util::body;
using test_util::frame;

TEST(StiffDampingRule, GershgorinRateOfAKnownInverseMass) {
  // c = (4, 9), P = [2 -1; -1 3]: s_0 = sqrt(16) 2 + sqrt(36) 1 = 14, s_1 = 6 + sqrt(81) 3 = 33
  const double c[2] = {4.0, 9.0};
  const double P[2][2] = {{2.0, -1.0}, {-1.0, 3.0}};
  auto rate = [&](double h, int k) {
    return stiff_damping::decayRate(h, c[k], [&](auto add) {
      for (int l = 0; l < 2; ++l) add(c[l], P[l][k]);
    });
  };
  EXPECT_DOUBLE_EQ(rate(1.0, 0), 14.0);
  EXPECT_DOUBLE_EQ(rate(0.1, 1), 3.3);
  // RK4's bound 2 (tableau.h): 0.1 * 14 stays in the stages, 0.1 * 33 and 0.2 * 14 do not
  EXPECT_FALSE(stiff_damping::isStiff(rate(0.1, 0), kRk4.stiff_bound));
  EXPECT_TRUE(stiff_damping::isStiff(rate(0.1, 1), kRk4.stiff_bound));
  EXPECT_TRUE(stiff_damping::isStiff(rate(0.2, 0), kRk4.stiff_bound));
  EXPECT_FALSE(stiff_damping::isStiff(kRk4.stiff_bound, kRk4.stiff_bound));  // (at the bound: the stages)
  EXPECT_TRUE(stiff_damping::isStiff(std::nan(""), kRk4.stiff_bound));       // (no bound: stiff)
  EXPECT_TRUE(stiff_damping::isStiff(HUGE_VAL, kRk4.stiff_bound));
}

TEST(StiffDampingRule, BodyInverseMassIsTheRowsQuadraticForm) {
  // m = 2 kg, J' = diag(1, 2, 4): M_b^-1 = diag(1/2, 1/2, 1/2, 1, 1/2, 1/4)
  Eigen::Matrix<double, 6, 6> Mi = Eigen::Matrix<double, 6, 6>::Zero();
  Mi.diagonal() << 0.5, 0.5, 0.5, 1.0, 0.5, 0.25;
  stiff_damping::Row6 a, b;
  a << 1, 2, 0, 0, 0, 3;
  b << 0, 1, 0, 1, 0, 2;
  EXPECT_DOUBLE_EQ(stiff_damping::bodyInverseMass(a, b, Mi), 0.5 * 2 + 0.25 * 6);
  EXPECT_DOUBLE_EQ(stiff_damping::bodyInverseMass(b, b, Mi), 0.5 * 1 + 1.0 + 0.25 * 4);
}

// RK4's amplification of y' = -y / tau over one step of s = h / tau.
double rk4Amplification(double s) { return 1 - s + s * s / 2 - s * s * s / 6 + s * s * s * s / 24; }

void dampedDisc(Mechanism& m, const char* formulation, double I, double c) {
  const int b = m.addBody(body("disc", 1.0, Vector3d(0.025, 0.025, I), Vector3d::Zero()));
  m.addJoint(makeJoint("revolute", "axle", Mechanism::kGround, frame(Vector3d::Zero()), b, frame(Vector3d::Zero())));
  m.setGravity(Vector3d::Zero());
  m.setJointDamping(0, 0, c);
  IntegratorOptions o;
  o.formulation = formulation;
  o.method = "rk4";
  m.setIntegrator(o);
  m.build();
}

TEST(StiffDampingRule, BothFormulationsClassifyAgainAfterTheStepOrTheDampingChanges) {
  for (const char* formulation : {"absolute", "joint"}) {
    SCOPED_TRACE(formulation);
    const double I = 0.05, rate = 1500.0, w0 = 10.0, h = 1e-3;  // h c / I = 1.5: the stages
    for (const bool by_damping : {false, true}) {
      SCOPED_TRACE(by_damping ? "damping doubled" : "step doubled");
      Mechanism m;
      dampedDisc(m, formulation, I, rate * I);
      m.assemble({}, {CoordinateTarget{0, 0, w0}});
      double expected = w0;
      for (int s = 0; s < 20; ++s) m.step(h), expected *= rk4Amplification(h * rate);
      EXPECT_NEAR(m.jointVelocity(0, 0), expected, 1e-12 * w0);
      // h c / I = 3, past RK4's bound 2 (and its stability limit 2.785): implicit Euler
      double h2 = h;
      if (by_damping) m.setJointDamping(0, 0, 2 * rate * I);
      else h2 = 2 * h;
      for (int s = 0; s < 5; ++s) m.step(h2), expected /= 1.0 + 3.0;
      EXPECT_NEAR(m.jointVelocity(0, 0), expected, 1e-12 * w0);
    }
  }
}

}  // namespace
}  // namespace mechanism_sim
