// What real robot files contain and how the loader takes it (doc/robots.md): a zero pose
// outside the limits, inertias judged on the merged rigid body, mass-0 links with inertia,
// urdfdom's refusals explained, and a step failure named by file and time. Models written
// here, shaped like ../shared/robots' files.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "mechanism_sim/urdf/model.h"

namespace mechanism_sim {
namespace {

// An arm of two links about y (hanging along -z); `extra` goes inside <robot>, `link2`
// inside the second link, `limit2` is the second joint's <limit> attributes.
std::string arm(const std::string& extra = "", const std::string& limit2 = "lower=\"-1\" upper=\"1\" effort=\"10\" velocity=\"5\"",
                const std::string& link2_inertia = "ixx=\"0.02\" iyy=\"0.02\" izz=\"0.001\"") {
  return R"(<robot name="arm">
  <link name="base"/>
  <link name="upper"><inertial><origin xyz="0 0 -0.25"/><mass value="1"/>
    <inertia ixx="0.02" iyy="0.02" izz="0.001" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="lower"><inertial><origin xyz="0 0 -0.25"/><mass value="1"/>
    <inertia )" + link2_inertia + R"( ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="shoulder" type="revolute"><parent link="base"/><child link="upper"/><axis xyz="0 1 0"/>
    <limit lower="-2" upper="2" effort="10" velocity="5"/></joint>
  <joint name="elbow" type="revolute"><parent link="upper"/><child link="lower"/><origin xyz="0 0 -0.5"/>
    <axis xyz="0 1 0"/><limit )" + limit2 + R"(/></joint>
)" + extra + "</robot>";
}

bool hasNote(const MechanismModel& m, const std::string& part) {
  for (const std::string& n : m.notes())
    if (n.find(part) != std::string::npos) return true;
  return false;
}

std::string loadError(const std::string& xml, const LoadOptions& o = {}) {
  try {
    loadModelString(xml, "robot.urdf", o);
  } catch (const LoadError& e) {
    return e.what();
  }
  return "(loaded)";
}

// An elbow whose range excludes 0 (nao's LElbowRoll: [-1.54, -0.035]) starts on its
// nearest limit with a note; the same position given explicitly is refused.
TEST(RealFiles, AZeroPoseOutsideTheLimitsStartsAtTheNearestLimit) {
  const std::string xml = arm("", "lower=\"0.2\" upper=\"1.5\" effort=\"10\" velocity=\"5\"");
  auto m = loadModelString(xml, "robot.urdf");
  EXPECT_NEAR(m->position(m->dofIndex("elbow")), 0.2, 1e-12);
  EXPECT_NEAR(m->position(m->dofIndex("shoulder")), 0.0, 1e-12);
  EXPECT_TRUE(hasNote(*m, "joint 'elbow': its zero pose (0) lies outside its limits [0.2, 1.5]; it starts at 0.2"));
  EXPECT_EQ(m->notes().size(), 1u);
  LoadOptions o;
  o.positions = {{"elbow", 0.0}};
  EXPECT_NE(loadError(xml, o).find("joint 'elbow': initial position 0 is outside its limits"), std::string::npos)
      << loadError(xml, o);
}

// A mimic follower whose zero pose is outside its limits moves its leader (free) so that
// it sits on its nearest limit; the coupling holds.
TEST(RealFiles, AMimicFollowerOutsideItsLimitsMovesItsLeader) {
  const std::string finger = R"(
  <link name="finger"><inertial><mass value="0.1"/><inertia ixx="1e-4" iyy="1e-4" izz="1e-4" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="finger_joint" type="revolute"><parent link="lower"/><child link="finger"/><origin xyz="0 0 -0.5"/>
    <axis xyz="0 1 0"/><limit lower="0.3" upper="1" effort="1" velocity="1"/>
    <mimic joint="elbow" multiplier="2" offset="0.1"/></joint>
)";
  auto m = loadModelString(arm(finger), "robot.urdf");
  EXPECT_NEAR(m->position(m->dofIndex("finger_joint")), 0.3, 1e-10);
  EXPECT_NEAR(m->position(m->dofIndex("elbow")), 0.1, 1e-10);
  EXPECT_TRUE(hasNote(*m, "joint 'finger_joint': its zero pose (0.1) lies outside its limits [0.3, 1]"));
}

