// Paths for drives (drive.h DrivePath) and drives added after build (mechanism.h): the
// quintic segments reproduce polynomials they can represent and are C2 at their knots; a
// free pendulum that becomes driven in mid-swing keeps its position, velocity and
// acceleration, then needs exactly the inverse dynamics of the path; a second path takes
// over without a jump; a removed drive leaves the pendulum free; a drive whose equation
// depends on the others is refused with the mechanism unchanged.
#include <gtest/gtest.h>

#include <cmath>

#include "mechanism_sim/core/models.h"

namespace mechanism_sim {
namespace {

constexpr double kG = 9.81;

double poly(const std::vector<double>& c, double t, int derivative) {
  double y = 0;
  for (size_t k = derivative; k < c.size(); ++k) {
    double f = 1;
    for (int d = 0; d < derivative; ++d) f *= static_cast<double>(k - d);
    y += c[k] * f * std::pow(t, static_cast<double>(k - derivative));
  }
  return y;
}

// C2: at every knot the segment after it starts at the knot's q, v, a and the segment
// before it (Taylor-extended over a small step) ends there. Past the last knot the path
// goes on with acceleration 0.
void expectC2(const DrivePath& p) {
  const std::vector<PathKnot>& k = p.knots();
  for (size_t i = 0; i < k.size(); ++i) {
    double q, v, a;
    p.eval(k[i].t, &q, &v, &a);
    EXPECT_NEAR(q, k[i].q, 1e-12) << i;
    EXPECT_NEAR(v, k[i].v, 1e-10) << i;
    EXPECT_NEAR(a, i + 1 < k.size() ? k[i].a : 0.0, 1e-9) << i;
    if (i == 0) continue;
    const double e = 1e-7;
    p.eval(k[i].t - e, &q, &v, &a);
    EXPECT_NEAR(q + v * e + 0.5 * a * e * e, k[i].q, 1e-12) << i;
    EXPECT_NEAR(v + a * e, k[i].v, 1e-9) << i;
    EXPECT_NEAR(a, k[i].a, 1e-4) << i;
  }
}

TEST(DrivePath, QuinticSegmentsReproduceAQuintic) {
  const std::vector<double> c = {0.3, -1.0, 0.5, 2.0, -1.5, 0.4};
  const std::vector<double> t = {0.3, 0.5, 1.1, 1.4, 2.0};
  std::vector<double> q, v, a;
  for (double x : t) q.push_back(poly(c, x, 0)), v.push_back(poly(c, x, 1)), a.push_back(poly(c, x, 2));
  const DrivePath p = DrivePath::through(PathKnot{0.0, poly(c, 0, 0), poly(c, 0, 1), poly(c, 0, 2)}, t, q, v, a);
  double worst = 0;
  for (double x = 0.0; x <= 2.0; x += 0.01) {
    double y, yd, ydd;
    p.eval(x, &y, &yd, &ydd);
    worst = std::max({worst, std::fabs(y - poly(c, x, 0)), std::fabs(yd - poly(c, x, 1)) / 10,
                      std::fabs(ydd - poly(c, x, 2)) / 100});
  }
  EXPECT_LT(worst, 1e-12);
  expectC2(p);
  // past the end: on at the last velocity, acceleration 0
  double y, yd, ydd;
  p.eval(3.0, &y, &yd, &ydd);
  EXPECT_NEAR(yd, v.back(), 1e-12);
  EXPECT_NEAR(y, q.back() + v.back(), 1e-12);
  EXPECT_EQ(ydd, 0.0);
}

// Positions only: a clamped cubic spline. Through a cubic whose slope at the start is the
// start's and whose acceleration there too, every segment but the last (which comes to
// rest with acceleration 0) is that cubic.
TEST(DrivePath, PositionsOnlyMakeAClampedSplineThatKeepsACubic) {
  const double T = 2.0;
  const std::vector<double> c = {0.2, 0.0, 1.5, -0.5};  // p'(2) = 6 - 6 = 0: at rest at the end
  const std::vector<double> t = {0.25, 0.7, 1.0, 1.6, T};
  std::vector<double> q;
  for (double x : t) q.push_back(poly(c, x, 0));
  const DrivePath p = DrivePath::through(PathKnot{0.0, c[0], 0.0, 2 * c[2]}, t, q);
  double worst = 0;
  for (double x = 0.0; x < 1.6; x += 0.01) {
    double y, yd, ydd;
    p.eval(x, &y, &yd, &ydd);
    worst = std::max({worst, std::fabs(y - poly(c, x, 0)), std::fabs(yd - poly(c, x, 1)), std::fabs(ydd - poly(c, x, 2))});
  }
  EXPECT_LT(worst, 1e-12);
  EXPECT_EQ(p.knots().back().v, 0.0);
  EXPECT_EQ(p.knots().back().a, 0.0);
  expectC2(p);
  // a single point: from the start to rest there
  const DrivePath one = DrivePath::through(PathKnot{1.0, 0.0, 0.5, -1.0}, {2.0}, {1.0});
  expectC2(one);
}

// Velocities without accelerations: from a cubic, the mean of the two Hermite
// accelerations is the cubic's, so the path is the cubic (but the last segment).
TEST(DrivePath, VelocitiesWithoutAccelerationsKeepACubic) {
  const std::vector<double> c = {-0.4, 0.8, -1.2, 0.9};
  const std::vector<double> t = {0.2, 0.5, 0.9, 1.5, 1.8};
  std::vector<double> q, v;
  for (double x : t) q.push_back(poly(c, x, 0)), v.push_back(poly(c, x, 1));
  const DrivePath p = DrivePath::through(PathKnot{0.0, c[0], c[1], 2 * c[2]}, t, q, v);
  for (double x = 0.0; x < 1.5; x += 0.01) {
    double y, yd, ydd;
    p.eval(x, &y, &yd, &ydd);
    ASSERT_NEAR(ydd, poly(c, x, 2), 1e-11) << x;
    ASSERT_NEAR(y, poly(c, x, 0), 1e-12) << x;
  }
  expectC2(p);
}

TEST(DrivePath, BadPointsAreRefused) {
  const PathKnot s{1.0, 0, 0, 0};
  EXPECT_THROW(DrivePath::through(s, {}, {}), UsageError);
  EXPECT_THROW(DrivePath::through(s, {1.0}, {0.0}), UsageError);  // not after the start
  EXPECT_THROW(DrivePath::through(s, {2.0, 2.0}, {0.0, 1.0}), UsageError);
  EXPECT_THROW(DrivePath::through(s, {2.0, 3.0}, {0.0, NAN}), UsageError);
  EXPECT_THROW(DrivePath::through(s, {2.0, 3.0}, {0.0, 1.0}, {1.0}), UsageError);
  EXPECT_THROW(DrivePath::through(s, {2.0}, {0.0}, {INFINITY}), UsageError);
}

// A mass m at distance L from a revolute about y (central inertia Ic), released from the
// horizontal: q = 0 horizontal, q > 0 below; (m L^2 + Ic) q'' = tau + m g L cos q.
struct Pendulum {
  double m = 2.0, L = 0.5, Ic = 0.01;
  Mechanism mech;
  Pendulum() {
    Body b;
    b.name = "bob";
    b.m = m;
    b.Jp = Ic * Matrix3d::Identity();
    b.r = Vector3d(L, 0, 0);
    const int body = mech.addBody(b);
    mech.addJoint(makeJoint("revolute", "pivot", Mechanism::kGround, models::axisY(Vector3d::Zero()), body,
                            models::axisY(Vector3d(-L, 0, 0))));
    mech.build();
    mech.assemble();
  }
  double inertia() const { return m * L * L + Ic; }
  double effort(double q, double q_ddot) const { return inertia() * q_ddot - m * kG * L * std::cos(q); }
};

TEST(DriveAfterBuild, FreePendulumFollowsAPathWithoutAJumpAndNeedsItsInverseDynamics) {
  Pendulum p;
  const double h = 1e-3;
  for (int k = 0; k < 300; ++k) p.mech.step(h);
  // free: the acceleration query is the equation of motion's
  const double q0 = p.mech.jointPosition(0, 0), v0 = p.mech.jointVelocity(0, 0), a0 = p.mech.jointAcceleration(0, 0);
  EXPECT_NEAR(a0, p.effort(q0, 0.0) / -p.inertia(), 1e-9);
  const long steps = p.mech.stepsTaken();
  const int d = p.mech.addDrive(0, 0, DriveProfile::velocity(0.0));
  EXPECT_EQ(d, 0);
  EXPECT_EQ(p.mech.numDrives(), 1);
  EXPECT_EQ(p.mech.stepsTaken(), steps);  // the State is kept
  const double t0 = p.mech.time();
  auto path = std::make_shared<const DrivePath>(
      DrivePath::through(PathKnot{t0, q0, v0, a0}, {t0 + 0.4, t0 + 0.9, t0 + 1.3}, {1.2, 0.4, 0.8}));
  p.mech.commandDrivePath(d, path);
  EXPECT_EQ(p.mech.jointPosition(0, 0), q0);
  EXPECT_NEAR(p.mech.jointVelocity(0, 0), v0, 1e-12);
  EXPECT_NEAR(p.mech.jointAcceleration(0, 0), a0, 1e-9);
  // at the switch the drive supplies nothing: the path goes on as the free swing would
  EXPECT_NEAR(p.mech.jointEffort(0, 0), 0.0, 1e-9);
  double worst_q = 0, worst_tau = 0;
  for (int k = 0; k < 800; ++k) {
    p.mech.step(h);
    double q, v, a;
    path->eval(p.mech.time(), &q, &v, &a);
    worst_q = std::max(worst_q, std::fabs(p.mech.jointPosition(0, 0) - q));
    worst_tau = std::max(worst_tau, std::fabs(p.mech.jointEffort(0, 0) - p.effort(q, a)));
  }
  // a second path from the drive's target now: no jump in q, q', q''
  double q1, v1, a1;
  p.mech.driveTarget(d, &q1, &v1, &a1);
  const double tau1 = p.mech.jointEffort(0, 0);
  const double t1 = p.mech.time();
  auto second = std::make_shared<const DrivePath>(
      DrivePath::through(PathKnot{t1, q1, v1, a1}, {t1 + 0.5, t1 + 1.0}, {-0.3, 0.2}, {0.5, 0.0}, {0.0, 0.0}));
  p.mech.commandDrivePath(d, second);
  EXPECT_NEAR(p.mech.jointPosition(0, 0), q1, 1e-12);
  EXPECT_NEAR(p.mech.jointVelocity(0, 0), v1, 1e-10);
  EXPECT_NEAR(p.mech.jointAcceleration(0, 0), a1, 1e-8);
  EXPECT_NEAR(p.mech.jointEffort(0, 0), tau1, 1e-8);
  for (int k = 0; k < 1500; ++k) {
    p.mech.step(h);
    double q, v, a;
    second->eval(p.mech.time(), &q, &v, &a);
    worst_q = std::max(worst_q, std::fabs(p.mech.jointPosition(0, 0) - q));
    worst_tau = std::max(worst_tau, std::fabs(p.mech.jointEffort(0, 0) - p.effort(q, a)));
  }
  const double scale = p.m * kG * p.L;
  std::printf("path drive after build: |q - path| %.2e rad, |tau - inverse dynamics| %.2e N m (of %.2f)\n", worst_q,
              worst_tau, scale);
  EXPECT_LT(worst_q, 1e-11);
  EXPECT_LT(worst_tau, 1e-8 * scale);
  // past its end the second path holds 0.2 rad: the static torque
  EXPECT_NEAR(p.mech.jointPosition(0, 0), 0.2, 1e-11);
  EXPECT_NEAR(p.mech.jointEffort(0, 0), p.effort(0.2, 0.0), 1e-8 * scale);

  // removed: free again, swinging from rest at 0.2 rad with energy kept
  p.mech.removeDrive(d);
  EXPECT_EQ(p.mech.numDrives(), 0);
  EXPECT_EQ(p.mech.jointEffort(0, 0), 0.0);
  const double E = p.mech.kineticEnergy() + p.mech.potentialEnergy();
  EXPECT_NEAR(p.mech.jointAcceleration(0, 0), p.effort(0.2, 0.0) / -p.inertia(), 1e-9);
  for (int k = 0; k < 500; ++k) p.mech.step(h);
  EXPECT_GT(p.mech.jointPosition(0, 0), 0.3);  // it fell
  EXPECT_NEAR(p.mech.kineticEnergy() + p.mech.potentialEnergy(), E, 1e-9 * scale);
}

// Double pendulum with q_2 = 2 q_1 (a coupler): driving q_1 drives q_2; a drive on q_2 as
// well depends on them and is refused, the mechanism unchanged.
TEST(DriveAfterBuild, ADependentDriveIsRefusedAndChangesNothing) {
  Mechanism m;
  models::pendulumChain(m, 2);
  m.addCoupler("twice", 1, 0, 0, 0, 2.0, 0.0);
  m.build();
  m.assemble();
  for (int k = 0; k < 100; ++k) m.step(1e-3);
  EXPECT_EQ(m.addDrive(0, 0, DriveProfile::velocity(0.0)), 0);
  const Eigen::VectorXd x = m.state().x;
  const int equations = m.numEquations();
  try {
    m.addDrive(1, 0, DriveProfile::velocity(0.0));
    ADD_FAILURE() << "a dependent drive was accepted";
  } catch (const ModelError& e) {
    EXPECT_NE(std::string(e.what()).find("follows from the other joints"), std::string::npos) << e.what();
  }
  EXPECT_EQ(m.numDrives(), 1);
  EXPECT_EQ(m.numEquations(), equations);
  EXPECT_EQ((m.state().x - x).cwiseAbs().maxCoeff(), 0.0);
  // the drive added holds the velocity it found: the coupled joint follows at twice it
  const double v = m.jointVelocity(0, 0);
  for (int k = 0; k < 200; ++k) m.step(1e-3);
  EXPECT_NEAR(m.jointVelocity(0, 0), v, 1e-12);
  EXPECT_NEAR(m.jointVelocity(1, 0), 2 * v, 1e-10);
  EXPECT_THROW(m.addDrive(0, 0, DriveProfile::velocity(0.0)), ModelError);        // already driven
  EXPECT_THROW(m.addDrive(1, 0, DriveProfile::harmonic(0, 1, 1, 0)), ModelError);  // a profile
  EXPECT_THROW(m.removeDrive(3), UsageError);
}

}  // namespace
}  // namespace mechanism_sim

