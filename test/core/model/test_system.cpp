// System (system.h): validation, layout, scales, and the State's clock. Oracles: one bad
// input per kind that System::finalize validates, each a ModelError whose message names the
// body, joint, drive or constraint at fault; layout sizes counted by hand from the joint
// types (6 - dof equations each, one per coupler, drive and limit; n = 6 nb); scales and
// inverse masses from their definitions on models whose answer is written here; the clock
// against exact arithmetic: after N steps of h the time is t_run + N h to one rounding, bit
// for bit, where a running sum is not.
#include <gtest/gtest.h>

#include <cmath>
#include <initializer_list>
#include <string>

#include "mechanism_sim/core/mechanism.h"
#include "mechanism_sim/core/models.h"
#include "random_loops.h"

namespace mechanism_sim {
namespace {

using test_util::Builder;

// finalize() throws a ModelError whose message holds every one of `says`.
void expectModelError(System& sys, std::initializer_list<const char*> says) {
  try {
    sys.finalize();
    ADD_FAILURE() << "finalize() accepted the model; expected a ModelError saying " << *says.begin();
  } catch (const ModelError& e) {
    for (const char* s : says) EXPECT_NE(std::string(e.what()).find(s), std::string::npos) << e.what();
  }
}

// Two bodies: b1 on revolute0 to ground, b2 on spherical1 to b1, and three more bodies b3..b5
// on revolutes 2..4 (a chain), all valid.
Builder validChain() {
  Builder b(1.0, 1.0);
  for (int k = 1; k <= 5; ++k) b.addBody(k, Vector3d(0.1, 0.1, 0.1), Vector3d(k, 0, 0), Matrix3d::Identity());
  b.addJoint("revolute", 0, 1, Vector3d(0.5, 0, 0), Matrix3d::Identity());
  b.addJoint("spherical", 1, 2, Vector3d(1.5, 0, 0), Matrix3d::Identity());
  for (int k = 3; k <= 5; ++k) b.addJoint("revolute", k - 1, k, Vector3d(k - 0.5, 0, 0), Matrix3d::Identity());
  return b;
}

TEST(SystemValidation, AValidModelFinalizes) {
  Builder b = validChain();
  EXPECT_NO_THROW(b.sys->finalize());
}

TEST(SystemValidation, NoMovingBody) {
  Builder b(1.0, 1.0);
  expectModelError(*b.sys, {"no moving body"});
}

TEST(SystemValidation, EachBadBodyIsNamed) {
  struct Case {
    const char* says;
    void (*spoil)(Body&);
  };
  const Case cases[] = {
      {"mass must be finite and >= 0", [](Body& B) { B.m = -1.0; }},
      {"mass must be finite and >= 0", [](Body& B) { B.m = NAN; }},
      {"inertia must be finite", [](Body& B) { B.Jp(1, 1) = INFINITY; }},
      {"inertia must be symmetric", [](Body& B) { B.Jp(0, 1) += 0.05; }},
      {"negative principal moment", [](Body& B) { B.Jp = Vector3d(-0.01, 0.1, 0.1).asDiagonal(); }},
      {"triangle inequality", [](Body& B) { B.Jp = Vector3d(0.1, 0.1, 0.3).asDiagonal(); }},
      {"initial state must be finite with a non-zero orientation", [](Body& B) { B.p = Quaterniond(0, 0, 0, 0); }},
      {"initial state must be finite with a non-zero orientation", [](Body& B) { B.v(2) = NAN; }},
      {"initial state must be finite with a non-zero orientation", [](Body& B) { B.r(0) = INFINITY; }},
      {"initial state must be finite with a non-zero orientation", [](Body& B) { B.w(1) = NAN; }},
  };
  for (const Case& c : cases) {
    Builder b = validChain();
    c.spoil(b.sys->bodies[4]);
    SCOPED_TRACE(c.says);
    expectModelError(*b.sys, {"body 'b4'", c.says});
  }
}

TEST(SystemValidation, BadGravityAndIntegratorOptions) {
  {
    Builder b = validChain();
    b.sys->gravity(1) = NAN;
    expectModelError(*b.sys, {"gravity must be finite"});
  }
  {
    Builder b = validChain();
    b.sys->options.method = "euler";
    expectModelError(*b.sys, {"unknown integrator 'euler'"});
  }
  {
    Builder b = validChain();
    b.sys->options.formulation = "fastest";
    expectModelError(*b.sys, {"unknown formulation 'fastest'"});
  }
  for (double IntegratorOptions::*tol :
       {&IntegratorOptions::position_tol, &IntegratorOptions::velocity_tol, &IntegratorOptions::solve_tol}) {
    for (double bad : {0.0, -1e-12, double(NAN)}) {
      Builder b = validChain();
      b.sys->options.*tol = bad;
      expectModelError(*b.sys, {"tolerances must be positive"});
    }
  }
}

TEST(SystemValidation, EachBadDriveIsNamed) {
  {  // no such joint, no such coordinate
    Builder b = validChain();
    b.addDrive(9, 0, DriveProfile::velocity(1.0), 0.0);
    expectModelError(*b.sys, {"drive 0", "no such joint coordinate"});
    Builder c = validChain();
    c.addDrive(0, 0, DriveProfile::velocity(1.0), 0.0);
    c.addDrive(0, 1, DriveProfile::velocity(1.0), 0.0);  // a revolute has one coordinate
    expectModelError(*c.sys, {"drive 1", "no such joint coordinate"});
  }
  {  // a spherical joint's rates are not the derivatives of its coordinates
    Builder b = validChain();
    b.addDrive(1, 0, DriveProfile::velocity(1.0), 0.0);
    expectModelError(*b.sys, {"joint 'spherical1'", "a drive needs a position coordinate"});
  }
  {
    Builder b = validChain();
    b.addDrive(0, 0, DriveProfile::velocity(1.0), 0.0);
    b.addDrive(0, 0, DriveProfile::velocity(2.0), 0.0);
    expectModelError(*b.sys, {"joint 'revolute0'", "already driven"});
  }
  {
    Builder b = validChain();
    b.addDrive(0, 0, DriveProfile::velocity(1.0), NAN);
    expectModelError(*b.sys, {"joint 'revolute0'", "drive start position not finite"});
  }
}

// A constraint over more bodies than the layout takes (kMaxConstraintBodies).
class WideTie : public Constraint {
 public:
  explicit WideTie(std::vector<int> bodies) : Constraint("wide", std::move(bodies)) {}
  std::string type() const override { return "tie"; }
  int size() const override { return 1; }
  void evaluate(const BodyKin* const*, const EvalContext&, Eigen::Ref<Eigen::VectorXd> Phi,
                Eigen::Ref<Eigen::MatrixXd> J, Eigen::Ref<Eigen::VectorXd> gamma) const override {
    Phi.setZero(), J.setZero(), gamma.setZero();
  }
};

TEST(SystemValidation, AConstraintOverTooManyBodiesIsNamed) {
  Builder b(1.0, 1.0);
  std::vector<int> bodies;
  for (int k = 1; k <= kMaxConstraintBodies + 1; ++k) {
    b.addBody(k, Vector3d(0.1, 0.1, 0.1), Vector3d(k, 0, 0), Matrix3d::Identity());
    b.addJoint("revolute", k - 1, k, Vector3d(k - 0.5, 0, 0), Matrix3d::Identity());
    bodies.push_back(k);
  }
  b.sys->constraints.push_back(std::make_shared<WideTie>(bodies));
  const std::string says = "couples more than " + std::to_string(kMaxConstraintBodies) + " bodies";
  expectModelError(*b.sys, {"constraint 'wide'", says.c_str()});
}

// A limit is validated as a drive is: one on a joint coordinate that does not exist, or with
// bounds that are not finite and ordered, is a ModelError naming it (the limit, or its
// joint). Each case runs in a child process, so that a crash fails this test alone.
TEST(SystemValidation, ABadLimitIsAModelError) {
  struct Case {
    int joint, k;
    double lower, upper;
    const char* says;
  };
  const Case cases[] = {
      {9, 0, -1.0, 1.0, "limit"},            // no such joint
      {0, 2, -1.0, 1.0, "revolute0"},        // no such coordinate of a revolute
      {0, 0, 1.0, -1.0, "revolute0"},        // lower > upper
      {0, 0, -1.0, double(NAN), "revolute0"},  // not finite
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(std::string("joint ") + std::to_string(c.joint) + " k " + std::to_string(c.k) + " [" +
                 std::to_string(c.lower) + ", " + std::to_string(c.upper) + "]");
    EXPECT_EXIT(
        {
          Builder b = validChain();
          b.addLimit(c.joint, c.k, c.lower, c.upper);
          try {
            b.sys->finalize();
          } catch (const ModelError& e) {
            std::exit(std::string(e.what()).find(c.says) != std::string::npos ? 0 : 2);
          }
          std::exit(1);  // accepted
        },
        ::testing::ExitedWithCode(0), "");
  }
}

// ---- layout

// revolute0 (ground-b1, 5 equations), spherical1 (b1-b2, 3), prismatic2 (b2-b3, 5),
// universal3 (b3-ground, 4: closes a loop), a coupler revolute0 = 0.5 prismatic2 (1), a
// velocity drive on universal3's second coordinate (1), a limit on prismatic2 (1).
Builder layoutModel() {
  Builder b(1.0, 1.0);
  b.addBody(1.0, Vector3d(0.1, 0.1, 0.1), Vector3d(1, 0, 0), Matrix3d::Identity());
  b.addBody(2.0, Vector3d(0.1, 0.1, 0.1), Vector3d(2, 0, 0), Matrix3d::Identity());
  b.addBody(3.0, Vector3d(0.1, 0.1, 0.1), Vector3d(2, 1, 0), Matrix3d::Identity());
  b.addJoint("revolute", 0, 1, Vector3d(0, 0, 0), Matrix3d::Identity());
  b.addJoint("spherical", 1, 2, Vector3d(1.5, 0, 0), Matrix3d::Identity());
  b.addJoint("prismatic", 2, 3, Vector3d(2, 0.5, 0), Matrix3d::Identity());
  b.addJoint("universal", 3, 0, Vector3d(2, 2, 0), Matrix3d::Identity());
  b.addCoupler(0, 2, 0.5, 0.0);
  b.addDrive(3, 1, DriveProfile::velocity(0.2), 0.0);
  b.addLimit(2, 0, -0.3, 0.3);
  return b;
}

TEST(SystemLayout, SizesRowsAndOrderAreCountedFromTheJointTypes) {
  Builder b = layoutModel();
  System& sys = *b.sys;
  sys.finalize();
  EXPECT_EQ(sys.nb, 3);
  EXPECT_EQ(sys.n, 18);
  EXPECT_EQ(sys.m, 5 + 3 + 5 + 4 + 1 + 1 + 1);
  EXPECT_EQ(sys.m_eq, sys.m - 1) << "the limit's row is not an equality";
  ASSERT_EQ(sys.numConstraints(), 7);
  // joints, the coupler, then the drive, then the limit
  const char* types[] = {"revolute", "spherical", "prismatic", "universal", "coupler", "drive", "limit"};
  const int sizes[] = {5, 3, 5, 4, 1, 1, 1};
  int row = 0;
  for (int c = 0; c < 7; ++c) {
    EXPECT_EQ(sys.constraints[c]->type(), types[c]) << c;
    EXPECT_EQ(sys.constraints[c]->id(), c);
    EXPECT_EQ(sys.layout[c].row, row) << c;
    EXPECT_EQ(sys.layout[c].size, sizes[c]) << c;
    row += sizes[c];
  }
  EXPECT_EQ(sys.drives[0].constraint, 5);
  EXPECT_EQ(sys.limits[0].constraint, 6);
  EXPECT_EQ(sys.constraints[5]->drive(), 0);
  EXPECT_EQ(sys.constraints[6]->limit(), 0);
  EXPECT_EQ(sys.rheonomic, std::vector<int>{5}) << "the drive alone has a velocity term";
  // the coupler's slots: the bodies of revolute0 (ground, b1) then prismatic2's (b2, b3),
  // moving indices (body - 1), -1 for ground
  EXPECT_EQ(sys.layout[4].bodies, (std::vector<int>{-1, 0, 1, 2}));
  EXPECT_EQ(sys.layout[3].bodies, (std::vector<int>{2, -1}));

  // the State of this layout
  const State s = initialState(sys);
  EXPECT_EQ(s.x.size(), 7 * 3);
  EXPECT_EQ(s.u.size(), 18);
  EXPECT_EQ(s.lambda.size(), sys.m);
  EXPECT_EQ(static_cast<int>(s.dropped.size()), sys.m);
  EXPECT_EQ(s.limit_side, std::vector<signed char>{0}) << "a limit starts free";
  EXPECT_EQ(s.tracked.size(), 7u);
  EXPECT_EQ(s.drive.size(), 1u);
  EXPECT_EQ(s.drive[0].v1, 0.2);
  EXPECT_EQ(s.friction.size(), 4u);
  EXPECT_EQ(s.t, 0.0);
  for (int b = 0; b < 3; ++b) {  // positions r then p (w x y z), from the bodies
    EXPECT_EQ(Vector3d(s.x.segment<3>(7 * b)), sys.bodies[b + 1].r);
    EXPECT_EQ(s.x(7 * b + 3), 1.0);
  }

  // finalizing again lays out the same (drives and limits are made again, not added)
  const int m = sys.m;
  sys.finalize();
  EXPECT_EQ(sys.m, m);
  EXPECT_EQ(sys.numConstraints(), 7);
  EXPECT_EQ(sys.layout[6].row, m - 1);
}

// Scales by their definitions: the length scale is the largest joint offset, spring
// length or extent of the bodies; the mass scale the mean mass of the bodies that have one,
// which also stands in for a massless body's mass in the row weights (Minv); the moments get
// 1e-3 of their mean added there.
TEST(SystemLayout, ScalesAndInverseMassesFollowTheirDefinitions) {
  Builder b(1.0, 1.0);
  b.addBody(2.0, Vector3d(0.1, 0.2, 0.25), Vector3d(3, 0, 0), Matrix3d::Identity());
  b.addBody(0.0, Vector3d::Zero(), Vector3d(3, 0, -1), Matrix3d::Identity());  // massless
  b.addBody(4.0, Vector3d(0.1, 0.1, 0.1), Vector3d(3, 0, -2), Matrix3d::Identity());
  b.addJoint("revolute", 0, 1, Vector3d(0, 0, 0), Matrix3d::Identity());  // offset 3 on b1
  b.addJoint("revolute", 1, 2, Vector3d(3, 0, -0.5), Matrix3d::Identity());
  b.addJoint("revolute", 2, 3, Vector3d(3, 0, -1.5), Matrix3d::Identity());
  System& sys = *b.sys;
  sys.finalize();
  EXPECT_EQ(sys.length_scale, 3.0);
  EXPECT_EQ(sys.mass_scale, 3.0) << "mean of 2 and 4";
  EXPECT_DOUBLE_EQ(sys.acceleration_scale, 9.81);
  EXPECT_DOUBLE_EQ(sys.velocity_scale, std::sqrt(9.81 * 3.0));
  // b1: 1/m and (Jp + 1e-3 tr/3 I)^-1
  const Matrix3d J1 = sys.bodies[1].Jp;
  const Matrix3d J1s = J1 + 1e-3 * J1.trace() / 3 * Matrix3d::Identity();
  EXPECT_LT((sys.Minv[0].topLeftCorner<3, 3>() - Matrix3d::Identity() / 2.0).norm(), 1e-15);
  EXPECT_LT((sys.Minv[0].bottomRightCorner<3, 3>() - J1s.inverse()).norm(), 1e-12 * J1s.inverse().norm());
  // the massless b2 weighs the mass scale and the inertia scale (mean moment of b1 and b3)
  EXPECT_LT((sys.Minv[1].topLeftCorner<3, 3>() - Matrix3d::Identity() / 3.0).norm(), 1e-15);
  const double inertia_scale = 0.5 * (J1.trace() / 3 + sys.bodies[3].Jp.trace() / 3);
  EXPECT_DOUBLE_EQ(sys.inertia_scale, inertia_scale);
  EXPECT_LT((sys.Minv[1].bottomRightCorner<3, 3>() - Matrix3d::Identity() / inertia_scale).norm(),
            1e-12 / inertia_scale);
  // a spring longer than everything sets the length scale
  SpringDamper s;
  s.body_i = 0, s.body_j = 3, s.k = 10.0, s.L0 = 5.0;
  sys.springs.push_back(s);
  sys.finalize();
  EXPECT_EQ(sys.length_scale, 5.0);
  // its load k L0 / mass scale is the acceleration scale when larger than gravity
  EXPECT_DOUBLE_EQ(sys.acceleration_scale, 10.0 * 5.0 / 3.0);
}

// limitSide: a coordinate at its bound, or past it by a few ulps of the bounds (a drive's
// q = v t landing on it), is at it; past by more, on that side.
TEST(SystemLimits, SideOfABoundWithARoundOffSlack) {
  const LimitSpec L{0, 0, -1.0, 2.0, 0};
  EXPECT_EQ(limitSide(L, 0.5), 0);
  EXPECT_EQ(limitSide(L, 2.0), 0);
  EXPECT_EQ(limitSide(L, std::nextafter(2.0, 3.0)), 0);
  EXPECT_EQ(limitSide(L, std::nextafter(-1.0, -2.0)), 0);
  EXPECT_EQ(limitSide(L, 2.0 + 1e-12), 1);
  EXPECT_EQ(limitSide(L, -1.0 - 1e-12), -1);
}

// drivenAtLimit: a driven coordinate within round-off of its range is held by its drive;
// past it, the run cannot go on (SimulationError naming the joint); an undriven one: false.
TEST(SystemLimits, ADrivePastItsLimitIsASimulationErrorNamingTheJoint) {
  Builder b = validChain();
  b.addDrive(0, 0, DriveProfile::velocity(1.0), 0.0);
  b.addLimit(0, 0, -1.0, 1.0);
  b.addLimit(2, 0, -1.0, 1.0);
  System& sys = *b.sys;
  sys.finalize();
  EXPECT_TRUE(drivenAtLimit(sys, sys.limits[0], 1.0 + 1e-12, 1.0));
  EXPECT_FALSE(drivenAtLimit(sys, sys.limits[1], 1.5, 1.0));
  try {
    drivenAtLimit(sys, sys.limits[0], 1.5, 1.5);
    ADD_FAILURE() << "a drive past its limit was accepted";
  } catch (const SimulationError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("joint 'revolute0'"), std::string::npos) << what;
    EXPECT_NE(what.find("past its limits"), std::string::npos) << what;
    EXPECT_NE(what.find("t = 1.5"), std::string::npos) << what;
  }
}

// ---- the clock

// After N steps of h the time is t_run + N h, one rounding: the running sum of 1000 steps of
// 1 ms is not 1000 * 1e-3, the clock is. A step of another size starts a run where
// the time stands.
// The spring law (SpringDamper::forceOnI): tension k (L - L0) + c L_dot + f_act + actuation
// along the line from i's point to j's, written here from the points' world positions and
// velocities; none where the points coincide.
TEST(SpringLaw, TensionAlongTheLineBetweenThePoints) {
  BodyKin ki, kj;
  ki.r = Vector3d(0.1, -0.2, 0.3), kj.r = Vector3d(1.0, 0.5, -0.4);
  ki.A_Oi = Eigen::AngleAxisd(0.4, Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  kj.A_Oi = Eigen::AngleAxisd(-1.1, Vector3d(0, 1, 1).normalized()).toRotationMatrix();
  ki.v = Vector3d(0.3, 0.0, -0.1), kj.v = Vector3d(-0.2, 0.4, 0.5);
  ki.w = Vector3d(0.5, -1.0, 0.2), kj.w = Vector3d(0.0, 0.7, -0.3);  // body components
  SpringDamper sd;
  sd.sp_i = Vector3d(0.05, 0.0, 0.1), sd.sp_j = Vector3d(-0.1, 0.2, 0.0);
  sd.k = 200.0, sd.c = 3.0, sd.L0 = 0.6, sd.f_act = 1.5;
  const Vector3d pi = ki.r + ki.A_Oi * sd.sp_i, pj = kj.r + kj.A_Oi * sd.sp_j;
  const Vector3d vi = ki.v + ki.A_Oi * ki.w.cross(sd.sp_i), vj = kj.v + kj.A_Oi * kj.w.cross(sd.sp_j);
  const double L = (pj - pi).norm();
  const Vector3d e = (pj - pi) / L;
  const double F = sd.k * (L - sd.L0) + sd.c * e.dot(vj - vi) + sd.f_act + 0.25;
  EXPECT_LE((sd.forceOnI(ki, kj, 0.25, 1.0) - F * e).norm(), 1e-12 * std::fabs(F));
  // coincident points: no direction, no force
  kj.r = pi - kj.A_Oi * sd.sp_j;
  EXPECT_EQ(sd.forceOnI(ki, kj, 0.25, 1.0), Vector3d::Zero());
}

TEST(StateClock, TimeAfterNStepsIsTheStartOfTheRunPlusNTimesTheStep) {
  State s;
  double sum = 0.0;
  const double h = 1e-3;
  for (int k = 0; k < 1000; ++k) {
    const double next = s.timeAfterStep(h);
    s.countStep(h);
    EXPECT_EQ(s.t, next) << "timeAfterStep is the time countStep reaches";
    sum += h;
  }
  EXPECT_EQ(s.t, 1000 * h);
  EXPECT_EQ(s.steps, 1000);
  ASSERT_NE(sum, 1000 * h) << "(the running sum differs here: the check can fail)";
  // a run of another step size starts at the time reached
  const double t1 = s.t, h2 = 2.5e-4;
  for (int k = 0; k < 3001; ++k) s.countStep(h2);
  EXPECT_EQ(s.t_run, t1);
  EXPECT_EQ(s.n_run, 3001);
  EXPECT_EQ(s.t, t1 + 3001 * h2);
  EXPECT_EQ(s.steps, 4001);
  // a step of another size, asked for before it is taken
  EXPECT_EQ(s.timeAfterStep(0.1), s.t + 0.1);
  // the clock is part of a snapshot: set back, the same times follow
  const State::Clock c = s.clock();
  State r;
  r.setClock(c);
  for (int k = 0; k < 10; ++k) s.countStep(h2), r.countStep(h2);
  EXPECT_EQ(r.t, s.t);
  EXPECT_EQ(r.t, t1 + 3011 * h2);
}

// The same through the facade, in both formulations: Mechanism::time() after N steps.
TEST(StateClock, AMechanismsTimeIsExactAfterManySteps) {
  for (const char* f : {"absolute", "joint"}) {
    Mechanism m;
    models::pendulumChain(m, 2);
    IntegratorOptions io;
    io.formulation = f;
    m.setIntegrator(io);
    m.build();
    m.assemble();
    ASSERT_STREQ(m.formulation(), f);
    for (int k = 0; k < 1000; ++k) m.step(1e-3);
    EXPECT_EQ(m.time(), 1000 * 1e-3) << f;
    for (int k = 0; k < 7; ++k) m.step(3e-4);
    EXPECT_EQ(m.time(), 1000 * 1e-3 + 7 * 3e-4) << f;
    EXPECT_EQ(m.stepsTaken(), 1007) << f;
  }
}

}  // namespace
}  // namespace mechanism_sim