// A finger pad whose own inertia is all 1e-10 (not physical: the products exceed the
// moments) fixed to a physical link runs, with a note; the same pad as a moving body alone
// runs with the nearest physical inertia, or with strict_inertia is refused at its
// <inertia>, naming the link.
TEST(RealFiles, InertiaIsJudgedOnTheMergedRigidBody) {
  const std::string pad_inertia =
      R"(<inertia ixx="1e-10" iyy="1e-10" izz="1e-10" ixy="1e-10" ixz="1e-10" iyz="1e-10"/>)";
  const std::string fixed_pad = R"(<link name="pad"><inertial><mass value="0.01"/>)" + pad_inertia +
                                R"(</inertial></link>
  <joint name="pad_fix" type="fixed"><parent link="lower"/><child link="pad"/><origin xyz="0 0 -0.5"/></joint>
)";
  auto m = loadModelString(arm(fixed_pad), "robot.urdf");
  EXPECT_TRUE(hasNote(*m, "link 'pad': its own inertia violates the triangle inequality (a principal moment exceeds the sum of the other two); it is fixed to body 'lower'"));
  for (int i = 0; i < 100; ++i) m->step(1e-3);
  EXPECT_LT(m->positionViolation(), 1e-12);

  const std::string moving_pad = R"(<link name="pad"><inertial><mass value="0.01"/>)" + pad_inertia +
                                 R"(</inertial></link>
  <joint name="pad_joint" type="continuous"><parent link="lower"/><child link="pad"/><origin xyz="0 0 -0.5"/>
    <axis xyz="0 1 0"/></joint>
)";
  // moving, the pad is a body of its own whose inertia (moments (0, 0, 3e-10)) is not
  // physical: it runs with the nearest physical one, and strict_inertia refuses it
  auto moving = loadModelString(arm(moving_pad), "robot.urdf");
  EXPECT_TRUE(hasNote(*moving, "body 'pad': its inertia violates the triangle inequality (a principal moment exceeds the "
                               "sum of the other two); principal moments ("));
  EXPECT_TRUE(hasNote(*moving, "3e-10) -> (1e-10, 1e-10, 2e-10) kg m^2, the nearest physical inertia"));
  LoadOptions strict;
  strict.strict_inertia = true;
  const std::string e = loadError(arm(moving_pad), strict);
  EXPECT_NE(e.find("robot.urdf:"), std::string::npos) << e;
  EXPECT_NE(e.find("the rigid body of link 'pad'"), std::string::npos) << e;
  EXPECT_NE(e.find("fix the <inertia> of link 'pad'"), std::string::npos) << e;
}

// A frame link of mass 0 with inertia 0.1 fixed to the lower link (a hand's frame, as in
// franka_panda) carries no inertia: the arm moves exactly as without it (MuJoCo's choice).
TEST(RealFiles, AMassZeroLinkCarriesNoInertia) {
  const std::string frame = R"(<link name="frame"><inertial><mass value="0"/>
    <inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="frame_fix" type="fixed"><parent link="lower"/><child link="frame"/><origin xyz="0 0 -0.5"/></joint>
)";
  LoadOptions o;
  o.positions = {{"shoulder", 0.7}};
  auto with = loadModelString(arm(frame), "robot.urdf", o), without = loadModelString(arm(), "robot.urdf", o);
  EXPECT_TRUE(hasNote(*with, "links of mass 0 with a non-zero inertia: 'frame': their inertia is dropped"));
  for (int i = 0; i < 1000; ++i) with->step(1e-3), without->step(1e-3);
  EXPECT_GT(std::fabs(without->position(without->dofIndex("elbow"))), 1e-2);  // it moved
  for (const char* dof : {"shoulder", "elbow"})
    EXPECT_EQ(with->position(with->dofIndex(dof)), without->position(without->dofIndex(dof))) << dof;
}

