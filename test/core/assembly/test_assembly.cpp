// Assembly from any pose (assembly/assembly.cpp, through Mechanism::assemble): loops whose two cut frames start far apart, as
// files from the wild have them. A planar four-bar 0.6 m and 3 rad apart closes on the
// branch nearest its start, against the closed-form positions of both branches, and on the
// other branch when targets name it; four-bars from 107 starts half a metre apart all
// close; a spatial RSSR loop closes from 1.4 m apart (the crank's and the rocker's ends the
// coupler's length apart); a spherical four-bar whose cut axes start 1.44 rad apart closes,
// and ones whose axes start nearly or exactly opposed (which closed mirrored) close
// unmirrored, as does a hinge whose frames start 170 degrees apart; a four-bar whose links
// cannot reach across its ground is refused naming the joint that closes the loop, with
// its gap as the least-squares minimum gives it (the links stretched in a line);
// parallelograms taken past their flat pose by a target stay parallelograms.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "assembly/four_bar_parts.h"
#include "bodies.h"
#include "mechanism_sim/core/model/errors.h"
#include "mechanism_sim/core/mechanism.h"
#include "mechanism_sim/core/models.h"

namespace mechanism_sim {
namespace {

using namespace test_util::assembly;

TEST(Assembly, FourBarSixTenthsOfAMetreAndThreeRadiansApartClosesOnTheNearestBranch) {
  Mechanism m;
  Parts p{m};
  FourBar fb;
  fb.build(p);
  ASSERT_NEAR((fb.C1 - fb.C2).norm(), 0.6, 0.05);  // the file's gap
  const AssemblyReport rep = m.assemble();
  EXPECT_LT(rep.position_residual, 1e-12);
  EXPECT_LT(m.positionViolation(), 1e-12);
  const Vector3d B = p.now(fb.crank, fb.B0), C = p.now(fb.coupler, fb.C1), C_rocker = p.now(fb.rocker, fb.C2);
  Vector3d up, down;
  fb.branches(B, up, down);
  ASSERT_GT((up - down).norm(), 0.3);  // two distinct branches
  // The start's open ends lie on the upper side of B-D: the upper branch.
  EXPECT_GT(side(fb.B0, fb.D, 0.5 * (fb.C1 + fb.C2)), 0);
  EXPECT_LT((C - up).norm(), 1e-10) << "C " << C.transpose() << " up " << up.transpose() << " down "
                                     << down.transpose();
  EXPECT_LT((C_rocker - up).norm(), 1e-10);
  EXPECT_NEAR((B - fb.O).norm(), fb.a, 1e-12);
  // The crank moved less than a turn's quarter: the nearest closed pose, not a far one.
  EXPECT_LT(std::fabs(m.jointPosition(fb.crank_joint, 0)), kPi / 2);
}

// Four-bars started from a grid of crank, coupler and rocker angles whose open ends lie
// 0.5 to 0.7 m apart (the closing frames turned 3 rad as well), 107 starts: every one
// closes (the absolute iteration alone refused 15 of them, as not closing or mirrored).
TEST(Assembly, FourBarsFromAGridOfStartsHalfAMetreApartAllClose) {
  int starts = 0, closed = 0;
  for (double th = 0.2; th < 6.2; th += 0.6)
    for (double be = 0.0; be < 6.2; be += 0.6)
      for (double ga = 0.0; ga < 6.2; ga += 0.6) {
        FourBar fb;
        fb.theta0 = th, fb.beta0 = be, fb.gamma0 = ga;
        const Vector3d B0 = fb.a * inPlane(th), C1 = B0 + fb.b * inPlane(be), C2 = Vector3d(fb.d, 0, 0) + fb.c * inPlane(ga);
        if ((C1 - C2).norm() < 0.5 || (C1 - C2).norm() > 0.7) continue;
        ++starts;
        Mechanism m;
        Parts p{m};
        fb.build(p);
        try {
          m.assemble();
        } catch (const ModelError& e) {
          ADD_FAILURE() << "theta0 " << th << " beta0 " << be << " gamma0 " << ga << ": " << e.what();
          continue;
        }
        const Vector3d C = p.now(fb.coupler, fb.C1);
        EXPECT_LT(m.positionViolation(), 1e-12);
        EXPECT_NEAR((C - fb.D).norm(), fb.c, 1e-12);  // the loop's equation, off the coupler's end
        closed += m.positionViolation() < 1e-12;
      }
  std::printf("four-bars from %d starts 0.5-0.7 m apart: %d closed\n", starts, closed);
  EXPECT_EQ(starts, 107);
}

TEST(Assembly, TargetsChooseTheOtherBranch) {
  Mechanism m;
  Parts p{m};
  FourBar fb;
  fb.build(p);
  // The crank held 0.2 rad from its file pose, and the rocker where the lower branch puts it.
  const double q_crank = 0.2;
  const Vector3d B = fb.O + Eigen::AngleAxisd(q_crank, Vector3d::UnitY()) * (fb.B0 - fb.O);
  Vector3d up, down;
  fb.branches(B, up, down);
  const Vector3d u0 = (fb.C2 - fb.D).normalized(), u1 = (down - fb.D).normalized();
  const double q_rocker = std::atan2(u0.cross(u1).y(), u0.dot(u1));  // about +y
  m.assemble({{fb.crank_joint, 0, q_crank}, {fb.rocker_joint, 0, q_rocker}});
  EXPECT_LT(m.positionViolation(), 1e-12);
  EXPECT_LT((p.now(fb.crank, fb.B0) - B).norm(), 1e-10);
  EXPECT_LT((p.now(fb.coupler, fb.C1) - down).norm(), 1e-10);
  EXPECT_LT((p.now(fb.rocker, fb.C2) - down).norm(), 1e-10);
  EXPECT_NEAR(m.jointPosition(fb.crank_joint, 0), q_crank, 1e-12);
  EXPECT_NEAR(m.jointPosition(fb.rocker_joint, 0), q_rocker, 1e-12);
}

// The nearest closed pose puts the rocker past a limit the file gives it: the assembly
// keeps the rocker within its limits (the iterates are clamped to them) and closes the
// loop at the bound's side (the crank moves instead): within the limits, and nearer the
// bound than the free closing is to it.
TEST(Assembly, AClosingThatWouldLeaveALimitEndsAtTheBound) {
  const double q_free = FourBar().freeRockerAngle();
  Mechanism m;
  Parts p{m};
  FourBar fb;
  fb.build(p);
  const double bound = q_free > 0 ? q_free - 0.05 : q_free + 0.05;
  m.setJointLimits(fb.rocker_joint, 0, q_free > 0 ? -kPi : bound, q_free > 0 ? bound : kPi);
  m.assemble();
  EXPECT_LT(m.positionViolation(), 1e-12);
  const double q = m.jointPosition(fb.rocker_joint, 0);
  EXPECT_TRUE(q_free > 0 ? q <= bound : q >= bound) << q << " past the bound " << bound;
  EXPECT_NEAR(q, bound, 1e-3);
}

TEST(Assembly, FourBarThatCannotReachAcrossItsGroundIsRefusedNamingTheLoop) {
  Mechanism m;
  Parts p{m};
  FourBar fb;
  fb.d = 3.0;  // a + b + c = 2.3 < d: no pose closes it
  fb.build(p);
  try {
    m.assemble();
    FAIL() << "assembled a four-bar that cannot close";
  } catch (const ModelError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("does not close"), std::string::npos) << what;
    EXPECT_NE(what.find("'closure'"), std::string::npos) << what;
    // The least-squares pose: the links stretched along the ground, the gap d - (a + b + c).
    const size_t at = what.find("largest residual ");
    ASSERT_NE(at, std::string::npos) << what;
    EXPECT_NEAR(std::strtod(what.c_str() + at + 17, nullptr), 0.7, 1e-6) << what;
  }
}

// RSSR: crank about z at O, coupler by spheres at B and C, rocker about x at D; closed
// with the coupler from B0 to C and the rocker from D to C. At the file's pose the coupler
// points elsewhere and the rocker is turned away: its two ends 1.4 m apart.
TEST(Assembly, SpatialRSSRClosesFromOneMetreApart) {
  Mechanism m;
  Parts p{m};
  const Vector3d O(0, 0, 0), B0(0.3, 0.1, 0), C(0.9, 0.4, 0.5), D(1.0, 0.2, 0.1);
  const double coupler_length = (C - B0).norm(), rocker_length = (C - D).norm();
  const Vector3d C1 = B0 + coupler_length * Vector3d(-0.2, 0.5, 0.8).normalized();
  const Vector3d C2 = D + rocker_length * Vector3d(0, -0.6, -0.8);
  ASSERT_GT((C1 - C2).norm(), 1.0);
  const int crank = p.add("crank", 0.8, 0.5 * (O + B0));
  const int coupler = p.add("coupler", 1.2, 0.5 * (B0 + C1));
  const int rocker = p.add("rocker", 1.0, 0.5 * (C2 + D));
  const Matrix3d I = Matrix3d::Identity();
  p.join("revolute", "crank_joint", 0, O, axisTo(Vector3d::UnitZ()), crank, O, axisTo(Vector3d::UnitZ()));
  p.join("spherical", "ball_b", crank, B0, I, coupler, B0, I);
  p.join("revolute", "rocker_joint", 0, D, axisTo(Vector3d::UnitX()), rocker, D, axisTo(Vector3d::UnitX()));
  p.join("spherical", "ball_c", coupler, C1, I, rocker, C2, I);
  m.assemble();
  EXPECT_LT(m.positionViolation(), 1e-12);
  // The loop's own equation, read off the crank and the rocker alone: |B - C| is the
  // coupler's length.
  const Vector3d Bn = p.now(crank, B0), Cn = p.now(rocker, C2);
  EXPECT_NEAR((Bn - Cn).norm(), coupler_length, 1e-12);
  EXPECT_NEAR(Bn.z(), 0.0, 1e-12);        // the crank turns about z at O
  EXPECT_NEAR(Bn.norm(), B0.norm(), 1e-12);
  EXPECT_NEAR((Cn - D).x(), 0.0, 1e-12);  // the rocker about x at D
  EXPECT_NEAR((Cn - D).norm(), rocker_length, 1e-12);
  EXPECT_LT((p.now(coupler, C1) - Cn).norm(), 1e-12);
}

// A spherical four-bar: four revolute axes through the origin, ground-crank a1,
// crank-coupler a2, ground-rocker a4 and the closing coupler-rocker a3. At the file's pose
// the rocker is turned by `open` about a4, so its a3 axis starts that far (in angle) from
// the coupler's.
struct SphericalFourBar {
  // (a3 nearly square to a4, so that turning the rocker swings it through large angles)
  Vector3d a1 = Vector3d(0, 0, 1), a2 = Vector3d(0.6, 0, 0.8), a3 = Vector3d(0.8, 0.36, 0.48),
           a4 = Vector3d(-0.6, 0, 0.8);
  int crank = 0, coupler = 0, rocker = 0, closure = -1;
  Vector3d a3_rocker;

