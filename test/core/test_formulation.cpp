// The formulation choice (formulation.h, chooseFormulation). Oracle: the rule as documented,
// applied by hand to small Systems whose answer is counted here: "auto" takes joint
// coordinates for a tree (limits and couplers on tree coordinates cost nothing) and for a
// loop (its closure on the tree), while the drives are at most one per 2 tree coordinates
// (coordinates, not joints: a spherical joint counts 3); else absolute coordinates, and
// absolute with the joint formulation's reason where it cannot run the System (a massless
// body between two moving joints, a massless branch, a constraint type it has no model of,
// Coulomb friction on a loop's cut joint). "joint" on such a System throws ModelError naming
// that reason; "absolute" is always taken. Each choice says why, naming what decided it.
#include <gtest/gtest.h>

#include <string>

#include "core/formulation.h"
#include "random_loops.h"

namespace mechanism_sim {
namespace {

using test_util::Builder;

bool contains(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

// Axes with frame z along global x (a revolute about x), or the identity (about z).
Matrix3d aboutX() {
  Matrix3d A;
  A << 0, 0, 1, 1, 0, 0, 0, 1, 0;  // columns bx = y, by = z, bz = x
  return A;
}

// A chain of n bodies along x, each of mass 1, on joints about z (of the types given,
// revolutes past them).
Builder chain(int n, const std::vector<std::string>& types = {}) {
  Builder b(1.0, 1.0);
  for (int k = 1; k <= n; ++k)
    b.addBody(1.0, Vector3d(0.05, 0.05, 0.05), Vector3d(0.3 * k, 0, 0), Matrix3d::Identity());
  for (int k = 1; k <= n; ++k)
    b.addJoint(k - 1 < static_cast<int>(types.size()) ? types[k - 1] : "revolute", k - 1, k,
               Vector3d(0.3 * k - 0.15, 0, 0), Matrix3d::Identity());
  return b;
}

struct Choice {
  Formulation f;
  std::string why;
};
Choice choose(System& sys, Formulation asked) {
  Choice c;
  c.f = chooseFormulation(sys, asked, &c.why);
  return c;
}

TEST(ChooseFormulation, ATreeRunsInJointCoordinatesAndAsAsked) {
  Builder b = chain(3);
  b.sys->finalize();
  const Choice a = choose(*b.sys, Formulation::kAuto);
  EXPECT_EQ(a.f, Formulation::kJoint) << a.why;
  EXPECT_TRUE(contains(a.why, "auto: a tree")) << a.why;
  const Choice j = choose(*b.sys, Formulation::kJoint);
  EXPECT_EQ(j.f, Formulation::kJoint);
  EXPECT_EQ(j.why, "joint coordinates, as asked");
  const Choice x = choose(*b.sys, Formulation::kAbsolute);
  EXPECT_EQ(x.f, Formulation::kAbsolute);
  EXPECT_EQ(x.why, "absolute coordinates, as asked");
  EXPECT_EQ(chooseFormulation(*b.sys, Formulation::kAuto, nullptr), Formulation::kJoint) << "why is optional";
}

// Limits and couplers between tree coordinates are rows on q itself: a tree with every
// coordinate limited and couplers on half of them stays in joint coordinates.
TEST(ChooseFormulation, LimitsAndCouplersOnTheTreeCostNothing) {
  Builder b = chain(4);
  for (int k = 0; k < 4; ++k) b.addLimit(k, 0, -1.0, 1.0);
  b.addCoupler(1, 0, 2.0, 0.0);
  b.addCoupler(3, 2, -1.0, 0.1);
  b.sys->finalize();
  const Choice a = choose(*b.sys, Formulation::kAuto);
  EXPECT_EQ(a.f, Formulation::kJoint) << a.why;
  EXPECT_TRUE(contains(a.why, "limits and couplers")) << a.why;
}

// A four-bar (ground, three links, four revolutes about z in the x-y plane): the joint
// formulation cuts one joint and closes it on the tree; auto takes it and names the joint.
TEST(ChooseFormulation, ALoopRunsInJointCoordinatesNamingTheJointThatClosesIt) {
  Builder b(1.0, 1.0);
  b.addBody(1.0, Vector3d(0.05, 0.05, 0.05), Vector3d(0, 0.2, 0), Matrix3d::Identity());
  b.addBody(1.0, Vector3d(0.05, 0.05, 0.05), Vector3d(0.5, 0.4, 0), Matrix3d::Identity());
  b.addBody(1.0, Vector3d(0.05, 0.05, 0.05), Vector3d(1, 0.2, 0), Matrix3d::Identity());
  b.addJoint("revolute", 0, 1, Vector3d(0, 0, 0), Matrix3d::Identity());
  b.addJoint("revolute", 1, 2, Vector3d(0, 0.4, 0), Matrix3d::Identity());
  b.addJoint("revolute", 2, 3, Vector3d(1, 0.4, 0), Matrix3d::Identity());
  b.addJoint("revolute", 3, 0, Vector3d(1, 0, 0), Matrix3d::Identity());
  b.sys->finalize();
  const Choice a = choose(*b.sys, Formulation::kAuto);
  EXPECT_EQ(a.f, Formulation::kJoint) << a.why;
  EXPECT_TRUE(contains(a.why, "closes a loop")) << a.why;
  bool names_a_joint = false;
  for (const Joint* j : b.sys->joints) names_a_joint |= contains(a.why, "joint '" + j->name() + "' closes a loop");
  EXPECT_TRUE(names_a_joint) << a.why;

  // Coulomb friction on the cut joint is not in the joint formulation: auto runs absolute
  // coordinates saying so, joint refuses with the same reason
  for (auto& f : b.sys->friction) f[0] = 0.1;
  const Choice c = choose(*b.sys, Formulation::kAuto);
  EXPECT_EQ(c.f, Formulation::kAbsolute) << c.why;
  EXPECT_TRUE(contains(c.why, "closes a loop: the joint formulation has no Coulomb friction on it")) << c.why;
  try {
    chooseFormulation(*b.sys, Formulation::kJoint, nullptr);
    ADD_FAILURE() << "joint accepted friction on a cut joint";
  } catch (const ModelError& e) {
    EXPECT_TRUE(contains(e.what(), "has no Coulomb friction on it")) << e.what();
  }
}

// Drives are closures through their absolute equations: auto keeps joint coordinates while
// 2 drives <= tree coordinates. On 8 revolutes, 4 drives stay, 5 tip it over.
TEST(ChooseFormulation, MoreThanOneDrivePerTwoCoordinatesRunsAbsolute) {
  for (int drives : {0, 1, 4, 5, 8}) {
    Builder b = chain(8);
    for (int k = 0; k < drives; ++k) b.addDrive(k, 0, DriveProfile::velocity(0.1), 0.0);
    b.sys->finalize();
    const Choice a = choose(*b.sys, Formulation::kAuto);
    SCOPED_TRACE(std::to_string(drives) + " drives: " + a.why);
    if (drives <= 4) {
      EXPECT_EQ(a.f, Formulation::kJoint);
      if (drives > 0) EXPECT_TRUE(contains(a.why, "few drives"));
    } else {
      EXPECT_EQ(a.f, Formulation::kAbsolute);
      EXPECT_TRUE(contains(a.why, "more than one drive per 2 coordinates"));
      // asked for, the joint formulation still runs it
      EXPECT_EQ(choose(*b.sys, Formulation::kJoint).f, Formulation::kJoint);
    }
  }
}

// The count is of coordinates: 3 revolutes and a spherical joint have 6, so 3 drives are one
// per 2 (joint); 4 revolutes have 4, so 3 drives are more (absolute). Counting joints (4 in
// both) would give the same answer for both.
TEST(ChooseFormulation, DrivesAreCountedAgainstCoordinatesNotJoints) {
  Builder with_ball = chain(4, {"revolute", "revolute", "spherical", "revolute"});
  for (int k : {0, 1, 3}) with_ball.addDrive(k, 0, DriveProfile::velocity(0.1), 0.0);
  with_ball.sys->finalize();
  const Choice a = choose(*with_ball.sys, Formulation::kAuto);
  EXPECT_EQ(a.f, Formulation::kJoint) << a.why;

  Builder hinges = chain(4);
  for (int k : {0, 1, 3}) hinges.addDrive(k, 0, DriveProfile::velocity(0.1), 0.0);
  hinges.sys->finalize();
  const Choice h = choose(*hinges.sys, Formulation::kAuto);
  EXPECT_EQ(h.f, Formulation::kAbsolute) << h.why;
}

// A massless body between two moving joints (a CAD exporter's gimbal: revolute about x, a
// massless cross, revolute about z, the bob): where the two axes line up the joint-space mass
// matrix is singular. Auto runs it in absolute coordinates naming the body and both joints;
// joint refuses with that reason and says what to use.
TEST(ChooseFormulation, AMasslessBodyBetweenMovingJointsRunsAbsoluteSayingWhy) {
  Builder b(1.0, 1.0);
  b.addBody(0.0, Vector3d::Zero(), Vector3d(0, 0, -0.1), Matrix3d::Identity());  // b1: the cross
  b.addBody(1.0, Vector3d(0.05, 0.05, 0.05), Vector3d(0, 0, -1), Matrix3d::Identity());
  b.addJoint("revolute", 0, 1, Vector3d(0, 0, 0), aboutX());
  b.addJoint("revolute", 1, 2, Vector3d(0, 0, -0.1), Matrix3d::Identity());
  b.sys->finalize();
  const std::string reason = "body 'b1' has neither mass nor inertia between joint 'revolute0' and joint 'revolute1'";
  const Choice a = choose(*b.sys, Formulation::kAuto);
  EXPECT_EQ(a.f, Formulation::kAbsolute) << a.why;
  EXPECT_TRUE(contains(a.why, "absolute coordinates (auto: " + reason)) << a.why;
  try {
    chooseFormulation(*b.sys, Formulation::kJoint, nullptr);
    ADD_FAILURE() << "joint accepted a massless body between moving joints";
  } catch (const ModelError& e) {
    EXPECT_TRUE(contains(e.what(), "the joint formulation cannot run this mechanism: " + reason)) << e.what();
    EXPECT_TRUE(contains(e.what(), "use formulation 'absolute'")) << e.what();
  }
  EXPECT_EQ(choose(*b.sys, Formulation::kAbsolute).f, Formulation::kAbsolute);
}

// A moving branch with no mass at all (a rotor turned by nothing with inertia): its joint
// moves no mass, which the articulated-body recursion divides by.
TEST(ChooseFormulation, AMasslessBranchRunsAbsoluteSayingWhy) {
  Builder b = chain(2);
  b.addBody(0.0, Vector3d::Zero(), Vector3d(0.9, 0, 0), Matrix3d::Identity());  // b3
  b.addJoint("revolute", 2, 3, Vector3d(0.75, 0, 0), Matrix3d::Identity());
  b.sys->finalize();
  const Choice a = choose(*b.sys, Formulation::kAuto);
  EXPECT_EQ(a.f, Formulation::kAbsolute) << a.why;
  EXPECT_TRUE(contains(a.why, "body 'b3' and the bodies it carries have neither mass nor inertia")) << a.why;
  EXPECT_TRUE(contains(a.why, "joint 'revolute2'")) << a.why;
  EXPECT_THROW(chooseFormulation(*b.sys, Formulation::kJoint, nullptr), ModelError);
}

// A constraint of a type the joint formulation has no model of.
class DistanceTie : public Constraint {
 public:
  DistanceTie() : Constraint("rope", {1, 2}) {}
  std::string type() const override { return "distance"; }
  int size() const override { return 1; }
  void evaluate(const BodyKin* const*, const EvalContext&, Eigen::Ref<Eigen::VectorXd> Phi,
                Eigen::Ref<Eigen::MatrixXd> J, Eigen::Ref<Eigen::VectorXd> gamma) const override {
    Phi.setZero(), J.setZero(), gamma.setZero();
  }
};

TEST(ChooseFormulation, AConstraintTypeTheTreeHasNoModelOfRunsAbsolute) {
  Builder b = chain(2);
  b.sys->constraints.push_back(std::make_shared<DistanceTie>());
  b.sys->finalize();
  const Choice a = choose(*b.sys, Formulation::kAuto);
  EXPECT_EQ(a.f, Formulation::kAbsolute) << a.why;
  EXPECT_TRUE(contains(a.why, "constraint 'rope' (distance)")) << a.why;
  EXPECT_THROW(chooseFormulation(*b.sys, Formulation::kJoint, nullptr), ModelError);
}

}  // namespace
}  // namespace mechanism_sim