// urdfdom's own refusals say why (captured from console_bridge instead of discarded): a
// <safety_controller> (which the loader does not read) without k_velocity.
TEST(RealFiles, UrdfdomRefusalsSayWhy) {
  const std::string e = loadError(arm(R"(<link name="hand"><inertial><mass value="0.1"/>
    <inertia ixx="1e-4" iyy="1e-4" izz="1e-4" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="wrist" type="continuous"><parent link="lower"/><child link="hand"/><axis xyz="0 0 1"/>
    <safety_controller soft_lower_limit="-1"/></joint>
)"));
  EXPECT_EQ(e.find("robot.urdf: urdfdom could not parse the robot description: "), 0u) << e;
  EXPECT_EQ(e.find('\n'), std::string::npos) << e;
  EXPECT_GT(e.size(), std::string("robot.urdf: urdfdom could not parse the robot description: ").size() + 5) << e;
}

// A <limit> without effort or velocity (URDF requires both) is refused at its line.
TEST(RealFiles, ALimitWithoutEffortIsRefusedAtItsLine) {
  const std::string e = loadError(arm("", "lower=\"-1\" upper=\"1\" velocity=\"1\""));
  EXPECT_NE(e.find("robot.urdf:10: "), std::string::npos) << e;
  EXPECT_NE(e.find("missing attribute 'effort'"), std::string::npos) << e;
}

// The bounds of a <limit> on a fixed or a continuous joint are not read: reversed ones load
// (a fixed joint of Omnid's spring.urdf has lower="1000" upper="-1000"); on a revolute
// joint they are refused at the <limit>'s line.
TEST(RealFiles, ReversedBoundsOfAFixedOrContinuousJointAreNotRead) {
  const std::string reversed = "lower=\"1000\" upper=\"-1000\" effort=\"10\" velocity=\"5\"";
  auto tool = [&](const std::string& type) {
    return R"(<link name="tool"><inertial><mass value="0.1"/>
    <inertia ixx="1e-4" iyy="1e-4" izz="1e-4" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="mount" type=")" + type + R"("><parent link="lower"/><child link="tool"/><origin xyz="0 0 -0.5"/>
    <axis xyz="0 0 1"/><limit )" + reversed + R"(/></joint>
)";
  };
  EXPECT_EQ(loadError(arm(tool("fixed"))), "(loaded)");
  EXPECT_EQ(loadError(arm(tool("continuous"))), "(loaded)");
  const std::string e = loadError(arm(tool("revolute")));
  EXPECT_NE(e.find("robot.urdf:14: "), std::string::npos) << e;
  EXPECT_NE(e.find("lower limit exceeds upper limit"), std::string::npos) << e;
}

// A step that fails names the file and the time, in one line.
TEST(RealFiles, AFailedStepNamesTheFileAndTheTime) {
  LoadOptions o;
  o.velocities = {{"elbow", 1e5}};
  // (absolute coordinates: a body turning 100 rad a step fails the step there; in joint
  // coordinates, auto's choice, the angle is a coordinate and the arm simply turns)
  o.formulation = "absolute";
  auto m = loadModelString(arm("", "lower=\"-100000\" upper=\"100000\" effort=\"10\" velocity=\"5\""), "robot.urdf", o);
  try {
    for (int i = 0; i < 10; ++i) m->step(1e-3);
    FAIL() << "a link turning 100 rad a step was stepped";
  } catch (const SimulationError& e) {
    const std::string what = e.what();
    EXPECT_EQ(what.find("robot.urdf: at t = 0 s: "), 0u) << what;
    EXPECT_EQ(what.find('\n'), std::string::npos) << what;
  }
}

// A file with a second root link (a loose part beside the arm): the root with the most
// links below it is the model's root, the other floats: under gravity alone it falls as
// a free body, z(t) = z0 - g t^2 / 2, with a note naming it.
TEST(RealFiles, AnExtraRootLinkFloats) {
  const std::string loose = R"(<link name="loose"><inertial><origin xyz="0.3 0 0"/><mass value="0.5"/>
    <inertia ixx="1e-3" iyy="1e-3" izz="1e-3" ixy="0" ixz="0" iyz="0"/></inertial></link>
)";
  auto m = loadModelString(arm(loose), "robot.urdf");
  EXPECT_TRUE(hasNote(*m, "several root links: 'base' is the model's root; 'loose' (joint 'loose_floating') float"));
  const int loose_link = m->linkIndex("loose");
  ASSERT_GE(loose_link, 0);
  const Eigen::Vector3d p0 = m->linkPose(loose_link).translation();
  for (int i = 0; i < 1000; ++i) m->step(1e-3);
  const Eigen::Vector3d p1 = m->linkPose(loose_link).translation();
  EXPECT_NEAR(p1.z() - p0.z(), -0.5 * 9.81 * 1.0, 1e-9);
  EXPECT_NEAR((p1 - p0).head<2>().norm(), 0.0, 1e-12);
}

// What a file holds that is read but not simulated is listed once.
TEST(RealFiles, ElementsReadButNotSimulatedAreListed) {
  // (transmissions of the types doc/actuators.md lists are simulated; others are listed)
  const std::string extra = R"(<transmission name="t1"><type>sr_mechanism_model/SimpleTransmission</type></transmission>
  <transmission name="t2"><type>sr_mechanism_model/SimpleTransmission</type></transmission>
  <gazebo><plugin name="control" filename="libgazebo_ros_control.so"/></gazebo>
)";
  auto m = loadModelString(arm(extra), "robot.urdf");
  EXPECT_TRUE(hasNote(*m, "ignored (read, not simulated): 1 <gazebo> plugin, 2 <transmission> of type "
                          "sr_mechanism_model/SimpleTransmission"))
      << m->notes().size();
  auto plain = loadModelString(arm(), "robot.urdf");
  EXPECT_TRUE(plain->notes().empty());
}

}  // namespace
}  // namespace mechanism_sim