  void build(Parts& p, double open) {
    a1.normalize(), a2.normalize(), a3.normalize(), a4.normalize();
    a3_rocker = Eigen::AngleAxisd(open, a4) * a3;
    crank = p.add("crank", 0.5, 0.5 * (a1 + a2));
    coupler = p.add("coupler", 0.7, 0.5 * (a2 + a3));
    rocker = p.add("rocker", 0.6, 0.5 * (a3_rocker + a4));
    const Vector3d O = Vector3d::Zero();
    p.join("revolute", "crank_joint", 0, O, axisTo(a1), crank, O, axisTo(a1));
    p.join("revolute", "coupler_joint", crank, O, axisTo(a2), coupler, O, axisTo(a2));
    p.join("revolute", "rocker_joint", 0, O, axisTo(a4), rocker, O, axisTo(a4));
    closure = p.join("revolute", "closure", coupler, O, axisTo(a3), rocker, O, axisTo(a3_rocker));
  }
  // The closing axis as the coupler and the rocker carry it now.
  void axes(const Mechanism& m, Vector3d& on_coupler, Vector3d& on_rocker) const {
    on_coupler = m.rotation(coupler) * a3;
    on_rocker = m.rotation(rocker) * a3_rocker;
  }
};

TEST(Assembly, SphericalFourBarWhoseCutAxesStart144RadiansApartCloses) {
  Mechanism m;
  Parts p{m};
  SphericalFourBar sb;
  sb.build(p, 1.44);
  ASSERT_NEAR(std::acos(sb.a3.dot(sb.a3_rocker)), 1.44, 0.5);  // the start's orientation gap
  m.assemble();
  EXPECT_LT(m.positionViolation(), 1e-12);
  Vector3d c, r;
  sb.axes(m, c, r);
  EXPECT_LT((c - r).norm(), 1e-12) << c.transpose() << " / " << r.transpose();
  // The crank's axis stays a1 and the rocker's a4 (ground joints), the coupler's a2 on the
  // crank's cone: the angles between consecutive axes are the links' own.
  EXPECT_NEAR((m.rotation(sb.crank) * sb.a2).dot(c), sb.a2.dot(sb.a3), 1e-12);
  EXPECT_NEAR(r.dot(sb.a4), sb.a3.dot(sb.a4), 1e-12);
}

TEST(Assembly, CutAxesStartingNearlyOpposedCloseUnmirrored) {
  for (double open : {2.4, 2.8, -2.6}) {
    Mechanism m;
    Parts p{m};
    SphericalFourBar sb;
    sb.build(p, open);
    ASSERT_LT(sb.a3.dot(sb.a3_rocker), 0) << open;  // nearer the mirror pose than the joint's own at the start
    m.assemble();
    EXPECT_LT(m.positionViolation(), 1e-12) << open;
    Vector3d c, r;
    sb.axes(m, c, r);
    EXPECT_GT(c.dot(r), 1 - 1e-12) << open;  // aligned, not opposed
  }
}

// A hinge whose frames start 170 degrees apart (about a line square to its axis): under its
// dot-product equations alone it closed mirrored (axes opposed) and was refused; on the
// tree its body is placed where the frames coincide, the axes aligned.
// Exactly opposed at the start (a3 square to a4, the rocker turned by pi): the axes'
// difference is at its largest there, where it has no slope to descend.
TEST(Assembly, CutAxesStartingExactlyOpposedCloseUnmirrored) {
  for (double open : {kPi, -kPi}) {
    Mechanism m;
    Parts p{m};
    SphericalFourBar sb;
    sb.a3 = Vector3d(0.8, 0.36, 0.6);  // a3 . a4 = 0
    sb.build(p, open);
    ASSERT_LT(sb.a3.dot(sb.a3_rocker), -1 + 1e-15) << open;
    m.assemble();
    EXPECT_LT(m.positionViolation(), 1e-12) << open;
    Vector3d c, r;
    sb.axes(m, c, r);
    EXPECT_GT(c.dot(r), 1 - 1e-12) << open;
  }
}

TEST(Assembly, AHingeWhoseFramesStart170DegreesApartClosesUnmirrored) {
  Mechanism m;
  Body b = body("arm", 1.0, 0.01 * Matrix3d::Identity(), Vector3d(0.5, 0, 0));
  b.p = Quaterniond(Eigen::AngleAxisd(170.0 * kPi / 180.0, Vector3d::UnitX()));
  const int id = m.addBody(b);
  JointFrame on_arm;
  on_arm.sp_B = Vector3d(-0.5, 0, 0);
  m.addJoint(makeJoint("revolute", "hinge", Mechanism::kGround, JointFrame(), id, on_arm));
  m.assemble();
  EXPECT_LT(m.positionViolation(), 1e-14);
  EXPECT_GT(m.rotation(id).col(2).dot(Vector3d::UnitZ()), 1 - 1e-14);  // the axes aligned
  EXPECT_LT((m.position(id) - Vector3d(0.5, 0, 0)).norm(), 1e-14);
  EXPECT_LT((m.rotation(id) - Matrix3d::Identity()).norm(), 1e-14);
}

// Parallelograms in series driven from 0 to the crank at pi/2 and pi by a target: the path
// passes flat, where every loop's anti-parallelogram branch crosses its own; the predictor
// keeps the parallelograms (every crank turned as the first).
TEST(Assembly, ParallelogramsTakenAcrossTheirFlatPoseStayParallelograms) {
  for (double q : {kPi / 2, kPi, -2.0}) {
    Mechanism m;
    models::fourBarChain(m, 4, 0.4, 1.0, 0.3);
    m.assemble({CoordinateTarget{0, 0, q}});
    EXPECT_LT(m.positionViolation(), 1e-12) << q;
    for (int k = 1; k <= 4; ++k) {  // joints 0..4: the cranks' pivots
      const double d = std::remainder(m.jointPosition(k, 0) - q, 2 * kPi);
      EXPECT_NEAR(d, 0.0, 1e-10) << "crank " << k << " at q " << q;
    }
  }
}

// A four-bar whose file pose has the crank and the rocker outside their limits (the loop
// open as well), like a Strandbeest leg whose joints are all limited away from zero. The
// limits admit a band of closed poses: held on the bound nearest the start one at a time,
// the crank on its bound leaves the rocker outside its own, and both on their bounds the
// loop cannot close. The limits are bounds of the assembly's least squares instead: it
// closes with both coordinates within their limits.
TEST(Assembly, ALoopStartedOutsideItsJointsLimitsClosesWithinThem) {
  auto rockerAt = [](double crank) {  // the closed rocker angle for a crank angle
    Mechanism m;
    Parts p{m};
    FourBar fb;
    fb.build(p);
    m.assemble({{fb.crank_joint, 0, crank}});
    return m.jointPosition(fb.rocker_joint, 0);
  };
  const double r1 = rockerAt(1.25), r2 = rockerAt(1.35), r0 = rockerAt(1.0);
  const double r_lo = std::min(r1, r2), r_hi = std::max(r1, r2);
  ASSERT_TRUE(r0 < r_lo || r0 > r_hi);  // the crank on its lower bound puts the rocker outside its limits
  Mechanism m;
  Parts p{m};
  FourBar fb;
  fb.build(p);
  m.setJointLimits(fb.crank_joint, 0, 1.0, 1.4);
  m.setJointLimits(fb.rocker_joint, 0, r_lo, r_hi);
  ASSERT_GT(std::fabs(r_lo), 1e-3);  // (the rocker's zero, the file's pose, lies outside too)
  ASSERT_TRUE(0.0 < r_lo || 0.0 > r_hi);
  m.assemble();
  EXPECT_LT(m.positionViolation(), 1e-12);
  const double crank = m.jointPosition(fb.crank_joint, 0), rocker = m.jointPosition(fb.rocker_joint, 0);
  EXPECT_GE(crank, 1.0 - 1e-9);
  EXPECT_LE(crank, 1.4 + 1e-9);
  EXPECT_GE(rocker, r_lo - 1e-9);
  EXPECT_LE(rocker, r_hi + 1e-9);
  EXPECT_NEAR((p.now(fb.coupler, fb.C1) - fb.D).norm(), fb.c, 1e-12);  // the loop's equation
}

// A spherical four-bar closed by a ball at a point of its closing axis (as onshape-to-robot
// closes a spherical parallel mechanism): the point stays on the sphere about the axes'
// common point, so one of the ball's three equations is dependent, and at a start whose
// points are a chord apart that row cannot shrink with the others as (1 - s) R0: the
// continuation follows the least-squares path.
struct BallClosedSphericalFourBar : SphericalFourBar {
  double rho = 0.5;  // the ball's distance from the axes' common point

