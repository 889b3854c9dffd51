// The linear coupling sum_i c_i q_i = c_0 (coupling.h). Oracles: its value at poses built
// from known coordinates is sum c_i q_i - c_0; its Jacobian and gamma match central finite
// differences of that value (fd_util.h, rotations perturbed on the manifold), over three
// joints on six bodies (more than a two-joint coupler's four); the efforts its multiplier
// stands for act on the bodies as -Phi_q^T lambda. Physics, in both formulations, which
// also agree with each other to round-off on the accelerations and the reaction at one
// state: a planetary train with its ring held turns the carrier at Z_s / (Z_s + Z_r) of the
// sun's speed (Willis); a differential driven at its carrier and one output moves the other
// output by q_R = 2 q_C - q_L and carries its load, lambda = tau_load / c_R, with the drives'
// power equal to the load's; a free-swinging geared pair keeps 1/2 qdot^T M qdot + V; an
// effort on the output of a gear pair turns the input at r tau / (I_a + r^2 I_b).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <string>

#include "bodies.h"
#include "coordinate_cases.h"
#include "fd_util.h"
#include "mechanism_sim/core/model/coupling.h"
#include "mechanism_sim/core/models.h"

namespace mechanism_sim {
namespace {

using test_util::CoordinateCase;
using test_util::placeJ;
using test_util::randomJoint;
using test_util::rotZ;
const auto& kCases = test_util::kCoordinateCases;

// Three joints on bodies (1, 2), (3, 4), (5, 6), or sharing bodies along a chain (1, 2),
// (2, 3), (3, 4); a coupling of one coordinate of each, the poses built from known q_i.
struct Coupled {
  std::vector<std::unique_ptr<Joint>> joints;
  std::unique_ptr<LinearCoupling> coupling;
  std::vector<Tracked> tracked;
  std::vector<double> c, q;
  double c0 = 0;
};

Coupled coupled(std::mt19937& rng, bool chain, std::vector<BodyKin>& kin) {
  Coupled p;
  std::vector<BodyKin> by_number(7);
  std::vector<CouplingTerm> terms;
  std::uniform_real_distribution<double> u(-2.5, 2.5);
  by_number[1] = test::randomBody(rng);
  for (int i = 0; i < 3; ++i) {
    const CoordinateCase& cc = kCases[std::uniform_int_distribution<int>(0, 3)(rng)];
    const int bi = chain ? i + 1 : 2 * i + 1, bj = bi + 1;
    p.joints.push_back(randomJoint(cc, "j" + std::to_string(i), bi, bj, rng));
    Joint& J = *p.joints.back();
    J.setId(i);
    const int k = std::uniform_int_distribution<int>(0, cc.dof - 1)(rng);
    const double q = u(rng), c = u(rng) + (u(rng) > 0 ? 3.0 : -3.0);
    if (!chain) by_number[bi] = test::randomBody(rng);
    by_number[bj] = placeJ(J, cc, k, q, by_number[bi], test::randomBody(rng));
    Tracked tr = J.initialTracked();
    if (J.trackedSlot(k) >= 0) tr[J.trackedSlot(k)] = q;
    p.tracked.push_back(tr);
    p.c.push_back(c), p.q.push_back(q);
    terms.push_back({&J, k, c});
  }
  p.c0 = u(rng);
  p.coupling = std::make_unique<LinearCoupling>("gears", terms, p.c0);
  p.coupling->setId(3);
  p.tracked.push_back(Tracked{});
  kin.clear();
  for (int b : p.coupling->bodies()) kin.push_back(by_number[b]);
  return p;
}

Eigen::VectorXd evaluate(const Coupled& p, const std::vector<BodyKin>& kin, Eigen::MatrixXd* J = nullptr,
                         Eigen::VectorXd* gamma = nullptr) {
  const int nb = static_cast<int>(p.coupling->bodies().size());
  std::vector<const BodyKin*> ptrs(nb);
  for (int s = 0; s < nb; ++s) ptrs[s] = &kin[s];
  Eigen::VectorXd Phi(1), g(1);
  Eigen::MatrixXd Jc = Eigen::MatrixXd::Constant(1, 6 * nb, 7.0);
  p.coupling->evaluate(ptrs.data(), EvalContext{p.tracked.data(), nullptr}, Phi, Jc, g);
  if (J) *J = Jc;
  if (gamma) *gamma = g;
  return Phi;
}

TEST(LinearCoupling, ValueIsTheSumOfTheCoordinatesThePoseWasBuiltFrom) {
  std::mt19937 rng(31);
  for (int n = 0; n < 200; ++n) {
    std::vector<BodyKin> kin;
    const Coupled p = coupled(rng, n % 2 == 0, kin);
    EXPECT_EQ(p.coupling->bodies().size(), n % 2 == 0 ? 4u : 6u) << "the union of the joints' bodies";
    double expected = -p.c0, scale = std::fabs(p.c0);
    for (int i = 0; i < 3; ++i) expected += p.c[i] * p.q[i], scale += std::fabs(p.c[i] * p.q[i]);
    EXPECT_NEAR(evaluate(p, kin)(0), expected, 1e-14 * scale * 10) << n;
  }
}

TEST(LinearCoupling, JacobianAndGammaMatchFiniteDifferences) {
  std::mt19937 rng(32);
  for (int n = 0; n < 200; ++n) {
    std::vector<BodyKin> kin;
    const Coupled p = coupled(rng, n % 2 == 0, kin);
    Eigen::MatrixXd J;
    Eigen::VectorXd gamma;
    evaluate(p, kin, &J, &gamma);
    auto f = [&p](const std::vector<BodyKin>& k) { return evaluate(p, k); };
    const double scale = 1.0 + J.cwiseAbs().maxCoeff();
    EXPECT_LT((test::fdJacobian(f, kin) - J).cwiseAbs().maxCoeff(), 1e-7 * scale) << n;
    EXPECT_LT((test::fdGamma(f, kin) - gamma).cwiseAbs().maxCoeff(), 2e-5 * (scale + std::fabs(gamma(0)))) << n;
    EXPECT_NEAR((J * test::velocityOf(kin))(0), test::fdRate(f, kin)(0), 1e-7 * scale) << n;
  }
}

// Efforts -c_i lambda along q_i act on the bodies as -lambda Phi_q^T, the constraint force.
TEST(LinearCoupling, ItsEffortsActOnTheBodiesAsTheConstraintForce) {
  std::mt19937 rng(33);
  for (int n = 0; n < 50; ++n) {
    std::vector<BodyKin> kin;
    const Coupled p = coupled(rng, n % 2 == 0, kin);
    Eigen::MatrixXd J;
    evaluate(p, kin, &J);
    CoordinateEffort efforts[kMaxCoordinateEfforts];
    ASSERT_EQ(p.coupling->coordinateEfforts(EvalContext{p.tracked.data(), nullptr}, efforts), 3);
    Eigen::RowVectorXd force = Eigen::RowVectorXd::Zero(J.cols());
    const auto& bodies = p.coupling->bodies();
    auto slot = [&](int b) { return static_cast<int>(std::find(bodies.begin(), bodies.end(), b) - bodies.begin()); };
    for (int e = 0; e < 3; ++e) {
      Row rows[kMaxJointDofs];
      const Joint& joint = *efforts[e].joint;
      const int si = slot(joint.bodyI()), sj = slot(joint.bodyJ());
      joint.coordinates(kin[si], kin[sj], p.tracked[joint.id()], rows);
      force.segment<6>(6 * si) += efforts[e].sign * rows[efforts[e].k].J.segment<6>(0);
      force.segment<6>(6 * sj) += efforts[e].sign * rows[efforts[e].k].J.segment<6>(6);
    }
    EXPECT_LT((force + J).cwiseAbs().maxCoeff(), 1e-14 * (1 + J.cwiseAbs().maxCoeff())) << n;
  }
}

// ---- mechanisms

constexpr double kG = 9.81;

IntegratorOptions formulation(const char* f) {
  IntegratorOptions io;
  io.formulation = f;
  return io;
}

// A disc (mass m, polar inertia I about its axis, 0.6 I across) on a revolute about the
// world z through `at`, to ground.
int addDisc(Mechanism& mech, const std::string& name, const Vector3d& at, double m, double I) {
  const int b = mech.addBody(body(name, m, Vector3d(0.6 * I, 0.6 * I, I).asDiagonal(), at));
  JointFrame fi, fj;
  fi.sp_B = at;
  mech.addJoint(makeJoint("revolute", name + "_axle", Mechanism::kGround, fi, b, fj));
  return mech.numJoints() - 1;
}

// A bob of mass m (central inertia Ic about y) hanging at L below a pivot, on a revolute
// about +y, placed at angle q.
int addPendulum(Mechanism& mech, const std::string& name, const Vector3d& pivot, double m, double L, double Ic,
                double q) {
  const Eigen::AngleAxisd turn(q, Vector3d::UnitY());
  Body b = body(name, m, Ic * Matrix3d::Identity(), pivot + turn * Vector3d(0, 0, -L));
  b.p = Quaterniond(turn);
  const int body_index = mech.addBody(b);
  mech.addJoint(makeJoint("revolute", name + "_pivot", Mechanism::kGround, models::axisY(pivot), body_index,
                          models::axisY(Vector3d(0, 0, L))));
  return mech.numJoints() - 1;
}

// The joint accelerations and the coupling's reaction at the current state: both
// formulations, at the same state (the first one, assembled alike), agree on them to
// round-off.
struct Instant {
  std::vector<double> acc;
  double lambda = 0;
};
Instant instant(const Mechanism& mech, const std::vector<int>& joints, int coupling) {
  Instant in;
  for (int k : joints) in.acc.push_back(mech.jointAcceleration(k, 0));
  in.lambda = mech.couplingReaction(coupling);
  return in;
}
void expectSameInstant(const Instant& a, const Instant& j) {
  double scale = std::fabs(a.lambda);
  for (double x : a.acc) scale = std::max(scale, std::fabs(x));
  ASSERT_GT(scale, 0.0) << "the state has accelerations or a reaction";
  for (size_t k = 0; k < a.acc.size(); ++k) EXPECT_NEAR(a.acc[k], j.acc[k], 1e-13 * scale) << k;
  EXPECT_NEAR(a.lambda, j.lambda, 1e-13 * scale);
  double worst = std::fabs(a.lambda - j.lambda);
  for (size_t k = 0; k < a.acc.size(); ++k) worst = std::max(worst, std::fabs(a.acc[k] - j.acc[k]));
  std::printf("  absolute vs joint at the first state: largest difference %.1e of %.3g\n", worst, scale);
}

// Willis: Z_s q_s + Z_r q_r - (Z_s + Z_r) q_c = 0. The ring held (a velocity drive at 0),
// an effort on the sun: the carrier turns at Z_s / (Z_s + Z_r) of the sun's speed, and its
// acceleration is that of one inertia I_s + k^2 I_c (k that ratio) under the sun's effort.
TEST(LinearCoupling, PlanetaryTrainWithItsRingHeldTurnsTheCarrierByWillis) {
  const double Zs = 24, Zr = 72, Is = 0.002, Ir = 0.05, Ic = 0.03, tau = 0.5;
  const double k = Zs / (Zs + Zr), I = Is + k * k * Ic;
  Instant first[2];
  int n = 0;
  for (const char* f : {"absolute", "joint"}) {
    SCOPED_TRACE(f);
    auto mech = std::make_unique<Mechanism>();
    const int sun = addDisc(*mech, "sun", Vector3d::Zero(), 0.5, Is);
    const int ring = addDisc(*mech, "ring", Vector3d::Zero(), 2.0, Ir);
    const int carrier = addDisc(*mech, "carrier", Vector3d::Zero(), 1.0, Ic);
    const int willis = mech->addCoupling("planetary", {{sun, 0, Zs}, {ring, 0, Zr}, {carrier, 0, -(Zs + Zr)}}, 0.0);
    mech->addDrive(ring, 0, DriveProfile::velocity(0.0));
    mech->setGravity(Vector3d(0, 0, -kG));
    mech->setIntegrator(formulation(f));
    mech->build();
    mech->setJointEffort(sun, 0, tau);  // (before assembly: its accelerations take it)
    mech->assemble();
    ASSERT_STREQ(mech->formulation(), f);
    first[n++] = instant(*mech, {sun, ring, carrier}, willis);
    for (int s = 0; s < 1000; ++s) mech->step(1e-3);
    const double t = mech->time(), w_s = tau / I * t;
    EXPECT_NEAR(mech->jointVelocity(sun, 0), w_s, 1e-10 * w_s);
    EXPECT_NEAR(mech->jointVelocity(carrier, 0), k * mech->jointVelocity(sun, 0), 1e-12 * w_s);
    EXPECT_NEAR(mech->jointPosition(carrier, 0), k * mech->jointPosition(sun, 0), 1e-12 * w_s);
    EXPECT_NEAR(mech->jointVelocity(ring, 0), 0.0, 1e-12 * w_s);
    // the sun's effort less its own inertia's share is what the mesh carries: -Z_s lambda
    const double lambda = mech->couplingReaction(willis);
    EXPECT_NEAR(-Zs * lambda, -(tau - Is * tau / I), 1e-10 * tau);
    std::printf("[planetary, %s] carrier / sun = %.15f (Z_s / (Z_s + Z_r) = %.15f), lambda = %.12f\n", f,
                mech->jointVelocity(carrier, 0) / mech->jointVelocity(sun, 0), k, lambda);
  }
  expectSameInstant(first[0], first[1]);
}

// A differential: q_L + q_R - 2 q_C = 0. The carrier and the left output driven at constant
// rates (the two inputs), a constant load tau on the right output: q_R = 2 q_C - q_L exactly,
// the mesh carries the load (lambda = tau / c_R, q_R's acceleration 0), and the drives'
// power equals the load's taken back (power in = power out).
TEST(LinearCoupling, DrivenDifferentialMovesItsOutputExactlyAndBalancesPower) {
  const double w_c = 3.0, w_l = 1.2, tau = -0.7;
  Instant first[2];
  int n = 0;
  for (const char* f : {"absolute", "joint"}) {
    SCOPED_TRACE(f);
    auto mech = std::make_unique<Mechanism>();
    const int left = addDisc(*mech, "left", Vector3d(-0.3, 0, 0), 1.0, 0.01);
    const int right = addDisc(*mech, "right", Vector3d(0.3, 0, 0), 1.2, 0.015);
    const int carrier = addDisc(*mech, "carrier", Vector3d::Zero(), 3.0, 0.04);
    const int diff = mech->addCoupling("differential", {{left, 0, 1.0}, {right, 0, 1.0}, {carrier, 0, -2.0}}, 0.0);
    mech->addDrive(carrier, 0, DriveProfile::velocity(w_c));
    mech->addDrive(left, 0, DriveProfile::velocity(w_l));
    mech->setGravity(Vector3d(0, 0, -kG));
    mech->setIntegrator(formulation(f));
    mech->build();
    mech->setJointEffort(right, 0, tau);
    mech->assemble();
    ASSERT_STREQ(mech->formulation(), f);
    first[n++] = instant(*mech, {left, right, carrier}, diff);
    double worst_power = 0;
    for (int s = 0; s < 500; ++s) {
      mech->step(2e-3);
      double power = 0;
      for (int j : {left, right, carrier}) power += mech->jointEffort(j, 0) * mech->jointVelocity(j, 0);
      worst_power = std::max(worst_power, std::fabs(power));
    }
    const double t = mech->time();
    EXPECT_NEAR(mech->jointPosition(right, 0), (2 * w_c - w_l) * t, 1e-12 * (2 * w_c - w_l) * t);
    EXPECT_NEAR(mech->jointVelocity(right, 0), 2 * w_c - w_l, 1e-12 * w_c);
    EXPECT_NEAR(mech->couplingReaction(diff), tau / 1.0, 1e-10 * std::fabs(tau));
    const double p_load = std::fabs(tau * (2 * w_c - w_l));
    EXPECT_LT(worst_power, 1e-10 * p_load) << "drives' power + load's power";
    std::printf("[differential, %s] q_R = %.15f (2 q_C - q_L = %.15f), largest |power in - power out| %.1e W of %.3f W\n",
                f, mech->jointPosition(right, 0), (2 * w_c - w_l) * t, worst_power, p_load);
  }
  expectSameInstant(first[0], first[1]);
}

// Two pendulums meshing as gears (Z_a q_a + Z_b q_b = 0) swing freely from 1 rad, damping
// off: 1/2 qdot^T M qdot + V stays put to the integrator's tolerance.
TEST(LinearCoupling, FreeSwingingGearPairConservesEnergy) {
  const double Za = 20, Zb = 30, q0 = 1.0;
  Instant first[2];
  int n = 0;
  for (const char* f : {"absolute", "joint"}) {
    SCOPED_TRACE(f);
    auto mech = std::make_unique<Mechanism>();
    const int a = addPendulum(*mech, "a", Vector3d::Zero(), 1.0, 0.4, 0.01, q0);
    const int b = addPendulum(*mech, "b", Vector3d(1, 0, 0), 2.0, 0.6, 0.02, -Za / Zb * q0);
    const int mesh = mech->addCoupling("mesh", {{a, 0, Za}, {b, 0, Zb}}, 0.0);
    mech->setIntegrator(formulation(f));
    mech->build();
    mech->assemble();
    ASSERT_STREQ(mech->formulation(), f);
    first[n++] = instant(*mech, {a, b}, mesh);
    const double E0 = mech->kineticEnergy() + mech->potentialEnergy(), V0 = std::fabs(mech->potentialEnergy());
    double worst = 0, worst_tie = 0, swing = 0;
    for (int s = 0; s < 3000; ++s) {
      mech->step(1e-3);
      worst = std::max(worst, std::fabs(mech->kineticEnergy() + mech->potentialEnergy() - E0));
      worst_tie = std::max(worst_tie, std::fabs(Za * mech->jointPosition(a, 0) + Zb * mech->jointPosition(b, 0)));
      swing = std::max(swing, mech->kineticEnergy());
    }
    std::printf("[gear pair, %s] largest energy drift over 3 s: %.1e J of %.3f J swinging\n", f, worst, swing);
    EXPECT_GT(swing, 0.1 * V0) << "it swings";
    EXPECT_LT(worst, 1e-8 * swing);
    EXPECT_LT(worst_tie, 1e-9 * Za);
  }
  expectSameInstant(first[0], first[1]);
}

// Two-way: an effort tau on the output b of Z_a q_a + Z_b q_b = 0 turns the input a as one
// inertia: q_a'' = r tau / (I_a + r^2 I_b), r = -Z_a / Z_b (q_b = r q_a).
TEST(LinearCoupling, AnEffortOnTheOutputTurnsTheInput) {
  const double Za = 15, Zb = 45, Ia = 0.004, Ib = 0.09, tau = 1.5;
  const double r = -Za / Zb, acc = r * tau / (Ia + r * r * Ib);
  for (const char* f : {"absolute", "joint"}) {
    SCOPED_TRACE(f);
    Mechanism mech;
    const int a = addDisc(mech, "pinion", Vector3d::Zero(), 0.3, Ia);
    const int b = addDisc(mech, "wheel", Vector3d(0.3, 0, 0), 2.0, Ib);
    const int mesh = mech.addCoupling("mesh", {{a, 0, Za}, {b, 0, Zb}}, 0.0);
    mech.setGravity(Vector3d(0, 0, -kG));
    mech.setIntegrator(formulation(f));
    mech.build();
    mech.assemble();
    mech.setJointEffort(b, 0, tau);
    for (int s = 0; s < 1000; ++s) mech.step(1e-3);
    const double t = mech.time();
    EXPECT_NEAR(mech.jointVelocity(a, 0), acc * t, 1e-10 * std::fabs(acc * t));
    EXPECT_NEAR(mech.jointPosition(a, 0), 0.5 * acc * t * t, 1e-10 * std::fabs(acc * t * t));
    EXPECT_NEAR(mech.jointPosition(b, 0), r * mech.jointPosition(a, 0), 1e-12);
    // the pinion's only load is the mesh's -Z_a lambda
    EXPECT_NEAR(-Za * mech.couplingReaction(mesh), Ia * acc, 1e-10 * std::fabs(Ia * acc));
  }
}

// A coupling over three joints on six moving bodies (a chain, each joint's bodies its own):
// more bodies than a coupler's, the same answers in both formulations at the first instant
// and after 0.5 s of free swinging (to the integrators' tolerance), and energy kept.
TEST(LinearCoupling, ACouplingOverSixBodiesRunsInBothFormulations) {
  std::unique_ptr<Mechanism> run[2];
  int n = 0;
  double E_drift[2];
  for (const char* f : {"absolute", "joint"}) {
    SCOPED_TRACE(f);
    auto mech = std::make_unique<Mechanism>();
    int parent = Mechanism::kGround;
    Vector3d at = Vector3d::Zero();
    for (int k = 0; k < 6; ++k) {  // a chain of rods hanging along -z, hinged about y
      const Vector3d centre = at + Vector3d(0, 0, -0.2);
      const int b = mech->addBody(body("rod" + std::to_string(k), 0.5, Vector3d(0.007, 0.007, 0.001).asDiagonal(), centre));
      JointFrame fi, fj;
      fi = models::axisY(parent == Mechanism::kGround ? at : Vector3d(0, 0, -0.2));
      fj = models::axisY(Vector3d(0, 0, 0.2));
      mech->addJoint(makeJoint("revolute", "hinge" + std::to_string(k), parent, fi, b, fj));
      parent = b, at = centre + Vector3d(0, 0, -0.2);
    }
    // hinges 1, 3, 5 join rods (0, 1), (2, 3), (4, 5)
    const int c = mech->addCoupling("three", {{1, 0, 1.0}, {3, 0, -2.0}, {5, 0, 0.5}}, 0.0);
    EXPECT_EQ(mech->system().constraints[c]->bodies().size(), 6u);
    mech->setIntegrator(formulation(f));
    mech->build();
    mech->assemble({{0, 0, 0.8}, {1, 0, 0.4}, {2, 0, -0.3}, {3, 0, 0.1}});
    ASSERT_STREQ(mech->formulation(), f);
    const double E0 = mech->kineticEnergy() + mech->potentialEnergy();
    double worst = 0;
    for (int s = 0; s < 500; ++s) {
      mech->step(1e-3);
      worst = std::max(worst, std::fabs(mech->kineticEnergy() + mech->potentialEnergy() - E0));
    }
    E_drift[n] = worst;
    EXPECT_NEAR(mech->jointPosition(1, 0) - 2 * mech->jointPosition(3, 0) + 0.5 * mech->jointPosition(5, 0), 0.0, 1e-10);
    run[n++] = std::move(mech);
  }
  std::printf("[six bodies] energy drift over 0.5 s: %.1e J (absolute), %.1e J (joint)\n", E_drift[0], E_drift[1]);
  for (double d : E_drift) EXPECT_LT(d, 1e-7);
  for (int j = 0; j < 6; ++j)
    EXPECT_NEAR(run[0]->jointPosition(j, 0), run[1]->jointPosition(j, 0), 1e-7) << "hinge " << j;
}

// addCoupling refuses what no coupling can be, naming it.
TEST(LinearCoupling, BadCouplingsAreNamed) {
  auto expectError = [](const std::vector<Mechanism::CouplingCoordinate>& terms, double c0, const std::string& says) {
    Mechanism mech;
    addDisc(mech, "a", Vector3d::Zero(), 1, 0.1);
    addDisc(mech, "b", Vector3d(1, 0, 0), 1, 0.1);
    try {
      mech.addCoupling("g", terms, c0);
      ADD_FAILURE() << "accepted: " << says;
    } catch (const ModelError& e) {
      EXPECT_NE(std::string(e.what()).find("coupling 'g'"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(says), std::string::npos) << e.what();
    }
  };
  expectError({{0, 0, 1.0}}, 0.0, "couples 1 coordinates");
  expectError({{0, 0, 1.0}, {1, 0, 0.0}}, 0.0, "coefficient of joint 'b_axle'");
  expectError({{0, 0, 1.0}, {1, 0, NAN}}, 0.0, "finite and non-zero");
  expectError({{0, 0, 1.0}, {1, 0, 1.0}}, INFINITY, "constant must be finite");
  expectError({{0, 0, 1.0}, {0, 0, 2.0}}, 0.0, "joint 'a_axle' appears twice");
  expectError({{0, 0, 1.0}, {2, 0, 2.0}}, 0.0, "no such joint coordinate");
}

// Backlash: Z_a q_a + Z_b q_b = 0 with a clearance b, |Z_a q_a + Z_b q_b| <= b/2
// (addBacklashCoupling). The pinion a, driven at w from the centre of the gap, turns alone:
// the wheel stays exactly at rest, its reaction 0, until the pinion has turned b / (2 Z_a)
// (t* = b / (2 Z_a w)); the stop it then reaches is inelastic, as a joint limit's: the
// wheel takes the speed the mesh gives, w_b = -Z_a w / Z_b, at once, and carries its
// damping's load through the mesh, lambda = c Z_a w / Z_b^2 (on the wheel, -Z_b lambda =
// c w_b). Both formulations, which agree.
TEST(LinearCoupling, ADrivenGearWithBacklashMovesItsLoadOnlyAfterTakingUpTheClearance) {
  const double Za = 20, Zb = 50, b = 0.4, w = 2.0, c = 0.3, h = 1e-3;
  const double t_contact = b / (2 * Za * w), w_b = -Za * w / Zb, lambda = c * Za * w / (Zb * Zb);
  double after[2][2];
  int n = 0;
  for (const char* f : {"absolute", "joint"}) {
    SCOPED_TRACE(f);
    Mechanism mech;
    const int a = addDisc(mech, "pinion", Vector3d::Zero(), 0.3, 0.002);
    const int wheel = addDisc(mech, "wheel", Vector3d(0.35, 0, 0), 2.0, 0.05);
    const int gap = mech.addBacklashCoupling("mesh", {{a, 0, Za}, {wheel, 0, Zb}}, 0.0, b);
    mech.addDrive(a, 0, DriveProfile::velocity(w));
    mech.setJointDamping(wheel, 0, c);
    mech.setGravity(Vector3d(0, 0, -kG));
    mech.setIntegrator(formulation(f));
    mech.build();
    mech.assemble();
    ASSERT_STREQ(mech.formulation(), f);
    double first_motion = -1;
    for (int s = 0; s < 100; ++s) {
      const double t0 = mech.time();
      mech.step(h);
      const double t = mech.time();
      if (t < t_contact) {  // in the gap: the wheel at rest, no load through the mesh
        EXPECT_NEAR(mech.jointPosition(wheel, 0), 0.0, 1e-15) << "t = " << t;
        EXPECT_NEAR(mech.jointVelocity(wheel, 0), 0.0, 1e-14 * std::fabs(w_b)) << "t = " << t;
        EXPECT_EQ(mech.limitReaction(gap), 0.0) << "t = " << t;
      }
      if (first_motion < 0 && std::fabs(mech.jointVelocity(wheel, 0)) > 1e-6 * std::fabs(w_b)) {
        first_motion = t;
        EXPECT_LE(t0, t_contact + 1e-12) << "the stop is taken at the end of the step that reaches it";
        EXPECT_GE(t, t_contact - 1e-12);
      }
      if (t > t_contact + h) {  // engaged: on the stop, the mesh's speed and load
        EXPECT_NEAR(Za * mech.jointPosition(a, 0) + Zb * mech.jointPosition(wheel, 0), b / 2, 1e-12 * b);
        EXPECT_NEAR(mech.jointVelocity(wheel, 0), w_b, 1e-12 * std::fabs(w_b));
        EXPECT_NEAR(mech.limitReaction(gap), lambda, 1e-9 * lambda);
      }
    }
    ASSERT_GT(first_motion, 0.0) << "the wheel never moved";
    after[n][0] = mech.jointPosition(wheel, 0), after[n][1] = mech.limitReaction(gap);
    std::printf("[backlash, driven, %s] wheel first moves in the step ending at %.4f s (contact %.4f s); w_b %.15f "
                "(-Z_a w / Z_b %.15f), lambda %.12f (c Z_a w / Z_b^2 %.12f)\n",
                f, first_motion, t_contact, mech.jointVelocity(wheel, 0), w_b, mech.limitReaction(gap), lambda);
    ++n;
  }
  EXPECT_NEAR(after[0][0], after[1][0], 1e-12);
  EXPECT_NEAR(after[0][1], after[1][1], 1e-9 * lambda);
}

// A free pinion spinning at w0 meets a wheel at rest across the clearance: the wheel stays
// at rest until the pinion has turned b / (2 Z_a); the stop is the limits' inelastic impact,
// an impulse P along the stop's row (-Z_a P on the pinion, -Z_b P on the wheel), so
// I_a w_a / Z_a - I_b w_b / Z_b is kept and Z_a w_a + Z_b w_b = 0 after:
// w_a = I_a w0 / (I_a + I_b Z_a^2 / Z_b^2), and the kinetic energy falls by the impact's loss.
TEST(LinearCoupling, AFreePinionMeetsItsWheelAcrossTheBacklashInelastically) {
  const double Za = 12, Zb = 36, b = 0.3, w0 = 5.0, Ia = 0.004, Ib = 0.06, h = 1e-3;
  const double t_contact = b / (2 * Za * w0);
  const double w_a = Ia * w0 / (Ia + Ib * Za * Za / (Zb * Zb)), w_b = -Za * w_a / Zb;
  for (const char* f : {"absolute", "joint"}) {
    SCOPED_TRACE(f);
    Mechanism mech;
    const int a = addDisc(mech, "pinion", Vector3d::Zero(), 0.2, Ia);
    const int wheel = addDisc(mech, "wheel", Vector3d(0.3, 0, 0), 1.5, Ib);
    const int gap = mech.addBacklashCoupling("mesh", {{a, 0, Za}, {wheel, 0, Zb}}, 0.0, b);
    mech.setGravity(Vector3d(0, 0, -kG));
    mech.setIntegrator(formulation(f));
    mech.build();
    mech.assemble({}, {{a, 0, w0}});
    ASSERT_STREQ(mech.formulation(), f);
    const double T0 = mech.kineticEnergy();
    for (int s = 0; s < 30; ++s) {
      mech.step(h);
      if (mech.time() < t_contact) {
        EXPECT_NEAR(mech.jointVelocity(wheel, 0), 0.0, 1e-14 * w0);
        EXPECT_NEAR(mech.jointVelocity(a, 0), w0, 1e-13 * w0);
      } else if (mech.time() > t_contact + h) {
        // (the joint formulation's impact projection keeps them to round-off, the absolute
        // formulation's, whose solves hold the joints in penalty form, to 1e-9)
        const double tol = std::string(f) == "joint" ? 1e-13 : 1e-8;
        EXPECT_NEAR(mech.jointVelocity(a, 0), w_a, tol * w0);
        EXPECT_NEAR(mech.jointVelocity(wheel, 0), w_b, tol * w0);
        EXPECT_NEAR(Za * mech.jointVelocity(a, 0) + Zb * mech.jointVelocity(wheel, 0), 0.0, 1e-12 * Za * w0);
        EXPECT_NEAR(Ia * mech.jointVelocity(a, 0) / Za - Ib * mech.jointVelocity(wheel, 0) / Zb, Ia * w0 / Za,
                    tol * Ia * w0 / Za);
      }
    }
    // the pair's rotational energy after the impact (the discs' centres stay put)
    const double T1 = 0.5 * (Ia * w_a * w_a + Ib * w_b * w_b);
    EXPECT_NEAR(mech.kineticEnergy(), T1, (std::string(f) == "joint" ? 1e-13 : 1e-8) * T0);
    std::printf("[backlash, free, %s] after the impact w_a %.15f (%.15f), w_b %.15f (%.15f); kinetic energy %.6f J "
                "of %.6f J before\n",
                f, mech.jointVelocity(a, 0), w_a, mech.jointVelocity(wheel, 0), w_b, mech.kineticEnergy(), T0);
  }
}

// addBacklashCoupling refuses a backlash that is not a positive finite clearance, naming it.
TEST(LinearCoupling, ABacklashMustBePositiveAndFinite) {
  for (double bad : {0.0, -0.1, std::nan("")}) {
    Mechanism mech;
    const int a = addDisc(mech, "a", Vector3d::Zero(), 1.0, 0.01);
    const int c = addDisc(mech, "c", Vector3d(1, 0, 0), 1.0, 0.01);
    try {
      mech.addBacklashCoupling("g", {{a, 0, 1.0}, {c, 0, 2.0}}, 0.0, bad);
      ADD_FAILURE() << "accepted backlash " << bad;
    } catch (const ModelError& e) {
      EXPECT_NE(std::string(e.what()).find("coupling 'g': its backlash"), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace mechanism_sim