namespace mechanism_sim {
namespace {

// A drum held at rest by a zero-velocity drive against a torque and a force on it, with no
// gravity: nothing in the model sets a velocity scale (the System's is 0), and the motion
// the drive forbids is round-off of zero. The steps hold it in both formulations, and the
// drive's effort balances the torque.
TEST(DriveAfterBuild, ADrumHeldAtRestWithoutGravityStepsUnderALoad) {
  for (const char* formulation : {"absolute", "joint"}) {
    SCOPED_TRACE(formulation);
    Mechanism m;
    IntegratorOptions o;
    o.formulation = formulation;
    m.setIntegrator(o);
    Body drum;
    drum.name = "drum";
    drum.m = 3.0;
    drum.Jp = Eigen::Vector3d(0.1, 0.1, 0.2).asDiagonal();
    const int b = m.addBody(drum);
    JointFrame f;
    m.addJoint(makeJoint("revolute", "axle", Mechanism::kGround, f, b, f));
    m.setGravity(Eigen::Vector3d::Zero());
    m.addDrive(0, 0, DriveProfile::velocity(0.0));
    m.build();
    m.assemble();
    m.setBodyWrench(b, Eigen::Vector3d(1.0, 0.0, 0.0), Eigen::Vector3d(0.0, 0.0, 4.0));
    for (int s = 0; s < 100; ++s) ASSERT_NO_THROW(m.step(1e-3)) << "step " << s;
    EXPECT_EQ(m.jointVelocity(0, 0), 0.0);
    EXPECT_NEAR(std::fabs(m.jointEffort(0, 0)), 4.0, 1e-12);
  }
}

}  // namespace
}  // namespace mechanism_sim
