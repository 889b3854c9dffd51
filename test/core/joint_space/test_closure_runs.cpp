// Runs in joint coordinates that left their closures (issue 35: robots of
// example-parallel-robots), each as a small model with a known answer:
//  - a limit on a revolute joint carried by a spherical joint is a row on the revolute's own
//    position (q has 4 coordinates for the sphere's 3 rates): the limit is not reached where
//    the joint starts inside it, and the run is the absolute formulation's;
//  - a four-bar whose coupler is a little shorter than its ground link passes near the flat
//    pose without the branches crossing there (a near change point): the closure's smallest
//    normalized singular value dips into the passage band and back, while the motion turns
//    from the parallelogram's branch onto the anti-parallelogram's. The equations carry the
//    turn: the loop stays closed, the energy is kept, and the motion is the absolute
//    formulation's;
//  (the exact parallelogram, whose branches do cross, is held through its crossing as
//  before: test_dynamics, test_joint_formulation.)
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

#include "mechanism_sim/core/mechanism.h"
#include "mechanism_sim/core/models.h"

namespace mechanism_sim {
namespace {

IntegratorOptions formulation(const char* f) {
  IntegratorOptions io;
  io.formulation = f;
  io.method = "rk4";
  return io;
}

// A rod from a to b in the x-z plane, body x along it.
int addRod(Mechanism& m, const std::string& name, const Vector3d& a, const Vector3d& b, double mass) {
  Body body;
  body.name = name;
  body.m = mass;
  const double L = (b - a).norm();
  body.Jp = models::rodInertia(mass, L);
  body.r = 0.5 * (a + b);
  const Vector3d e = (b - a) / L;
  body.p = Quaterniond(Eigen::AngleAxisd(-std::atan2(e.z(), e.x()), Vector3d::UnitY()));
  return m.addBody(body);
}

// A joint frame at global point P of body b (ground: -1), axis along global y.
JointFrame frameAt(const Mechanism& m, int b, const Vector3d& P) {
  if (b == Mechanism::kGround) return models::axisY(P);
  const Body& B = m.body(b);
  const Matrix3d A = B.p.toRotationMatrix();
  JointFrame f = models::axisY(A.transpose() * (P - B.r));
  f.Rp = A.transpose() * f.Rp;
  return f;
}

void pin(Mechanism& m, const std::string& name, int i, int j, const Vector3d& P) {
  m.addJoint(makeJoint("revolute", name, i, frameAt(m, i, P), j, frameAt(m, j, P)));
}

// The four-bar: cranks of length r pivoted on ground at x = 0 and x = d, a coupler of length
// d - delta between their tips (delta = 0: the parallelogram, flat at crank angle 0), built
// at crank angle theta on the parallelogram's side. No gravity.
void nearChangePoint(Mechanism& m, double r, double d, double delta, double theta) {
  m.setGravity(Vector3d::Zero());
  const double l = d - delta;
  const Vector3d O(0, 0, 0), D(d, 0, 0);
  const Vector3d A = O + r * Vector3d(std::cos(theta), 0, std::sin(theta));
  // C: |C - D| = r, |C - A| = l, the intersection nearer A + (d, 0, 0)
  const Vector3d AD = D - A;
  const double e = AD.norm(), x = (l * l - r * r + e * e) / (2 * e), y = std::sqrt(std::max(0.0, l * l - x * x));
  const Vector3d u = AD / e, n = Vector3d::UnitY().cross(u);
  const Vector3d C1 = A + x * u + y * n, C2 = A + x * u - y * n, P = A + D - O;
  const Vector3d C = (C1 - P).norm() < (C2 - P).norm() ? C1 : C2;
  const int crank0 = addRod(m, "crank0", O, A, 1.0), coupler = addRod(m, "coupler", A, C, 1.0),
            crank1 = addRod(m, "crank1", D, C, 1.0);
  pin(m, "pivot0", Mechanism::kGround, crank0, O);
  pin(m, "pin_a", crank0, coupler, A);
  pin(m, "pivot1", Mechanism::kGround, crank1, D);
  pin(m, "pin_b", coupler, crank1, C);
}

struct TwoRuns {
  double violation = 0;   // largest relative position violation after a step
  double energy = 0;      // largest |E - E0| / E0
  double difference = 0;  // largest joint position difference to the absolute run, rad
  double final_angle = 0;
  std::string error;
};

// Both formulations from the same assembled state (crank 0 at rate w), n steps of h.
template <class Build>
TwoRuns runBoth(const Build& build, double w, double h, int n) {
  Mechanism a, j;
  for (auto [mech, f] : {std::make_pair(&a, "absolute"), std::make_pair(&j, "joint")}) {
    build(*mech);
    mech->setIntegrator(formulation(f));
    mech->build();
    mech->assemble({}, {CoordinateTarget{0, 0, w}});
  }
  EXPECT_STREQ(j.formulation(), "joint");
  TwoRuns run;
  const double E0 = j.kineticEnergy() + j.potentialEnergy();
  try {
    for (int k = 0; k < n; ++k) {
      j.step(h);
      a.step(h);
      run.violation = std::max(run.violation, j.relativePositionViolation());
      run.energy = std::max(run.energy, std::fabs(j.kineticEnergy() + j.potentialEnergy() - E0) / E0);
      for (int q = 0; q < j.numJoints(); ++q)
        run.difference = std::max(run.difference, std::fabs(j.jointPosition(q, 0) - a.jointPosition(q, 0)));
    }
  } catch (const Error& e) {
    run.error = e.what();
  }
  run.final_angle = j.jointPosition(0, 0);
  return run;
}

// A pendulum hung by a spherical joint whose two frames start turned 2 rad apart about the
// vertical (its quaternion's z is sin 1 = 0.84), carrying a rod on a revolute joint limited
// to +-0.4 rad that starts at 0 and swings under gravity onto its upper stop. The limit is
// the revolute's: it is not active at the start (the rod at 0 after the first step, as in
// absolute coordinates), the stop is reached later, and the run agrees with the absolute
// formulation's.
TEST(ClosureRuns, ALimitPastASphericalJointReadsItsOwnCoordinate) {
  auto build = [](Mechanism& m) {
    Body b1 = Body();
    b1.name = "upper";
    b1.m = 1.0;
    b1.Jp = models::rodInertia(1.0, 0.5);
    b1.r = Vector3d(0, 0, -0.25);
    b1.p = Quaterniond(Eigen::AngleAxisd(M_PI / 2, Vector3d::UnitY()));  // (body x down)
    const int upper = m.addBody(b1);
    Body b2 = b1;
    b2.name = "lower";
    b2.r = Vector3d(0.25, 0, -0.5);
    b2.p = Quaterniond::Identity();  // (body x along global x: horizontal)
    const int lower = m.addBody(b2);
    JointFrame fi = models::axisY(Vector3d::Zero());
    fi.Rp = Eigen::AngleAxisd(-2.0, Vector3d::UnitZ()).toRotationMatrix();
    m.addJoint(makeJoint("spherical", "shoulder", Mechanism::kGround, fi, upper, frameAt(m, upper, Vector3d::Zero())));
    pin(m, "elbow", upper, lower, Vector3d(0, 0, -0.5));
    m.setJointLimits(1, 0, -0.4, 0.4);
  };
  Mechanism a, j;
  for (auto [mech, f] : {std::make_pair(&a, "absolute"), std::make_pair(&j, "joint")}) {
    build(*mech);
    mech->setIntegrator(formulation(f));
    mech->build();
    mech->assemble();
  }
  ASSERT_STREQ(j.formulation(), "joint");
  a.step(1e-3), j.step(1e-3);
  EXPECT_NEAR(j.jointPosition(1, 0), a.jointPosition(1, 0), 1e-9) << "the elbow after the first step";
  EXPECT_LT(std::fabs(j.jointPosition(1, 0)), 1e-3) << "the elbow starts at rest at 0, inside its limits";
  double worst = 0, top = 0;
  for (int k = 1; k < 1000; ++k) {
    a.step(1e-3), j.step(1e-3);
    worst = std::max(worst, std::fabs(j.jointPosition(1, 0) - a.jointPosition(1, 0)));
    top = std::max(top, std::fabs(j.jointPosition(1, 0)));
  }
  std::printf("[limit past a spherical joint] elbow reaches %.4f rad; joint against absolute: %.2e rad\n", top, worst);
  EXPECT_GT(top, 0.4 - 1e-6) << "the stop is reached";
  EXPECT_LT(top, 0.4 + 1e-9) << "and held";
  EXPECT_LT(worst, 1e-6);
}

// The near change point: a crank-to-crank four-bar (cranks 0.4 m, 1 m apart) whose coupler
// is delta shorter than the ground link. Spun from 0.3 rad towards flat at 1 rad/s without
// gravity, it passes within reach of the flat pose, where its closure's smallest
// normalized singular value dips below the passage band (1e-2) and comes back without a
// crossing: the motion turns there from the parallelogram's branch onto the
// anti-parallelogram's. Held at its acceleration across the branch, the turn was not made
// and the loop opened. The known answers: the loop stays closed to the projections'
// tolerance, the kinetic energy (no gravity, no loads) is kept, and the joint angles are
// the absolute formulation's.
TEST(ClosureRuns, ANearChangePointFourBarTurnsOntoTheOtherBranch) {
  // (the energy bound: RK4's error at 1 ms across the turn, which is sharper the smaller
  // delta; the absolute formulation makes the same error, as the third bound says)
  for (auto [delta, energy] : {std::make_pair(1e-5, 3e-3), std::make_pair(1e-4, 3e-5)}) {
    const TwoRuns run = runBoth([&](Mechanism& m) { nearChangePoint(m, 0.4, 1.0, delta, 0.3); }, 1.0, 1e-3, 2000);
    std::printf("[near change point, delta %.0e] 2 s: %s relative violation %.2e, energy %.2e, "
                "joint against absolute %.2e rad, crank at %.4f rad\n",
                delta, run.error.empty() ? "ran," : run.error.c_str(), run.violation, run.energy, run.difference,
                run.final_angle);
    EXPECT_TRUE(run.error.empty()) << run.error;
    EXPECT_LT(run.violation, 1e-12);
    EXPECT_LT(run.energy, energy);
    EXPECT_LT(run.difference, 1e-6);
  }
}

}  // namespace
}  // namespace mechanism_sim
