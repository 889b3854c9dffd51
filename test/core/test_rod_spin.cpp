// A rod between two ball joints in a loop (the shape of a leg's ankle linkage: a crank and
// a rocker on parallel axes, the rod out of their plane) spins freely about its own axis
// with a moment of inertia 8000 times smaller than its others. The ball joints' forces act
// on that axis and gravity at the rod's centre of mass on it, so nothing turns the rod
// about it: an axisymmetric rod keeps its spin rate (Euler: I3 w3' = (I1 - I2) w1 w2 = 0)
// while the loop swings under gravity, and the energy stays. A constraint force with a
// component about the axis, a wrong gyroscopic term or a stepper that cannot follow the
// tiny moment would change the spin rate or the energy.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "bodies.h"
#include "core/absolute/evaluation.h"
#include "mechanism_sim/core/mechanism.h"
#include "mechanism_sim/core/models.h"

namespace mechanism_sim {
namespace {

using test_util::frame;

struct RodLoop {
  int crank = 0, rocker = 0, rod = 0;
  double I3 = 1e-7, spin = 40.0;  // the rod's moment about its axis, and its spin rate (rad/s)
};

// Crank about z at the origin (its ball at A), rocker about z at (0.4, 0, 0) (its ball at
// B), the rod from A to B with its z axis along AB; gravity along -y, in the plane the
// crank and rocker turn in.
RodLoop build(Mechanism& m, const char* formulation) {
  RodLoop r;
  const Vector3d A(0.1, 0.0, -0.05), B(0.4, 0.3, 0.05);
  const Vector3d d = B - A;
  const double L = d.norm();
  const Matrix3d R = Eigen::Quaterniond::FromTwoVectors(Vector3d::UnitZ(), d).toRotationMatrix();
  r.crank = m.addBody(test_util::body("crank", 0.3, Vector3d(2e-4, 4e-4, 4e-4), Vector3d(0.05, 0.0, 0.0)));
  r.rocker = m.addBody(test_util::body("rocker", 0.6, Vector3d(5e-3, 2e-4, 5e-3), Vector3d(0.4, 0.15, 0.0)));
  Body rod = test_util::body("rod", 0.05, Vector3d(0.05 * L * L / 12, 0.05 * L * L / 12, r.I3), 0.5 * (A + B));
  rod.p = Eigen::Quaterniond(R);
  rod.w = Vector3d(0.0, 0.0, r.spin);  // body components: about the rod's own axis
  r.rod = m.addBody(rod);
  m.addJoint(makeJoint("revolute", "crank_pivot", Mechanism::kGround, frame(Vector3d::Zero()), r.crank,
                       frame(Vector3d(-0.05, 0.0, 0.0))));
  m.addJoint(makeJoint("revolute", "rocker_pivot", Mechanism::kGround, frame(Vector3d(0.4, 0.0, 0.0)), r.rocker,
                       frame(Vector3d(0.0, -0.15, 0.0))));
  m.addJoint(makeJoint("spherical", "ball_a", r.crank, frame(A - Vector3d(0.05, 0.0, 0.0)), r.rod,
                       frame(Vector3d(0.0, 0.0, -0.5 * L))));
  m.addJoint(makeJoint("spherical", "ball_b", r.rocker, frame(B - Vector3d(0.4, 0.15, 0.0)), r.rod,
                       frame(Vector3d(0.0, 0.0, 0.5 * L))));
  m.setGravity(Vector3d(0.0, -9.81, 0.0));
  IntegratorOptions io;
  io.formulation = formulation;
  m.setIntegrator(io);
  m.build();
  m.assemble();
  return r;
}

double spinRate(const Mechanism& m, int b) { return m.state().u[BodyCoordinates::u(b - 1) + 5]; }

TEST(RodSpin, ARodBetweenTwoBallJointsKeepsItsSpinRateAndTheLoopItsEnergy) {
  for (const char* f : {"absolute", "joint"}) {
    Mechanism m;
    const RodLoop r = build(m, f);
    EXPECT_STREQ(m.formulation(), f);
    const double w0 = spinRate(m, r.rod);
    EXPECT_NEAR(w0, r.spin, 1e-9 * r.spin) << f;  // the spin alone meets the joints: assembly keeps it
    const double E0 = m.kineticEnergy() + m.potentialEnergy();
    const double crank0 = m.jointPosition(0, 0);
    double worst_spin = 0, worst_energy = 0, swing = 0;
    for (int k = 0; k < 2000; ++k) {
      m.step(1e-3);
      worst_spin = std::max(worst_spin, std::fabs(spinRate(m, r.rod) - w0));
      worst_energy = std::max(worst_energy, std::fabs(m.kineticEnergy() + m.potentialEnergy() - E0));
      swing = std::max(swing, std::fabs(m.jointPosition(0, 0) - crank0));
    }
    std::printf("%s: spin rate off by %.2e rad/s, energy by %.2e J in 2 s; the crank swung %.2f rad\n", f, worst_spin,
                worst_energy, swing);
    EXPECT_GT(swing, 0.5) << f;  // the loop moves
    EXPECT_LT(worst_spin, 1e-6 * r.spin) << f;
    // the spin's own energy is 8e-5 J of the loop's 0.1 J or so
    EXPECT_LT(worst_energy, 1e-7 * 0.6 * 9.81 * 0.3) << f;
    EXPECT_LT(m.relativePositionViolation(), 1e-9) << f;
  }
}

}  // namespace
}  // namespace mechanism_sim
