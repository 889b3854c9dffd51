// Evaluations without rates (evaluateConstraints with rates false: the queries' own,
// Mechanism::evaluated): on a chain with active limits, a rheonomic drive and a mimic
// coupler, moving, Phi, Phi_q and nu have every bit of the full evaluation's, so the
// violations the queries report are the full evaluation's; gamma is 0 there.
#include <gtest/gtest.h>

#include <string>

#include <cmath>
#include <random>

#include "core/absolute/evaluation.h"
#include "mechanism_sim/core/mechanism.h"
#include "mechanism_sim/core/models.h"

namespace mechanism_sim {
namespace {

bool sameBits(double a, double b) { return a == b && std::signbit(a) == std::signbit(b); }

// The chain of joint_space/test_joint_stepper's LimitsDrivesAndCouplersMoveAsInAbsoluteCoordinates.
void chain(Mechanism& m, const char* formulation) {
  models::pendulumChain(m, 4, 0.5, 1.0, 0.4);
  m.setJointLimits(1, 0, -0.3, 0.3);
  m.setJointLimits(2, 0, -0.25, 0.25);
  m.addCoupler("mimic", 3, 0, 2, 0, -0.5, 0.0);
  m.addDrive(0, 0, DriveProfile::harmonic(0.0, 0.3, 0.7, 0.0));
  IntegratorOptions io;
  io.formulation = formulation;
  m.setIntegrator(io);
  m.build();
  m.assemble();
}

TEST(EvaluationWithoutRates, HasTheFullEvaluationsPhiJacobianAndNu) {
  Mechanism m;
  chain(m, "absolute");
  const System& sys = m.system();
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int n = 0; n < 10; ++n) {
    m.step(1e-2);
    State s = m.state();
    for (int i = 0; i < s.u.size(); ++i) s.u[i] += u(rng);  // (off the constraints: every term counts)
    for (auto& side : s.limit_side) side = u(rng) < 0 ? -1 : 1;  // both limits active
    s.t += 0.1;                                                    // (the drive's nu is not 0)
    Evaluation full(sys), bare(sys);
    evaluateAt(sys, s, full);
    evaluateAt(sys, s, bare, false);
    EXPECT_TRUE(full.stamp.rates);
    EXPECT_FALSE(bare.stamp.rates);
    for (int e = 0; e < sys.m; ++e) {
      EXPECT_TRUE(sameBits(full.Phi[e], bare.Phi[e])) << "row " << e;
      EXPECT_TRUE(sameBits(full.nu[e], bare.nu[e])) << "row " << e;
      EXPECT_EQ(bare.gamma[e], 0.0) << "row " << e;
    }
    for (int c = 0; c < sys.numConstraints(); ++c)
      for (int i = 0; i < full.J[c].size(); ++i)
        EXPECT_TRUE(sameBits(full.J[c](i), bare.J[c](i))) << sys.constraints[c]->name() << " entry " << i;
    EXPECT_GT(full.gamma.cwiseAbs().maxCoeff(), 0.0);  // (there was a gamma to leave out)
    EXPECT_GT(full.nu.cwiseAbs().maxCoeff(), 0.0);
    EXPECT_EQ(positionViolation(full), positionViolation(bare));
    EXPECT_EQ(velocityViolation(sys, full, s.u), velocityViolation(sys, bare, s.u));
    std::vector<std::array<double, 2>> scales(sys.nb);
    EXPECT_EQ(velocityResidual(sys, full, s.u, scales), velocityResidual(sys, bare, s.u, scales));
    EXPECT_EQ(positionResidual(sys, full), positionResidual(sys, bare));
  }
}

// The joint formulation's queries evaluate without rates (its stepper has no evaluation of
// the absolute state): the violations and residuals they report are the full evaluation's.
TEST(EvaluationWithoutRates, QueriesReportTheFullEvaluationsViolations) {
  Mechanism m;
  chain(m, "joint");
  ASSERT_STREQ(m.formulation(), "joint") << m.formulationReason();
  const System& sys = m.system();
  for (int n = 0; n < 200; ++n) {
    m.step(1e-3);
    if (n % 20) continue;
    Evaluation full(sys);
    evaluateAt(sys, m.state(), full);
    EXPECT_EQ(m.positionViolation(), positionViolation(full)) << n;
    EXPECT_EQ(m.velocityViolation(), velocityViolation(sys, full, m.state().u)) << n;
    EXPECT_EQ(m.relativePositionViolation(), positionResidual(sys, full)) << n;
    std::vector<std::array<double, 2>> scales(sys.nb);
    EXPECT_EQ(m.relativeVelocityViolation(), velocityResidual(sys, full, m.state().u, scales)) << n;
  }
}

// The joint queries (position, velocity, acceleration) read a joint's coordinate rows found
// once per state (Mechanism::coordinateRows): after every step, and after a restore() to an
// earlier state, they are Joint::coordinates at the state they are asked of, to the bit. In
// the joint formulation a tree joint's are the State's own q, q_dot, q_ddot, from which the
// poses were written: Joint::coordinates there gives them to round-off.
TEST(JointQueries, ReadTheCoordinatesOfTheCurrentState) {
  for (const char* formulation : {"absolute", "joint"}) {
    Mechanism m;
    chain(m, formulation);
    const System& sys = m.system();
    auto check = [&](const char* when) {
      Evaluation ev(sys);
      evaluateAt(sys, m.state(), ev);
      for (int j = 0; j < m.numJoints(); ++j) {
        const Joint& jt = m.joint(j);
        Row rows[kMaxJointDofs];
        jt.coordinates(ev.kin[jt.bodyI()], ev.kin[jt.bodyJ()], m.state().tracked[jt.id()], rows);
        for (int k = 0; k < jt.dof(); ++k) {
          const double a = rowDot(sys, j, rows[k], m.state().acc.data()) - rows[k].gamma;
          if (std::string(formulation) == "joint") {
            const int i = m.treeCoordinate(j, false), iv = m.treeCoordinate(j, true);
            ASSERT_GE(i, 0);
            EXPECT_TRUE(sameBits(m.jointPosition(j, k), m.state().q[i + k])) << when << " joint " << j;
            EXPECT_TRUE(sameBits(m.jointVelocity(j, k), m.state().qdot[iv + k])) << when << " joint " << j;
            EXPECT_TRUE(sameBits(m.jointAcceleration(j, k), m.state().qddot[iv + k])) << when << " joint " << j;
            EXPECT_NEAR(m.jointPosition(j, k), rows[k].Phi, 1e-15 * (1 + std::fabs(rows[k].Phi))) << when << " joint " << j;
            EXPECT_NEAR(m.jointVelocity(j, k), rows[k].Phi_dot, 1e-14 * (1 + std::fabs(rows[k].Phi_dot))) << when << " joint " << j;
            EXPECT_NEAR(m.jointAcceleration(j, k), a, 1e-12 * (1 + std::fabs(a))) << when << " joint " << j;
            continue;
          }
          EXPECT_TRUE(sameBits(m.jointPosition(j, k), rows[k].Phi)) << formulation << " " << when << " joint " << j;
          EXPECT_TRUE(sameBits(m.jointVelocity(j, k), rows[k].Phi_dot)) << formulation << " " << when << " joint " << j;
          EXPECT_TRUE(sameBits(m.jointAcceleration(j, k), a)) << formulation << " " << when << " joint " << j;
        }
      }
    };
    const Mechanism::Snapshot start = m.snapshot();
    check("at the start");
    const double q0 = m.jointPosition(1, 0);
    for (int n = 0; n < 50; ++n) {
      m.step(1e-3);
      check("after a step");
    }
    EXPECT_NE(m.jointPosition(1, 0), q0);  // (it moved: the rows of the start would not do)
    m.restore(start);
    check("restored");
    EXPECT_EQ(m.jointPosition(1, 0), q0);
  }
}

}  // namespace
}  // namespace mechanism_sim