  // miss: the rocker's ground pivot moved along its axis (the axes no longer meet).
  void build(Parts& p, double open, double miss) {
    a1.normalize(), a2.normalize(), a3.normalize(), a4.normalize();
    a3_rocker = Eigen::AngleAxisd(open, a4) * a3;
    crank = p.add("crank", 0.5, 0.5 * (a1 + a2));
    coupler = p.add("coupler", 0.7, 0.5 * (a2 + rho * a3));
    rocker = p.add("rocker", 0.6, 0.5 * (rho * a3_rocker + a4));
    const Vector3d O = Vector3d::Zero();
    const Matrix3d I = Matrix3d::Identity();
    p.join("revolute", "crank_joint", 0, O, axisTo(a1), crank, O, axisTo(a1));
    p.join("revolute", "coupler_joint", crank, O, axisTo(a2), coupler, O, axisTo(a2));
    p.join("revolute", "rocker_joint", 0, O + miss * a4, axisTo(a4), rocker, O, axisTo(a4));
    closure = p.join("spherical", "closure", coupler, rho * a3, I, rocker, rho * a3_rocker, I);
  }
};

TEST(Assembly, ABallClosedSphericalLoopStartedOneRadianOpenCloses) {
  for (double open : {1.0, -1.44}) {
    Mechanism m;
    Parts p{m};
    BallClosedSphericalFourBar sb;
    sb.build(p, open, 0.0);
    m.assemble();
    EXPECT_LT(m.positionViolation(), 1e-12) << open;
    // The ball's points meet on the sphere of radius rho; the rocker's axis stays a4.
    const Vector3d Pc = p.now(sb.coupler, sb.rho * sb.a3), Pr = p.now(sb.rocker, sb.rho * sb.a3_rocker);
    EXPECT_LT((Pc - Pr).norm(), 1e-12) << open;
    EXPECT_NEAR(Pc.norm(), sb.rho, 1e-12) << open;
    EXPECT_NEAR(Pr.dot(sb.a4), sb.rho * sb.a3.dot(sb.a4), 1e-12) << open;
  }
}

// The same loop with the rocker's pivot 1e-6 m off the axes' common point, along its axis,
// as a file's rounded numbers leave it: no pose closes it (the ball's point on the rocker
// runs on a circle 1e-6 |a3 . a4| m off the coupler's sphere), and the gap is at the
// file's precision (2e-6 of the loop's size). Assembly keeps the least-squares pose (the gap under the miss), the
// dependent row dropped; the mechanism then moves under gravity with its independent
// equations held and the gap unchanged. A miss of 1e-3 m is refused.
TEST(Assembly, ARedundantLoopWhoseAxesMissByAFilesRoundingIsAcceptedAndRuns) {
  const double miss = 1e-6;
  Mechanism m;
  Parts p{m};
  BallClosedSphericalFourBar sb;
  sb.build(p, 0.3, miss);
  m.setGravity(Vector3d(0, -9.81, 0));
  const AssemblyReport rep = m.assemble();
  const double gap = miss * std::fabs(sb.a3.dot(sb.a4));  // the rocker's circle off the sphere
  EXPECT_GT(rep.position_residual, 1e-9);
  EXPECT_LT(rep.position_residual, 1e-5);
  EXPECT_LE(m.positionViolation(), miss * 1.0001);
  EXPECT_GE(m.positionViolation(), 0.1 * gap);
  const double crank0 = m.jointPosition(0, 0);
  for (int i = 0; i < 200; ++i) m.step(1e-3);
  EXPECT_GT(std::fabs(m.jointPosition(0, 0) - crank0), 1e-3);  // it moves: one dof, not locked
  EXPECT_LE(m.positionViolation(), miss * 1.0001);
  EXPECT_LT(m.relativePositionViolation(), 1e-12);  // the independent equations (the dropped one not judged)

  Mechanism far;
  Parts q{far};
  BallClosedSphericalFourBar off;
  off.build(q, 0.3, 1e-3);
  try {
    far.assemble();
    FAIL() << "assembled a loop whose axes miss by 1e-3 m";
  } catch (const ModelError& e) {
    EXPECT_NE(std::string(e.what()).find("does not close"), std::string::npos) << e.what();
  }
}

TEST(Assembly, AClosedPoseIsLeftAsItIs) {
  Mechanism m;
  Parts p{m};
  SphericalFourBar sb;
  sb.build(p, 0.0);
  m.assemble();
  for (int j = 0; j < m.numJoints(); ++j) EXPECT_NEAR(m.jointPosition(j, 0), 0.0, 1e-14) << m.joint(j).name();
}

}  // namespace
}  // namespace mechanism_sim
