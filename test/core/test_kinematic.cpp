// Kinematic mechanisms (kinematic.h, independentCoordinates): which joint coordinates the
// equations leave free. Oracles: the degrees of freedom counted by hand (a four-bar has one,
// whichever joint is asked first; an open chain one per joint; a coupler or a drive takes one
// away; a spherical joint's rates are not positions), the same in millimetres as in metres;
// and the massless four-bar driven on the coordinate found free against Freudenstein's
// closure equation (the geometry and branch of test/urdf/test_kinematic.cpp's FourBar, which
// checks the loader's path with rates and accelerations; here the core's own, positions).
#include <gtest/gtest.h>

#include <cmath>
#include <utility>
#include <vector>

#include "bodies.h"
#include "mechanism_sim/core/kinematic.h"
#include "mechanism_sim/core/mechanism.h"
#include "mechanism_sim/core/models.h"

namespace mechanism_sim {
namespace {

using Candidates = std::vector<std::pair<int, int>>;

Body massless(const std::string& name, const Vector3d& r) { return body(name, 0.0, Matrix3d::Zero(), r); }

// The four-bar of test/urdf/test_kinematic.cpp in the x-z plane, angles about y, every
// length times `scale`: ground pivots (0, 0) and (a, 0), crank b, coupler c, rocker d
// (a = 0.4, b = 0.1, c = sqrt(0.2), d = 0.3), crank and rocker upright at the start. Joints:
// 0 crank, 1 coupler (crank-coupler), 2 rocker (coupler-rocker), 3 the rocker's ground pivot.
void fourBar(Mechanism& m, double scale = 1.0) {
  const double s = scale;
  const Vector3d P(0, 0, 0.1 * s), Q(0.4 * s, 0, 0.3 * s), O2(0.4 * s, 0, 0);
  const Vector3d r_crank(0, 0, 0.05 * s), r_coupler = 0.5 * (P + Q), r_rocker(0.4 * s, 0, 0.15 * s);
  const int crank = m.addBody(massless("crank", r_crank));
  const int coupler = m.addBody(massless("coupler", r_coupler));
  const int rocker = m.addBody(massless("rocker", r_rocker));
  m.addJoint(makeJoint("revolute", "crank_joint", Mechanism::kGround, models::axisY(Vector3d::Zero()), crank,
                       models::axisY(-r_crank)));
  m.addJoint(makeJoint("revolute", "coupler_joint", crank, models::axisY(P - r_crank), coupler,
                       models::axisY(P - r_coupler)));
  m.addJoint(makeJoint("revolute", "rocker_joint", coupler, models::axisY(Q - r_coupler), rocker,
                       models::axisY(Q - r_rocker)));
  m.addJoint(makeJoint("revolute", "loop", Mechanism::kGround, models::axisY(O2), rocker, models::axisY(O2 - r_rocker)));
}

// Crank tip P = b (sin t, cos t), rocker tip Q = (a, 0) + d (sin f, cos f); |Q - P| = c reads
// A(t) sin f + B(t) cos f = C(t), whose branch through (0, 0) is f = asin(C / R) - atan2(B, A).
double freudenstein(double t) {
  const double a = 0.4, b = 0.1, c = std::sqrt(0.2), d = 0.3;
  const double A = 2 * d * (a - b * std::sin(t)), B = -2 * b * d * std::cos(t),
               C = c * c - a * a - b * b - d * d + 2 * a * b * std::sin(t);
  return std::asin(C / std::hypot(A, B)) - std::atan2(B, A);
}

std::vector<char> freeCoordinates(const Mechanism& m, const Candidates& c) { return independentCoordinates(m.system(), c); }

// One degree of freedom: whichever of its joints is asked first is free, the rest follow.
TEST(IndependentCoordinates, AFourBarLeavesOneCoordinateFreeWhicheverIsAskedFirst) {
  for (double scale : {1.0, 1000.0}) {
    SCOPED_TRACE(scale);
    Mechanism m;
    fourBar(m, scale);
    EXPECT_EQ(freeCoordinates(m, {{0, 0}, {1, 0}, {2, 0}}), (std::vector<char>{1, 0, 0}));
    EXPECT_EQ(freeCoordinates(m, {{2, 0}, {1, 0}, {0, 0}}), (std::vector<char>{1, 0, 0}));
    EXPECT_EQ(freeCoordinates(m, {{1, 0}, {3, 0}, {0, 0}, {2, 0}}), (std::vector<char>{1, 0, 0, 0}));
  }
}

// An open chain of three massless revolutes: one free coordinate per joint. A coupler ties
// the third to the second; a drive prescribes the first: each takes its coordinate away.
TEST(IndependentCoordinates, CouplersAndDrivesTakeCoordinatesAway) {
  auto chain = [](Mechanism& m) {
    int prev = Mechanism::kGround;
    Vector3d prev_r = Vector3d::Zero();
    for (int k = 1; k <= 3; ++k) {
      const Vector3d r(0.3 * k, 0, 0), pivot(0.3 * k - 0.15, 0, 0);
      const int b = m.addBody(massless("link" + std::to_string(k), r));
      m.addJoint(makeJoint("revolute", "j" + std::to_string(k - 1), prev, models::axisY(pivot - prev_r), b,
                           models::axisY(pivot - r)));
      prev = b, prev_r = r;
    }
  };
  const Candidates all = {{0, 0}, {1, 0}, {2, 0}};
  Mechanism open;
  chain(open);
  EXPECT_EQ(freeCoordinates(open, all), (std::vector<char>{1, 1, 1}));
  Mechanism coupled;
  chain(coupled);
  coupled.addCoupler("mimic", 2, 0, 1, 0, 2.0, 0.0);
  EXPECT_EQ(freeCoordinates(coupled, all), (std::vector<char>{1, 1, 0}));
  coupled.addDrive(0, 0, DriveProfile::velocity(1.0));
  EXPECT_EQ(freeCoordinates(coupled, all), (std::vector<char>{0, 1, 0}));
}

// A spherical joint's coordinates are rates, never positions to prescribe; a candidate
// that names no coordinate, or one asked twice, is not taken.
TEST(IndependentCoordinates, RatesBadCandidatesAndRepeatsAreNotTaken) {
  Mechanism m;
  const int a = m.addBody(massless("a", Vector3d(0.3, 0, 0)));
  const int b = m.addBody(massless("b", Vector3d(0.6, 0, 0)));
  m.addJoint(makeJoint("spherical", "ball", Mechanism::kGround, models::axisY(Vector3d::Zero()), a,
                       models::axisY(Vector3d(-0.3, 0, 0))));
  m.addJoint(makeJoint("prismatic", "slide", a, models::axisY(Vector3d(0.15, 0, 0)), b,
                       models::axisY(Vector3d(-0.15, 0, 0))));
  EXPECT_EQ(freeCoordinates(m, {{0, 0}, {0, 1}, {0, 2}, {1, 0}, {1, 0}, {1, 1}, {5, 0}, {-1, 0}}),
            (std::vector<char>{0, 0, 0, 1, 0, 0, 0, 0}));
}

// The massless four-bar driven on the coordinate found free: the loop and the drive
// prescribe every motion, the masses drop out, and the rocker's angle (its ground pivot's
// coordinate) is Freudenstein's f(t) for the crank at t, over more than a turn of the crank.
// The projections hold the equations to 1e-13 relative: the angle to about that.
TEST(IndependentCoordinates, AFourBarDrivenOnItsFreeCoordinateFollowsFreudenstein) {
  Mechanism m;
  fourBar(m);
  const std::vector<char> take = freeCoordinates(m, {{0, 0}, {1, 0}, {2, 0}});
  ASSERT_EQ(take, (std::vector<char>{1, 0, 0}));
  const double w = 3.0;
  m.addDrive(0, 0, DriveProfile::velocity(w));
  IntegratorOptions io;
  io.formulation = "absolute";
  m.setIntegrator(io);
  m.build();
  m.assemble();
  double worst = 0, worst_sum = 0;
  for (int i = 1; i <= 2200; ++i) {  // 2.2 s: 6.6 rad of crank
    m.step(1e-3);
    if (i % 20) continue;
    const double t = m.jointPosition(0, 0);
    ASSERT_NEAR(t, w * m.time(), 1e-12 * w * m.time());
    const double f = freudenstein(t);
    worst = std::max(worst, std::fabs(std::remainder(m.jointPosition(3, 0) - f, 2 * M_PI)));
    // the rocker's angle is also the sum of the tree's three
    const double sum = m.jointPosition(0, 0) + m.jointPosition(1, 0) + m.jointPosition(2, 0);
    worst_sum = std::max(worst_sum, std::fabs(std::remainder(sum - f, 2 * M_PI)));
  }
  EXPECT_GT(m.jointPosition(0, 0), 2 * M_PI);
  EXPECT_LT(worst, 1e-9);
  EXPECT_LT(worst_sum, 1e-9);
}

}  // namespace
}  // namespace mechanism_sim
