// The constraints on joint coordinates (couplers.h). Oracles: for CoordinateCoupler (URDF
// <mimic>, q_a = m q_b + c), its value at poses built from known coordinates is
// q_a - m q_b - c, and its Jacobian and gamma match central finite differences of that value
// (fd_util.h, rotations perturbed on the manifold); for LimitConstraint, its row is zero while
// free and q_k - bound on the side it presses, the same finite differences. Both: the efforts
// their multiplier stands for (coordinateEfforts) act on the bodies as -Phi_q^T lambda, the
// constraint force of M a + Phi_q^T lambda = Q. Physics: a pendulum resting on a stop is held
// by the static gravity torque m g L cos q, with the sign that pushes it off the stop, on the
// side it presses; two pendulums tied by a mimic move as one body of inertia I_a m^2 + I_b
// (small-oscillation period 2 pi sqrt(I / K), K = m^2 m_a g L_a + m_b g L_b; under an effort
// alone, the constant acceleration m tau / I), in both formulations.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <string>

#include "bodies.h"
#include "coordinate_cases.h"
#include "fd_util.h"
#include "mechanism_sim/core/model/couplers.h"
#include "mechanism_sim/core/models.h"

namespace mechanism_sim {
namespace {

using test_util::CoordinateCase;
using test_util::placeJ;
using test_util::randomJoint;
using test_util::rotZ;
const auto& kCases = test_util::kCoordinateCases;

// Two joints and a coupler on them, with the bodies' states in the coupler's slot order.
struct CoupledPair {
  std::unique_ptr<Joint> a, b;
  std::unique_ptr<CoordinateCoupler> coupler;
  std::vector<Tracked> tracked;  // per joint id (a: 0, b: 1)
  double multiplier, offset;
};

Eigen::VectorXd evaluateCoupler(const CoupledPair& p, const std::vector<BodyKin>& kin, Eigen::MatrixXd* J = nullptr,
                                Eigen::VectorXd* gamma = nullptr) {
  const int nb = static_cast<int>(p.coupler->bodies().size());
  std::vector<const BodyKin*> ptrs(nb);
  for (int s = 0; s < nb; ++s) ptrs[s] = &kin[s];
  Eigen::VectorXd Phi(1), g(1);
  Eigen::MatrixXd Jc(1, 6 * nb);
  p.coupler->evaluate(ptrs.data(), EvalContext{p.tracked.data(), nullptr}, Phi, Jc, g);
  if (J) *J = Jc;
  if (gamma) *gamma = g;
  return Phi;
}

// The state of body `b` (a body number) among the coupler's slots.
int slotOf(const Constraint& c, int b) {
  for (size_t s = 0; s < c.bodies().size(); ++s)
    if (c.bodies()[s] == b) return static_cast<int>(s);
  return -1;
}

// Joint a between bodies 1 and 2; joint b between 2 and 3 (shared body) or 3 and 4.
// Coordinates q_a (k_a) and q_b (k_b) built into the poses; random velocities.
CoupledPair coupledPair(std::mt19937& rng, bool shared, double qa, double qb, std::vector<BodyKin>& kin,
                        int* k_a_out = nullptr) {
  std::uniform_int_distribution<int> pick(0, 3);
  const CoordinateCase& ca = kCases[pick(rng)];
  const CoordinateCase& cb = kCases[pick(rng)];
  CoupledPair p;
  p.a = randomJoint(ca, "a", 1, 2, rng);
  p.b = randomJoint(cb, "b", shared ? 2 : 3, shared ? 3 : 4, rng);
  p.a->setId(0);
  p.b->setId(1);
  const int k_a = std::uniform_int_distribution<int>(0, ca.dof - 1)(rng);
  const int k_b = std::uniform_int_distribution<int>(0, cb.dof - 1)(rng);
  if (k_a_out) *k_a_out = k_a;
  p.multiplier = std::uniform_real_distribution<double>(-3.0, 3.0)(rng);
  p.offset = std::uniform_real_distribution<double>(-1.0, 1.0)(rng);
  p.coupler = std::make_unique<CoordinateCoupler>("mimic", *p.a, k_a, *p.b, k_b, p.multiplier, p.offset);
  p.coupler->setId(2);
  // bodies by number: 1 random, 2 placed by joint a, 3 (shared) placed by joint b, else 3
  // random and 4 placed by joint b
  std::vector<BodyKin> by_number(5);
  by_number[1] = test::randomBody(rng);
  by_number[2] = placeJ(*p.a, ca, k_a, qa, by_number[1], test::randomBody(rng));
  if (shared) {
    by_number[3] = placeJ(*p.b, cb, k_b, qb, by_number[2], test::randomBody(rng));
  } else {
    by_number[3] = test::randomBody(rng);
    by_number[4] = placeJ(*p.b, cb, k_b, qb, by_number[3], test::randomBody(rng));
  }
  kin.clear();
  for (int b : p.coupler->bodies()) kin.push_back(by_number[b]);
  // the branch references of the pose built (the tracked angles are the coordinates)
  p.tracked = {p.a->initialTracked(), p.b->initialTracked(), Tracked{}};
  if (p.a->trackedSlot(k_a) >= 0) p.tracked[0][p.a->trackedSlot(k_a)] = qa;
  if (p.b->trackedSlot(k_b) >= 0) p.tracked[1][p.b->trackedSlot(k_b)] = qb;
  return p;
}

TEST(CoordinateCoupler, ValueIsTheCouplingOfTheCoordinatesThePoseWasBuiltFrom) {
  std::mt19937 rng(21);
  for (int n = 0; n < 200; ++n) {
    const double qa = std::uniform_real_distribution<double>(-2.5, 2.5)(rng);
    const double qb = std::uniform_real_distribution<double>(-2.5, 2.5)(rng);
    std::vector<BodyKin> kin;
    const CoupledPair p = coupledPair(rng, n % 2 == 0, qa, qb, kin);
    EXPECT_EQ(p.coupler->size(), 1);
    EXPECT_EQ(p.coupler->bodies().size(), n % 2 == 0 ? 3u : 4u) << "the union of the joints' bodies";
    const double expected = qa - p.multiplier * qb - p.offset;
    EXPECT_NEAR(evaluateCoupler(p, kin)(0), expected, 1e-12 * (1 + std::fabs(p.multiplier))) << n;
  }
}

TEST(CoordinateCoupler, JacobianAndGammaMatchFiniteDifferences) {
  std::mt19937 rng(22);
  for (int n = 0; n < 200; ++n) {
    std::vector<BodyKin> kin;
    const CoupledPair p = coupledPair(rng, n % 2 == 0, std::uniform_real_distribution<double>(-2.5, 2.5)(rng),
                                      std::uniform_real_distribution<double>(-2.5, 2.5)(rng), kin);
    Eigen::MatrixXd J;
    Eigen::VectorXd gamma;
    evaluateCoupler(p, kin, &J, &gamma);
    auto f = [&p](const std::vector<BodyKin>& k) { return evaluateCoupler(p, k); };
    const double scale = 1.0 + J.cwiseAbs().maxCoeff();
    EXPECT_LT((test::fdJacobian(f, kin) - J).cwiseAbs().maxCoeff(), 1e-7 * scale) << n;
    EXPECT_LT((test::fdGamma(f, kin) - gamma).cwiseAbs().maxCoeff(), 2e-5 * (1.0 + std::fabs(gamma(0)))) << n;
    // Phi_q v is the rate of Phi
    EXPECT_NEAR((J * test::velocityOf(kin))(0), test::fdRate(f, kin)(0), 1e-7 * scale) << n;
  }
}

// Effort signs: tau_a = -lambda along q_a and tau_b = m lambda along q_b act on the bodies as
// sum tau q_x^T = -lambda Phi_q^T, the constraint force.
TEST(CoordinateCoupler, ItsEffortsActOnTheBodiesAsTheConstraintForce) {
  std::mt19937 rng(23);
  for (int n = 0; n < 50; ++n) {
    std::vector<BodyKin> kin;
    const CoupledPair p = coupledPair(rng, n % 2 == 0, 0.3, -0.7, kin);
    Eigen::MatrixXd J;
    evaluateCoupler(p, kin, &J);
    CoordinateEffort efforts[2];
    ASSERT_EQ(p.coupler->coordinateEfforts(EvalContext{p.tracked.data(), nullptr}, efforts), 2);
    Eigen::RowVectorXd force = Eigen::RowVectorXd::Zero(J.cols());  // per unit lambda
    for (const CoordinateEffort& e : efforts) {
      Row rows[kMaxJointDofs];
      const Joint& joint = *e.joint;
      const int si = slotOf(*p.coupler, joint.bodyI()), sj = slotOf(*p.coupler, joint.bodyJ());
      joint.coordinates(kin[si], kin[sj], p.tracked[joint.id()], rows);
      force.segment<6>(6 * si) += e.sign * rows[e.k].J.segment<6>(0);
      force.segment<6>(6 * sj) += e.sign * rows[e.k].J.segment<6>(6);
    }
    EXPECT_LT((force + J).cwiseAbs().maxCoeff(), 1e-14 * (1 + J.cwiseAbs().maxCoeff())) << n;
  }
}

// A limit's row: zero while free, q_k - lower pressing on the lower bound, q_k - upper on the
// upper one; its Jacobian and gamma those of the coordinate (finite differences), its effort
// -lambda along q_k (the constraint force -lambda Phi_q^T).
TEST(LimitConstraint, RowFollowsTheSideItPressesAndMatchesFiniteDifferences) {
  std::mt19937 rng(24);
  const double lower = -0.4, upper = 0.9;
  for (int n = 0; n < 100; ++n) {
    const CoordinateCase& c = kCases[n % 4];
    auto joint = randomJoint(c, "j", 1, 2, rng);
    joint->setId(0);
    const int k = n % c.dof;
    const double q = std::uniform_real_distribution<double>(-1.5, 1.5)(rng);
    std::vector<BodyKin> kin = {test::randomBody(rng), test::randomBody(rng)};
    kin[1] = placeJ(*joint, c, k, q, kin[0], kin[1]);
    Tracked tracked = joint->initialTracked();
    if (joint->trackedSlot(k) >= 0) tracked[joint->trackedSlot(k)] = q;
    LimitConstraint limit(*joint, k, 0, lower, upper);
    EXPECT_EQ(limit.bodies(), joint->bodies());
    for (signed char side : {0, -1, 1}) {
      const signed char sides[1] = {side};
      const EvalContext ctx{&tracked, sides};
      auto eval = [&](const std::vector<BodyKin>& kk, Eigen::MatrixXd* J, Eigen::VectorXd* gamma) {
        const BodyKin* ptrs[2] = {&kk[0], &kk[1]};
        Eigen::VectorXd Phi(1), g(1);
        Phi(0) = g(0) = 7.0;
        Eigen::MatrixXd Jl = Eigen::MatrixXd::Constant(1, 12, 7.0);
        limit.evaluate(ptrs, ctx, Phi, Jl, g);
        if (J) *J = Jl;
        if (gamma) *gamma = g;
        return Phi;
      };
      Eigen::MatrixXd J;
      Eigen::VectorXd gamma;
      const double Phi = eval(kin, &J, &gamma)(0);
      CoordinateEffort effort[2];
      const int efforts = limit.coordinateEfforts(ctx, effort);
      if (side == 0) {
        EXPECT_EQ(Phi, 0.0);
        EXPECT_EQ(gamma(0), 0.0);
        EXPECT_EQ(J.cwiseAbs().maxCoeff(), 0.0);
        EXPECT_EQ(efforts, 0) << "a free limit exerts nothing";
        continue;
      }
      EXPECT_NEAR(Phi, q - (side < 0 ? lower : upper), 1e-12) << n << " side " << int(side);
      auto f = [&](const std::vector<BodyKin>& kk) { return eval(kk, nullptr, nullptr); };
      const double scale = 1.0 + J.cwiseAbs().maxCoeff();
      EXPECT_LT((test::fdJacobian(f, kin) - J).cwiseAbs().maxCoeff(), 1e-7 * scale) << n;
      EXPECT_LT(std::fabs(test::fdGamma(f, kin)(0) - gamma(0)), 2e-5 * (1.0 + std::fabs(gamma(0)))) << n;
      ASSERT_EQ(efforts, 1);
      EXPECT_EQ(effort[0].joint, joint.get());
      EXPECT_EQ(effort[0].k, k);
      EXPECT_EQ(effort[0].sign, -1.0);
    }
  }
}

// A limit on a linear combination s = c_a q_a + c_b q_b of two joints' coordinates (a
// coupling's backlash): its bodies the union of the joints', its row zero while free,
// s - bound on a side, its Jacobian and gamma those of the sum (finite differences), its
// efforts -c_i lambda along each q_i.
TEST(LimitConstraint, ALimitOnASumOfCoordinatesMatchesFiniteDifferences) {
  std::mt19937 rng(37);
  const double lower = -0.3, upper = 0.5, ca = 2.5, cb = -0.8;
  for (int n = 0; n < 60; ++n) {
    const CoordinateCase& c1 = kCases[n % 4];
    const CoordinateCase& c2 = kCases[(n / 4) % 4];
    auto a = randomJoint(c1, "a", 1, 2, rng), b = randomJoint(c2, "b", 3, 4, rng);
    a->setId(0), b->setId(1);
    const int ka = n % c1.dof, kb = (n / 3) % c2.dof;
    std::uniform_real_distribution<double> u(-1.5, 1.5);
    const double qa = u(rng), qb = u(rng);
    std::vector<BodyKin> kin = {test::randomBody(rng), test::randomBody(rng), test::randomBody(rng),
                                test::randomBody(rng)};
    kin[1] = placeJ(*a, c1, ka, qa, kin[0], kin[1]);
    kin[3] = placeJ(*b, c2, kb, qb, kin[2], kin[3]);
    std::vector<Tracked> tracked = {a->initialTracked(), b->initialTracked()};
    if (a->trackedSlot(ka) >= 0) tracked[0][a->trackedSlot(ka)] = qa;
    if (b->trackedSlot(kb) >= 0) tracked[1][b->trackedSlot(kb)] = qb;
    LimitConstraint limit("backlash", {{a.get(), ka, ca}, {b.get(), kb, cb}}, 0, lower, upper);
    EXPECT_EQ(limit.bodies(), std::vector<int>({1, 2, 3, 4}));
    for (signed char side : {0, -1, 1}) {
      const signed char sides[1] = {side};
      const EvalContext ctx{tracked.data(), sides};
      auto eval = [&](const std::vector<BodyKin>& kk, Eigen::MatrixXd* J, Eigen::VectorXd* gamma) {
        const BodyKin* ptrs[4] = {&kk[0], &kk[1], &kk[2], &kk[3]};
        Eigen::VectorXd Phi(1), g(1);
        Phi(0) = g(0) = 7.0;
        Eigen::MatrixXd Jl = Eigen::MatrixXd::Constant(1, 24, 7.0);
        limit.evaluate(ptrs, ctx, Phi, Jl, g);
        if (J) *J = Jl;
        if (gamma) *gamma = g;
        return Phi;
      };
      Eigen::MatrixXd J;
      Eigen::VectorXd gamma;
      const double Phi = eval(kin, &J, &gamma)(0);
      CoordinateEffort effort[kMaxCoordinateEfforts];
      const int efforts = limit.coordinateEfforts(ctx, effort);
      if (side == 0) {
        EXPECT_EQ(Phi, 0.0);
        EXPECT_EQ(J.cwiseAbs().maxCoeff(), 0.0);
        EXPECT_EQ(efforts, 0);
        continue;
      }
      EXPECT_NEAR(Phi, ca * qa + cb * qb - (side < 0 ? lower : upper), 1e-12 * (1 + std::fabs(ca * qa) + std::fabs(cb * qb)))
          << n;
      auto f = [&](const std::vector<BodyKin>& kk) { return eval(kk, nullptr, nullptr); };
      const double scale = 1.0 + J.cwiseAbs().maxCoeff();
      EXPECT_LT((test::fdJacobian(f, kin) - J).cwiseAbs().maxCoeff(), 1e-7 * scale) << n;
      EXPECT_LT(std::fabs(test::fdGamma(f, kin)(0) - gamma(0)), 2e-5 * scale * (1.0 + std::fabs(gamma(0)))) << n;
      ASSERT_EQ(efforts, 2);
      EXPECT_EQ(effort[0].joint, a.get());
      EXPECT_EQ(effort[0].sign, -ca);
      EXPECT_EQ(effort[1].joint, b.get());
      EXPECT_EQ(effort[1].k, kb);
      EXPECT_EQ(effort[1].sign, -cb);
    }
  }
}

constexpr double kG = 9.81;

// A bob of mass m (central inertia Ic about y) hanging at L below a pivot, on a revolute
// about +y, placed at angle q (q grows as the bob swings towards -x).
int addHangingPendulum(Mechanism& mech, const std::string& name, const Vector3d& pivot, double m, double L,
                       double Ic, double q) {
  const Eigen::AngleAxisd turn(q, Vector3d::UnitY());
  Body b = body(name, m, Ic * Matrix3d::Identity(), pivot + turn * Vector3d(0, 0, -L));
  b.p = Quaterniond(turn);
  const int body_index = mech.addBody(b);
  mech.addJoint(makeJoint("revolute", name + "_pivot", Mechanism::kGround, models::axisY(pivot), body_index,
                          models::axisY(Vector3d(0, 0, L))));
  return mech.numJoints() - 1;
}

IntegratorOptions formulation(const char* f) {
  IntegratorOptions io;
  io.formulation = f;
  return io;
}

// Resting on a stop, a pendulum is held there by the limit: the joint's effort is the
// static torque m g L cos(q_stop) that balances gravity, pushing away from the bound it
// presses, and the State says which bound (+1 upper, -1 lower). The bob starts horizontal
// and falls onto the stop (no rebound); gravity flipped makes it fall onto the other one.
TEST(LimitConstraint, APendulumRestsOnTheSideItPressesPushedOffIt) {
  const double m = 2.0, L = 0.7, stop = 0.5;
  for (const char* f : {"absolute", "joint"}) {
    for (int side : {1, -1}) {
      SCOPED_TRACE(std::string(f) + (side > 0 ? ", upper stop" : ", lower stop"));
      Mechanism mech;
      const int b = mech.addBody(body("bob", m, 1e-4 * Matrix3d::Identity(), Vector3d(L, 0, 0)));
      mech.addJoint(makeJoint("revolute", "pivot", Mechanism::kGround, models::axisY(Vector3d::Zero()), b,
                              models::axisY(Vector3d(-L, 0, 0))));
      // q grows as the bob falls (the rotation about +y takes +x to -z); gravity -z drives q
      // up onto the upper stop, +z down onto the lower one
      mech.setJointLimits(0, 0, -stop, stop);
      mech.setGravity(Vector3d(0, 0, -side * kG));
      mech.setIntegrator(formulation(f));
      mech.build();
      mech.assemble();
      for (int s = 0; s < 3000; ++s) mech.step(1e-3);
      ASSERT_EQ(mech.state().limit_side.size(), 1u);
      EXPECT_EQ(mech.state().limit_side[0], side);
      EXPECT_NEAR(mech.jointPosition(0, 0), side * stop, 1e-9);
      EXPECT_NEAR(mech.jointVelocity(0, 0), 0.0, 1e-9);
      // gravity's torque along q is side m g L cos(q); the stop's balances it
      const double torque = m * kG * L * std::cos(stop);
      EXPECT_NEAR(mech.jointEffort(0, 0), -side * torque, 1e-9 * torque);
    }
  }
}

// Two hanging pendulums, a mimic q_a = mult q_b between their joints: one degree of freedom
// q_b with kinetic energy (I_a mult^2 + I_b) q_b_dot^2 / 2 and, for small angles, potential
// (mult^2 m_a g L_a + m_b g L_b) q_b^2 / 2: q_b = q0 cos(2 pi t / T), T = 2 pi sqrt(I / K).
// From q0 = 1e-3 rad the pendulum's anharmonic phase drift is about q0^2 / 16 a radian, 4e-7
// of q0 over a period; I_a mult + I_b, or I_a + I_b, would be off by tens of percent.
TEST(CoordinateCoupler, MimicPendulumsSwingAsOneWithTheEffectiveInertia) {
  const double m_a = 1.0, L_a = 0.5, Ic_a = 0.01, m_b = 2.0, L_b = 1.0, Ic_b = 0.02, mult = -1.5, q0 = 1e-3;
  const double I = mult * mult * (m_a * L_a * L_a + Ic_a) + (m_b * L_b * L_b + Ic_b);
  const double K = mult * mult * m_a * kG * L_a + m_b * kG * L_b;
  const double omega = std::sqrt(K / I), T = 2 * M_PI / omega;
  for (const char* f : {"absolute", "joint"}) {
    SCOPED_TRACE(f);
    Mechanism mech;
    const int ja = addHangingPendulum(mech, "a", Vector3d(0, 0, 0), m_a, L_a, Ic_a, mult * q0);
    const int jb = addHangingPendulum(mech, "b", Vector3d(2, 0, 0), m_b, L_b, Ic_b, q0);
    mech.addCoupler("mimic", ja, 0, jb, 0, mult, 0.0);
    mech.setIntegrator(formulation(f));
    mech.build();
    mech.assemble();
    ASSERT_STREQ(mech.formulation(), f);
    EXPECT_NEAR(mech.jointPosition(jb, 0), q0, 1e-12);
    EXPECT_NEAR(mech.jointPosition(ja, 0), mult * q0, 1e-12);
    const double h = 1e-3;
    double worst = 0, worst_tie = 0;
    for (long s = 1, n = std::lround(1.25 * T / h); s <= n; ++s) {
      mech.step(h);
      const double t = mech.time(), qb = mech.jointPosition(jb, 0);
      worst = std::max(worst, std::fabs(qb - q0 * std::cos(omega * t)));
      worst_tie = std::max(worst_tie, std::fabs(mech.jointPosition(ja, 0) - mult * qb));
    }
    std::printf("[mimic pendulums, %s] T = %.6f s, largest |q_b - q0 cos(2 pi t / T)| over 1.25 T: %.1e q0\n", f, T,
                worst / q0);
    EXPECT_LT(worst, 1e-5 * q0) << "T = " << T << " s";
    EXPECT_LT(worst_tie, 1e-11) << "the slave follows q_a = m q_b (to the position tolerance)";
  }
}

// Without gravity, an effort tau on the slave (a) turns the pair as one: q_b'' = mult tau / I
// exactly, q_a = mult q_b + offset throughout (RK4 is exact on a constant acceleration).
TEST(CoordinateCoupler, AnEffortOnTheSlaveAcceleratesThePairByTheEffectiveInertia) {
  const double m_a = 1.0, L_a = 0.5, Ic_a = 0.01, m_b = 2.0, L_b = 1.0, Ic_b = 0.02, mult = -1.5, offset = 0.3;
  const double tau = 0.8;
  const double I = mult * mult * (m_a * L_a * L_a + Ic_a) + (m_b * L_b * L_b + Ic_b);
  for (const char* f : {"absolute", "joint"}) {
    SCOPED_TRACE(f);
    Mechanism mech;
    const int ja = addHangingPendulum(mech, "a", Vector3d(0, 0, 0), m_a, L_a, Ic_a, offset);
    const int jb = addHangingPendulum(mech, "b", Vector3d(2, 0, 0), m_b, L_b, Ic_b, 0.0);
    mech.addCoupler("mimic", ja, 0, jb, 0, mult, offset);
    mech.setGravity(Vector3d::Zero());
    mech.setIntegrator(formulation(f));
    mech.build();
    mech.assemble();
    mech.setJointEffort(ja, 0, tau);
    for (int s = 0; s < 1000; ++s) mech.step(1e-3);
    const double t = mech.time(), qb = 0.5 * mult * tau / I * t * t;
    EXPECT_NEAR(mech.jointPosition(jb, 0), qb, 1e-10 * std::fabs(qb));
    EXPECT_NEAR(mech.jointVelocity(jb, 0), mult * tau / I * t, 1e-10 * std::fabs(mult * tau / I * t));
    EXPECT_NEAR(mech.jointPosition(ja, 0), mult * qb + offset, 1e-10 * std::fabs(mult * qb));
  }
}

}  // namespace
}  // namespace mechanism_sim
