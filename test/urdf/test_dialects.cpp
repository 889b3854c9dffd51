// Loop closures in the dialects of other tools (doc/loop_dialects.md): one four-bar written
// in every dialect loads with its closure's equations and moves as the extension's; a loop
// open at the file's zero pose is assembled and reported; each dialect's bad input fails
// with its exact error (test/dialects/invalid/expected.txt).
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include <urdf_parser/urdf_parser.h>

#include "mechanism_sim/urdf/model.h"

namespace mechanism_sim {
namespace {

const std::string kDir = std::string(MECHANISM_SIM_SOURCE_DIR) + "/test/dialects";
const int kTreeEquations = 15;  // the four-bar's three tree hinges, 5 equations each

std::string readText(const std::string& path) {
  std::ifstream in(path);
  EXPECT_TRUE(in) << path;
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// text with `from` (which must occur once) replaced by `to`.
std::string replaced(std::string text, const std::string& from, const std::string& to) {
  const size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  EXPECT_EQ(text.find(from, at + 1), std::string::npos) << from;
  return at == std::string::npos ? text : text.replace(at, from.size(), to);
}

std::vector<double> positionsAfter(MechanismModel& m, double seconds, double h = 1e-3) {
  for (long s = 0; s < std::lround(seconds / h); ++s) {
    m.step(h);
    const double violation = m.mechanism().positionViolation();
    EXPECT_LE(violation, 1e-10) << m.name() << " t = " << m.time();
    if (!(violation <= 1e-10)) break;
  }
  std::vector<double> q;
  for (const char* dof : {"crank_joint", "coupler_joint", "rocker_joint"}) q.push_back(m.position(m.dofIndex(dof)));
  return q;
}

struct Dialect {
  std::string file;
  int closure_equations;  // 5: a hinge, 3: a ball
};

const std::vector<Dialect> kDialects = {
    {"four_bar_mechanism_sim.urdf", 5}, {"four_bar_gazebo.urdf", 5}, {"four_bar_dojo.urdf", 5},
    {"four_bar_urdfplus.urdf", 5},      {"four_bar_constraint.urdf", 5}, {"four_bar_drake.urdf", 3},
    {"four_bar_onshape.urdf", 3},       {"four_bar_extended.urdf", 3}};

// A closure not read would leave the tree's 15 equations: the mechanism run open.
TEST(Dialects, EachLoadsWithItsClosureEquations) {
  for (const Dialect& d : kDialects) {
    auto m = loadModelFile(kDir + "/" + d.file);
    EXPECT_EQ(m->numEquations(), kTreeEquations + d.closure_equations) << d.file;
    EXPECT_EQ(m->loopJoints().size(), 1u) << d.file;
    EXPECT_LE(m->assembly().position_residual, 1e-12) << d.file;
    for (const std::string& note : m->notes())  // each closes at its zero pose
      EXPECT_EQ(note.find("assembly moved"), std::string::npos) << d.file << ": " << note;
  }
}

// The same four-bar, whichever way its loop is written (a hinge, or a ball whose third
// equation the hinges make dependent), moves the same: after 2 s of falling the joint
// positions agree with the extension's within 1e-12.
TEST(Dialects, TheSameFourBarMovesIdenticallyInEveryDialect) {
  auto reference = loadModelFile(kDir + "/four_bar_mechanism_sim.urdf");
  const std::vector<double> q_ref = positionsAfter(*reference, 2.0);
  ASSERT_GT(std::fabs(q_ref[0]), 0.1) << "the four-bar should have moved";
  for (const Dialect& d : kDialects) {
    auto m = loadModelFile(kDir + "/" + d.file);
    const std::vector<double> q = positionsAfter(*m, 2.0);
    for (size_t k = 0; k < q.size(); ++k) EXPECT_NEAR(q[k], q_ref[k], 1e-12) << d.file << " dof " << k;
  }
}

// Dojo's child side: its rotation is the one that makes the two frames coincide at the
// zero pose, and link2's rpy is ignored. The same four-bar with the rocker's link frame
// turned 90 degrees about z (its hinge axis then x, its pin at (0, -0.12, 0.46)) and a
// wrong rpy on link2 moves as the straight one; with the child's rotation taken from
// link2's rpy or left at identity, the hinge on the rocker side would lie along -x
// instead of y.
TEST(Dialects, DojoTakesTheChildRotationFromTheZeroPose) {
  const std::string xml = readText(kDir + "/four_bar_dojo.urdf");
  std::string turned = replaced(xml, "<origin xyz=\"0.4 0 0\"/>\n    <axis xyz=\"0 1 0\"/>",
                                "<origin xyz=\"0.4 0 0\" rpy=\"0 0 1.5707963267948966\"/>\n    <axis xyz=\"1 0 0\"/>");
  turned = replaced(turned, "<origin xyz=\"0.06 0 0.23\"/>", "<origin xyz=\"0 -0.06 0.23\"/>");
  turned = replaced(turned, R"(xyz="0.12 0 0.46" rpy="0 0 0")", R"(xyz="0 -0.12 0.46" rpy="0.7 0.2 0.1")");
  auto straight = loadModelString(xml, "dojo");
  auto rotated = loadModelString(turned, "dojo turned");
  EXPECT_EQ(rotated->numEquations(), kTreeEquations + 5);
  for (const std::string& note : rotated->notes()) ADD_FAILURE() << note;
  const std::vector<double> a = positionsAfter(*straight, 1.0), b = positionsAfter(*rotated, 1.0);
  for (size_t k = 0; k < a.size(); ++k) EXPECT_NEAR(a[k], b[k], 1e-12) << k;
}

// The rocker's zero pose turned 0.5 rad leaves the loop 0.23 m open at zero: the loader
// assembles it and says which dofs moved, from where to where.
TEST(Dialects, ALoopOpenAtTheZeroPoseIsAssembledAndReported) {
  auto m = loadModelFile(kDir + "/four_bar_dojo_open.urdf");
  EXPECT_LE(m->relativePositionViolation(), 1e-12);
  ASSERT_EQ(m->notes().size(), 1u);
  const std::string& note = m->notes()[0];
  EXPECT_EQ(note.rfind("assembly moved ", 0), 0u) << note;
  int named = 0;
  for (const char* dof : {"crank_joint 0 -> ", "coupler_joint 0 -> ", "rocker_joint 0 -> "})
    named += note.find(dof) != std::string::npos;
  EXPECT_GE(named, 2) << note;
  // and it runs closed
  positionsAfter(*m, 1.0);
}

// URDF+ <coupling>: the successor's rate is ratio times the predecessor's, exactly.
TEST(Dialects, UrdfPlusCouplingHoldsItsRatio) {
  auto m = loadModelFile(kDir + "/urdfplus_coupling.urdf");
  EXPECT_EQ(m->numEquations(), 5 + 5 + 1);
  const int arm = m->dofIndex("arm_joint"), rotor = m->dofIndex("rotor_joint");
  for (int s = 0; s < 1000; ++s) m->step(1e-3);
  EXPECT_GT(std::fabs(m->position(arm)), 0.1);
  EXPECT_NEAR(m->position(rotor), 3.0 * m->position(arm), 1e-10);
  EXPECT_NEAR(m->velocity(rotor), 3.0 * m->velocity(arm), 1e-9);
}

// "Extended URDF": the YAML beside the file is read by loadModelFile, or given by
// LoadOptions::closures_file; loadModelString looks for none. name_mot is reported.
TEST(Dialects, ExtendedUrdfClosuresFile) {
  const std::string urdf = kDir + "/four_bar_extended.urdf", yaml = kDir + "/four_bar_extended.yaml";
  auto beside = loadModelFile(urdf);
  EXPECT_EQ(beside->numEquations(), kTreeEquations + 3);
  ASSERT_EQ(beside->notes().size(), 1u);
  EXPECT_NE(beside->notes()[0].find("actuated joints (name_mot in " + yaml + "): crank_joint; every other dof is passive"),
            std::string::npos)
      << beside->notes()[0];
  const std::string xml = readText(urdf);
  EXPECT_EQ(loadModelString(xml, "string")->numEquations(), kTreeEquations);
  LoadOptions with;
  with.closures_file = yaml;
  EXPECT_EQ(loadModelString(xml, "string", with)->numEquations(), kTreeEquations + 3);
  // 6d: the frames coincide (fixed): the four-bar is locked, with 6 equations more
  std::ofstream six(testing::TempDir() + "/closures_6d.yaml");
  six << "closed_loop: [[pin_on_coupler, pin_on_rocker]]\ntype: [6d]\n";
  six.close();
  with.closures_file = testing::TempDir() + "/closures_6d.yaml";
  EXPECT_EQ(loadModelString(xml, "string", with)->numEquations(), kTreeEquations + 6);
}

// Extended-URDF frames are Pinocchio's: a fixed joint's name is its frame (the child
// link's), and so is a moving joint's, turning with the joint. The four-bar's coupler pin
// welded (6d) to the frame of the hinge closedloop_A on the rocker moves as the same file
// naming the links (pin_on_coupler, rocker_tip); were the hinge's frame taken on its parent
// side (the rocker), the weld would lock the four-bar still.
TEST(Dialects, ExtendedUrdfFramesArePinocchioFrames) {
  const std::string urdf = kDir + "/four_bar_extended_frames.urdf";
  auto joints = loadModelFile(urdf);
  EXPECT_EQ(joints->numEquations(), 4 * 5 + 6);
  ASSERT_EQ(joints->loopJoints().size(), 1u);
  EXPECT_EQ(joints->loopJoints()[0].name, "pin_on_coupler_frame-closedloop_A");
  std::ofstream links(testing::TempDir() + "/closures_links.yaml");
  links << "closed_loop: [[pin_on_coupler, rocker_tip]]\ntype: [6d]\nname_mot: [crank_joint]\n";
  links.close();
  LoadOptions with;
  with.closures_file = testing::TempDir() + "/closures_links.yaml";
  auto by_links = loadModelFile(urdf, with);
  const std::vector<double> a = positionsAfter(*joints, 2.0), b = positionsAfter(*by_links, 2.0);
  EXPECT_GT(std::fabs(a[0]), 0.1) << "the four-bar should move";
  for (size_t k = 0; k < a.size(); ++k) EXPECT_NEAR(a[k], b[k], 1e-12) << k;
  // "universe" is the world: the root link
  std::ofstream world(testing::TempDir() + "/closures_universe.yaml");
  world << "closed_loop: [[universe, crank_joint]]\ntype: [3d]\n";
  world.close();
  with.closures_file = testing::TempDir() + "/closures_universe.yaml";
  auto m = loadModelFile(urdf, with);
  ASSERT_EQ(m->loopJoints().size(), 1u);
  EXPECT_EQ(m->links()[m->loopJoints()[0].parent_link].name, "ground");
  EXPECT_EQ(m->links()[m->loopJoints()[0].child_link].name, "crank");
}

// joint_name/joint_type: CARDAN is the reference loader's JointModelRX then JointModelRY at
// the joint's origin (a universal joint, axes x then y of that frame), SPHERICAL a ball,
// FIXED the joint locked at zero. The four-bar with its coupler joint made a cardan and its
// loop a ball moves in its plane as the hinged one (the cardan's x turn stays zero).
TEST(Dialects, ExtendedUrdfJointTypes) {
  const std::string xml = readText(kDir + "/four_bar_extended.urdf");
  auto yaml = [&](const std::string& text) {
    const std::string path = testing::TempDir() + "/closures_types.yaml";
    std::ofstream(path) << text;
    LoadOptions with;
    with.closures_file = path;
    return loadModelString(xml, "four_bar_extended", with);
  };
  const std::string loop = "closed_loop: [[pin_on_coupler, pin_on_rocker]]\ntype: [3d]\n";
  auto cardan = yaml(loop + "joint_name: [coupler_joint]\njoint_type: [CARDAN]\n");
  EXPECT_EQ(cardan->numEquations(), 10 + 4 + 3);
  const int x = cardan->dofIndex("coupler_joint.axis1"), y = cardan->dofIndex("coupler_joint.axis2");
  ASSERT_GE(x, 0);
  ASSERT_GE(y, 0);
  auto reference = loadModelFile(kDir + "/four_bar_mechanism_sim.urdf");
  for (int s = 0; s < 1000; ++s) cardan->step(1e-3), reference->step(1e-3);
  EXPECT_GT(std::fabs(reference->position(reference->dofIndex("crank_joint"))), 0.1);
  for (const char* dof : {"crank_joint", "rocker_joint"})
    EXPECT_NEAR(cardan->position(cardan->dofIndex(dof)), reference->position(reference->dofIndex(dof)), 1e-9) << dof;
  EXPECT_NEAR(cardan->position(y), reference->position(reference->dofIndex("coupler_joint")), 1e-9);
  EXPECT_NEAR(cardan->position(x), 0.0, 1e-9);
  // UJOINT_AB (later versions): RA then RB; UJOINT_ZY turns about the joint origin's z
  // first, so its second axis y is the hinge: the same planar motion, the z turn zero
  auto zy = yaml(loop + "joint_name: [coupler_joint]\njoint_type: [UJOINT_ZY]\n");
  for (int s = 0; s < 1000; ++s) zy->step(1e-3);
  EXPECT_NEAR(zy->position(zy->dofIndex("coupler_joint.axis2")), cardan->position(y), 1e-9);
  EXPECT_NEAR(zy->position(zy->dofIndex("coupler_joint.axis1")), 0.0, 1e-9);
  EXPECT_EQ(yaml(loop + "joint_name: [coupler_joint]\njoint_type: [SPHERICAL]\n")->numEquations(), 10 + 3 + 3);
  // a name that is no joint is passed over, as the reference does, with a note
  auto ghost = yaml(loop + "joint_name: [ghost_joint]\njoint_type: [SPHERICAL]\n");
  EXPECT_EQ(ghost->numEquations(), kTreeEquations + 3);
  bool noted = false;
  for (const std::string& n : ghost->notes()) noted = noted || n.find("joint_name 'ghost_joint' names no joint of the URDF: ignored") != std::string::npos;
  EXPECT_TRUE(noted);
  // FIXED merges crank and coupler into one body: the loop is then a rigid triangle
  EXPECT_EQ(yaml(loop + "joint_name: [coupler_joint]\njoint_type: [FIXED]\n")->numEquations(), 10 + 3);
}

// name_mot: the actuated joints; every other dof (loop closures too) is passive, as the
// reference loader's ActuationModel has it: a passive dof takes no effort command and no
// drive, an actuated one both.
TEST(Dialects, ExtendedUrdfNameMotMakesTheOthersPassive) {
  const std::string urdf = kDir + "/four_bar_extended.urdf";
  auto m = loadModelFile(urdf);
  for (const Dof& d : m->dofs()) EXPECT_EQ(d.actuated, d.name == "crank_joint") << d.name;
  EXPECT_THROW(m->setEffort(m->dofIndex("rocker_joint"), 1.0), UsageError);
  EXPECT_THROW(m->driveDof(m->dofIndex("rocker_joint")), UsageError);  // a trajectory's or ~position_command's drive
  m->setEffort(m->dofIndex("crank_joint"), 1.0);
  EXPECT_EQ(m->commandedEffort(m->dofIndex("crank_joint")), 1.0);
  LoadOptions drive;
  drive.drives = {{"crank_joint", 1.0}};
  auto driven = loadModelFile(urdf, drive);
  for (int s = 0; s < 500; ++s) driven->step(1e-3);
  EXPECT_NEAR(driven->position(driven->dofIndex("crank_joint")), 0.5, 1e-12);
  drive.drives = {{"rocker_joint", 1.0}};
  try {
    loadModelFile(urdf, drive);
    ADD_FAILURE() << "a passive dof was driven";
  } catch (const LoadError& e) {
    EXPECT_NE(std::string(e.what()).find("dof 'rocker_joint' is passive: only the actuated joints (name_mot in"),
              std::string::npos)
        << e.what();
  }
  // without name_mot every dof is actuated
  const auto all = loadModelFile(kDir + "/four_bar_mechanism_sim.urdf");
  for (const Dof& d : all->dofs()) EXPECT_TRUE(d.actuated) << d.name;
}

// onshape-to-robot 1.x writes a REVOLUTE closing mate as two frame pairs on the hinge axis,
// closing_pin_1/_2 and closing_pin_1_z/_2_z (its MuJoCo export: two <connect>s): two balls,
// 6 equations of which one is dependent, the hinge. The four-bar moves as the hinged one.
TEST(Dialects, OnshapeRevoluteClosingMateIsTwoBallsOnTheAxis) {
  auto m = loadModelFile(kDir + "/four_bar_onshape_hinge.urdf");
  EXPECT_EQ(m->numEquations(), kTreeEquations + 6);
  ASSERT_EQ(m->loopJoints().size(), 2u);
  EXPECT_EQ(m->loopJoints()[0].name, "closing_pin");
  EXPECT_EQ(m->loopJoints()[1].name, "closing_pin_z");
  auto reference = loadModelFile(kDir + "/four_bar_mechanism_sim.urdf");
  const std::vector<double> q_ref = positionsAfter(*reference, 2.0), q = positionsAfter(*m, 2.0);
  for (size_t k = 0; k < q.size(); ++k) EXPECT_NEAR(q[k], q_ref[k], 1e-12) << k;
}

// A gripper closed in <gazebo> blocks as PR2's: the SDF parallel links are bodies (with
// their SDF inertials and poses), the SDF hinges make each finger a parallelogram and the
// SDF prismatic joint ties the tips, so driving the left finger opens both symmetrically
// with the tips parallel; the SDF screw advances its nut by the lead per turn.
TEST(Dialects, GazeboSdfLinksAndJointsCloseAPr2LikeGripper) {
  const std::string path = kDir + "/pr2_like_gripper.urdf";
  LoadOptions drive;
  const double w_finger = 0.3, w_screw = 2.0 * M_PI, t = 1.0, lead = 0.004;
  drive.drives = {{"l_finger_joint", w_finger}, {"motor_screw_joint", w_screw}};
  auto m = loadModelFile(path, drive);
  EXPECT_EQ(m->loopJoints().size(), 6u);
  EXPECT_EQ(m->numMovingBodies(), 8);  // 6 URDF links and the 2 SDF parallel links
  ASSERT_GE(m->linkIndex("l_parallel_link"), 0);
  bool noted = false;
  for (const std::string& n : m->notes()) noted = noted || n.find("SDF links of <gazebo> blocks are bodies") != std::string::npos;
  EXPECT_TRUE(noted);
  EXPECT_LE(m->assembly().position_residual, 1e-12);
  // the SDF link sits where its <pose> puts it (the model frame: the root link's)
  EXPECT_LE((m->linkPose(m->linkIndex("l_parallel_link")).translation() - Eigen::Vector3d(0.06, 0.03, 0)).norm(), 1e-12);
  for (long s = 0; s < std::lround(t / 1e-3); ++s) m->step(1e-3);
  const double th = w_finger * t;
  auto q = [&](const char* dof) { return m->position(m->dofIndex(dof)); };
  EXPECT_NEAR(q("l_finger_joint"), th, 1e-12);
  EXPECT_NEAR(q("r_finger_joint"), th, 1e-9);
  EXPECT_NEAR(q("l_finger_tip_joint"), th, 1e-9);  // the tip keeps its orientation
  EXPECT_NEAR(q("r_finger_tip_joint"), th, 1e-9);
  // the tips' gap along y: 2 (0.09 sin th + 0.005 (cos th - 1)) wider than at zero
  EXPECT_NEAR(q("gripper_joint"), 2.0 * (0.09 * std::sin(th) + 0.005 * (std::cos(th) - 1.0)), 1e-9);
  // the parallel link turns with the finger
  const Eigen::Matrix3d R = m->linkPose(m->linkIndex("l_parallel_link")).linear();
  EXPECT_NEAR(std::atan2(R(1, 0), R(0, 0)), th, 1e-9);
  // a right-handed screw turned +phi with its nut held from turning: the nut moves back
  // lead phi / (2 pi) (one turn here: 4 mm)
  EXPECT_NEAR(q("motor_screw_joint"), w_screw * t, 1e-12);
  EXPECT_NEAR(q("motor_slider_joint"), -lead * w_screw * t / (2 * M_PI), 1e-12);
  // Gazebo classic's thread_pitch (radians per metre, positive left-handed; SDF 1.11 joint.sdf:
  // thread_pitch = -2 pi / screw_thread_pitch) moves it the same
  const std::string xml = replaced(readText(path), "<screw_thread_pitch>0.004</screw_thread_pitch>",
                                   "<thread_pitch>-1570.7963267948966</thread_pitch>");
  auto classic = loadModelString(xml, "classic", drive);
  for (long s = 0; s < std::lround(t / 1e-3); ++s) classic->step(1e-3);
  EXPECT_NEAR(classic->position(classic->dofIndex("motor_slider_joint")), -lead, 1e-12);
}

// Every SDF joint type a <gazebo> block may close a loop with, by its equations: the
// four-bar's closure as revolute 5, prismatic 5, screw 5, universal 4, ball 3, fixed 6,
// continuous 5; SDF's pose relative_to and axis expressed_in; "world" as the parent is the
// root link; revolute2 is refused with its fix.
TEST(Dialects, GazeboSdfJointTypes) {
  const std::string xml = readText(kDir + "/four_bar_gazebo.urdf");
  const std::string hinge = R"(<joint name="closure" type="revolute">)";
  auto equations = [&](const std::string& type, const std::string& extra) {
    std::string x = replaced(xml, hinge, "<joint name=\"closure\" type=\"" + type + "\">" + extra);
    return loadModelString(x, type)->numEquations() - kTreeEquations;
  };
  EXPECT_EQ(equations("prismatic", ""), 5);
  EXPECT_EQ(equations("screw", "<thread_pitch>100</thread_pitch>"), 5);
  // no pitch: SDF's default thread_pitch 1 (Gazebo classic's, with a warning), noted
  auto no_pitch = loadModelString(replaced(xml, hinge, R"(<joint name="closure" type="screw">)"), "no pitch");
  bool noted = false;
  for (const std::string& n : no_pitch->notes()) noted = noted || n.find("SDF's default thread_pitch 1") != std::string::npos;
  EXPECT_TRUE(noted);
  EXPECT_EQ(equations("universal", "<axis2><xyz>1 0 0</xyz></axis2>"), 4);
  EXPECT_EQ(equations("ball", ""), 3);
  EXPECT_EQ(equations("fixed", ""), 6);
  EXPECT_EQ(equations("continuous", ""), 5);
  // SDF 1.7+ frames: the joint pose relative_to the parent link, the axis expressed_in a
  // link while the joint frame is turned 90 degrees about x: the same hinge, the same motion
  const std::string pose = "<pose>0.12 0 0.46 0 0 0</pose>";
  auto reference = loadModelString(xml, "reference");
  auto relative = loadModelString(replaced(xml, pose, R"(<pose relative_to="coupler">0.4 0 0.3 0 0 0</pose>)"), "relative_to");
  auto expressed = loadModelString(
      replaced(replaced(xml, pose, "<pose>0.12 0 0.46 1.5707963267948966 0 0</pose>"), "<xyz>0 1 0</xyz>",
               R"(<xyz expressed_in="rocker">0 1 0</xyz>)"),
      "expressed_in");
  const std::vector<double> q_ref = positionsAfter(*reference, 1.0), q_rel = positionsAfter(*relative, 1.0),
                            q_exp = positionsAfter(*expressed, 1.0);
  for (size_t k = 0; k < q_ref.size(); ++k) {
    EXPECT_NEAR(q_rel[k], q_ref[k], 1e-12) << k;
    EXPECT_NEAR(q_exp[k], q_ref[k], 1e-12) << k;
  }
  try {
    loadModelString(replaced(xml, hinge, R"(<joint name="closure" type="revolute2">)"), "revolute2");
    ADD_FAILURE() << "revolute2 loaded";
  } catch (const LoadError& e) {
    EXPECT_NE(std::string(e.what()).find("unsupported SDF joint type 'revolute2': write it as a universal joint"),
              std::string::npos)
        << e.what();
  }
  // <parent>world</parent>: the rocker pinned to the world at its pin: the loop is then
  // closed on the ground instead of the coupler (a locked four-bar stays locked)
  std::string world = replaced(xml, "<parent>coupler</parent>", "<parent>world</parent>");
  auto m = loadModelString(world, "world");
  EXPECT_EQ(m->links()[m->loopJoints()[0].parent_link].name, "ground");
}

// urdfdom <constraint>: each type's equations (a revolute's 5 were checked above).
TEST(Dialects, UrdfdomConstraintTypes) {
  const std::string xml = readText(kDir + "/four_bar_constraint.urdf");
  const std::string axes = "    <parent_axis xyz=\"0 1 0\"/>\n";
  const std::string child_axis = "    <child_axis xyz=\"0 1 0\"/>\n";
  const std::string no_axes = replaced(replaced(xml, axes, ""), child_axis, "");
  EXPECT_EQ(loadModelString(replaced(no_axes, R"(type="revolute")", R"(type="spherical")"), "spherical")->numEquations(),
            kTreeEquations + 3);
  // universal: the hinge axis y on the coupler, the second axis x on the rocker
  const std::string universal =
      replaced(replaced(xml, R"(type="revolute")", R"(type="universal")"), child_axis, "    <child_axis xyz=\"1 0 0\"/>\n");
  auto u = loadModelString(universal, "universal");
  EXPECT_EQ(u->numEquations(), kTreeEquations + 4);
  EXPECT_TRUE(u->notes().empty());
}

// PR2's gripper_v0: an SDF joint of a <gazebo> block named as a URDF joint is a second
// joint, as in Gazebo classic: the URDF joint keeps its name and the closure is 'g (gazebo)'.
// The closure makes the two tips fall as one body (0.5 kg) against the right tip's damping
// c = 2 N s/m: z(t) = -(M g / c) (t - (M / c)(1 - exp(-c t / M))), where the right tip alone
// would fall slower and the left one freely.
TEST(Dialects, GazeboJointNamedAsAUrdfJointIsALoopClosureBesideIt) {
  auto m = loadModelFile(kDir + "/gazebo_joint_named_as_urdf_joint.urdf");
  ASSERT_EQ(m->loopJoints().size(), 1u);
  EXPECT_EQ(m->loopJoints()[0].name, "g (gazebo)");
  EXPECT_GE(m->dofIndex("g"), 0);
  EXPECT_GE(m->dofIndex("g (gazebo)"), 0);
  EXPECT_NE(m->dofIndex("g"), m->dofIndex("g (gazebo)"));
  bool noted = false;
  for (const std::string& note : m->notes()) noted = noted || note.find("'g (gazebo)'") != std::string::npos;
  EXPECT_TRUE(noted);
  const double M = 0.5, c = 2.0, g = 9.81, t = 1.0;
  const double h = 1e-3;
  for (int s = 0; s < 1000; ++s) m->step(h);
  const double z = -(M * g / c) * (t - (M / c) * (1.0 - std::exp(-c * t / M)));
  EXPECT_NEAR(m->position(m->dofIndex("tip_r_joint")), z, 1e-3 * std::fabs(z));
  EXPECT_NEAR(m->position(m->dofIndex("tip_l_joint")), z, 1e-3 * std::fabs(z));
  EXPECT_NEAR(m->position(m->dofIndex("g")), 0.0, 1e-12);  // the URDF gap joint: nothing moves it
}

// Drake's 'world' (strandbeest): a link welded to an undeclared 'world' is fixed to ground,
// and the four-bar moves as the one whose frame link is the root (1 m up and turned 0.7 rad
// about the vertical, which gravity does not see), written either way round.
TEST(Dialects, DrakeWorldIsGroundWithoutALink) {
  auto reference = loadModelFile(kDir + "/four_bar_drake.urdf");
  const std::vector<double> q_ref = positionsAfter(*reference, 2.0);
  ASSERT_GT(std::fabs(q_ref[0]), 0.1) << "the four-bar should have moved";
  for (const char* file : {"four_bar_drake_world.urdf", "four_bar_drake_world_reversed.urdf"}) {
    auto m = loadModelFile(kDir + "/" + file);
    EXPECT_EQ(m->rootLink(), "world") << file;
    EXPECT_EQ(m->loopJoints().size(), 1u) << file;
    EXPECT_EQ(m->numEquations(), kTreeEquations + 3) << file;
    bool noted = false;
    for (const std::string& note : m->notes()) noted = noted || note.find("Drake") != std::string::npos;
    EXPECT_TRUE(noted) << file;
    const Eigen::Isometry3d base = m->linkPose(m->linkIndex("base"));
    EXPECT_NEAR((base.translation() - Eigen::Vector3d(0, 0, 1)).norm(), 0.0, 1e-12) << file;
    const Eigen::Matrix3d turned = Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    EXPECT_NEAR((base.linear() - turned).norm(), 0.0, 1e-12) << file;
    const std::vector<double> q = positionsAfter(*m, 2.0);
    for (size_t k = 0; k < q.size(); ++k) EXPECT_NEAR(q[k], q_ref[k], 1e-9) << file << " dof " << k;
    EXPECT_NEAR((m->linkPose(m->linkIndex("base")).translation() - Eigen::Vector3d(0, 0, 1)).norm(), 0.0, 1e-12);
  }
}

// A Jansen-linkage walker shaped like Drake's strandbeest: twelve legs closed by ball
// constraints, each leg joint limited to +- 0.5 rad about its closed angle with the zero
// pose outside the limits. From the file's pose the bound-constrained least squares stops
// with some legs folded the other way; the legs left open start again from angles drawn
// within their limits (closed legs kept) and every leg closes within its limits.
TEST(Dialects, LegsLimitedAwayFromTheirZeroPoseAssembleWithinTheLimits) {
  const std::string file = kDir + "/jansen_walker_drake.urdf";
  auto m = loadModelFile(file);
  EXPECT_LT(m->relativePositionViolation(), 1e-12);
  // (urdfdom wants Drake's undeclared 'world' declared: the limits are read with it added)
  const urdf::ModelInterfaceSharedPtr urdf =
      urdf::parseURDF(replaced(readText(file), "<link name=\"frame\">", "<link name=\"world\"/><link name=\"frame\">"));
  ASSERT_TRUE(urdf);
  int limited = 0;
  for (const auto& entry : urdf->joints_) {
    const urdf::Joint& j = *entry.second;
    if (j.type != urdf::Joint::REVOLUTE) continue;
    ++limited;
    const int dof = m->dofIndex(j.name);
    ASSERT_GE(dof, 0) << j.name;
    const double q = m->position(dof);
    EXPECT_GE(q, j.limits->lower - 1e-9) << j.name;
    EXPECT_LE(q, j.limits->upper + 1e-9) << j.name;
  }
  EXPECT_EQ(limited, 60);
  // the legs stay closed as the walker runs
  for (int s = 0; s < 50; ++s) m->step(1e-3);
  EXPECT_LT(m->relativePositionViolation(), 1e-10);
}

// One file per dialect and per way it can be wrong, each with its exact one-line error
// naming the file (the URDF, or its YAML closures file) and line.
// A ball written as three revolute joints through links without mass (an X-Y-X gimbal at
// its lock in the zero pose) moves as the same rod on a spherical joint, in both
// formulations, and as a ball does: an axisymmetric rod hung by its axis keeps its spin
// about that axis (Euler's equations with I1 = I2 and gravity's moment across the axis) and
// its energy. Started spinning about the vertical, the direction the locked gimbal as written
// cannot turn in.
TEST(Dialects, BallWrittenAsAGimbalOfMasslessLinksMovesAsABall) {
  for (const char* formulation : {"joint", "absolute"}) {
    SCOPED_TRACE(formulation);
    LoadOptions o;
    o.formulation = formulation;
    o.velocities = {{"ball.x", 2.0}, {"ball.z", 3.0}};
    auto gimbal = loadModelFile(kDir + "/ball_as_gimbal.urdf", o);
    auto ball = loadModelFile(kDir + "/ball_as_spherical.urdf", o);
    // reported by the file's three joints (the next test checks their values)
    for (const char* j : {"ball", "ball_y", "ball_x"}) EXPECT_GE(gimbal->dofs().at(gimbal->dofIndex(j)).gimbal, 0) << j;
    EXPECT_LT(gimbal->dofIndex("ball.z"), 0);
    bool noted = false;
    for (const std::string& n : gimbal->notes()) noted = noted || n.find("'ball' (ball_y, ball_x)") != std::string::npos;
    EXPECT_TRUE(noted);
    auto spin = [](const MechanismModel& m) {
      const int rod = m.linkIndex("rod");
      return m.linkVelocity(rod).second.dot(m.linkPose(rod).linear().col(2));
    };
    // (ball.x: about the joint frame's x, which is the rod's axis: z turned onto the URDF axis)
    const double spin0 = spin(*gimbal);
    const double E0 = gimbal->kineticEnergy() + gimbal->potentialEnergy();
    EXPECT_NEAR(std::fabs(spin0), 2.0, 1e-12);
    for (int k = 0; k < 1000; ++k) gimbal->step(1e-3), ball->step(1e-3);
    const int rod = gimbal->linkIndex("rod");
    EXPECT_LE((gimbal->linkPose(rod).matrix() - ball->linkPose(ball->linkIndex("rod")).matrix()).norm(), 1e-12);
    EXPECT_NEAR(spin(*gimbal), spin0, 1e-6 * std::fabs(spin0));
    EXPECT_NEAR(gimbal->kineticEnergy() + gimbal->potentialEnergy(), E0, 1e-6 * gimbal->kineticEnergy());
    // the rod swung far from the vertical: the motion is not the start's spin alone
    EXPECT_LT(gimbal->linkPose(rod).linear()(2, 2), 0.9);
  }
}

// The same chain with its last axis z (X-Y-Z: its lock away from the zero pose) is a ball;
// with mass on a middle link, limits on a joint, or a joint in a coupling, it is a gimbal:
// kept as written.
TEST(Dialects, GimbalsWithMassOrLimitsStayAsWritten) {
  const std::string xyz = replaced(readText(kDir + "/ball_as_gimbal.urdf"), "<axis xyz=\"1 0 0\"/><limit",
                                   "<axis xyz=\"0 0 1\"/><limit");
  const std::string heavy = replaced(xyz, "<link name=\"gimbal_1\"/>",
                                     "<link name=\"gimbal_1\"><inertial><mass value=\"0.1\"/>"
                                     "<inertia ixx=\"1e-4\" ixy=\"0\" ixz=\"0\" iyy=\"1e-4\" iyz=\"0\" izz=\"1e-4\"/>"
                                     "</inertial></link>");
  const std::string limited = replaced(xyz, "<limit effort=\"1\" velocity=\"20\"/>",
                                       "<limit lower=\"-1\" upper=\"1\" effort=\"1\" velocity=\"20\"/>");
  const std::string coupled = replaced(xyz, "</robot>",
                                       "<mechanism_sim:coupling name=\"geared\" constant=\"0\">"
                                       "<joint name=\"ball\" coefficient=\"1\"/><joint name=\"ball_x\" coefficient=\"-2\"/>"
                                       "</mechanism_sim:coupling></robot>");
  LoadOptions o;
  o.formulation = "absolute";
  auto ball = loadModelString(xyz, "gimbal.urdf", o);
  EXPECT_EQ(ball->gimbals().size(), 1u);
  for (const std::string& xml : {heavy, limited, coupled}) {
    auto m = loadModelString(xml, "gimbal.urdf", o);
    EXPECT_TRUE(m->gimbals().empty());
    EXPECT_EQ(m->dofs().at(m->dofIndex("ball_y")).gimbal, -1);
  }
}

// The ball is reported as the file wrote it: the three joints' angles, rates, accelerations
// and reactions, and the massless links' poses and velocities, are those of the chain as
// written (kept as three joints by naming one of them; its zero pose is away from the lock),
// swinging from rest under a slanted gravity. The angles take no command.
TEST(Dialects, ABallWrittenAsAGimbalIsReportedByTheFilesJoints) {
  const std::string xyz = replaced(readText(kDir + "/ball_as_gimbal.urdf"), "<axis xyz=\"1 0 0\"/><limit",
                                   "<axis xyz=\"0 0 1\"/><limit");
  LoadOptions keep;
  keep.formulation = "absolute";
  keep.positions = {{"ball_y", 0.0}};
  auto chain = loadModelString(xyz, "gimbal.urdf", keep);
  ASSERT_TRUE(chain->gimbals().empty());
  const Eigen::Vector3d g(3.0, -2.0, -9.81);
  chain->setGravity(g);
  for (const char* formulation : {"joint", "absolute"}) {
    SCOPED_TRACE(formulation);
    auto c = loadModelString(xyz, "gimbal.urdf", keep);
    c->setGravity(g);
    LoadOptions o;
    o.formulation = formulation;
    auto ball = loadModelString(xyz, "gimbal.urdf", o);
    ASSERT_EQ(ball->gimbals().size(), 1u);
    ball->setGravity(g);
    for (int step = 1; step <= 600; ++step) {
      c->step(1e-3), ball->step(1e-3);
      if (step % 150) continue;
      double speed = 0.0;
      for (const char* j : {"ball", "ball_y", "ball_x"}) {
        const int a = c->dofIndex(j), b = ball->dofIndex(j);
        speed = std::max(speed, std::fabs(c->velocity(a)));
        EXPECT_NEAR(ball->position(b), c->position(a), 1e-9) << j;
        EXPECT_NEAR(ball->velocity(b), c->velocity(a), 1e-8) << j;
        EXPECT_NEAR(ball->acceleration(b), c->acceleration(a), 1e-6 * (1 + std::fabs(c->acceleration(a)))) << j;
        EXPECT_NEAR(ball->effort(b), 0.0, 1e-12) << j;
      }
      EXPECT_GT(speed, 0.5);  // it swings
      for (const char* l : {"gimbal_1", "gimbal_2", "rod"}) {
        const int a = c->linkIndex(l), b = ball->linkIndex(l);
        EXPECT_LE((ball->linkPose(b).matrix() - c->linkPose(a).matrix()).norm(), 1e-9) << l;
        EXPECT_LE((ball->linkVelocity(b).first - c->linkVelocity(a).first).norm(), 1e-8) << l;
        EXPECT_LE((ball->linkVelocity(b).second - c->linkVelocity(a).second).norm(), 1e-8) << l;
      }
      std::map<std::string, JointReaction> chain_reactions;
      for (const JointReaction& r : c->jointReactions()) chain_reactions[r.joint] = r;
      int reported = 0;
      for (const JointReaction& r : ball->jointReactions()) {
        const JointReaction& e = chain_reactions.at(r.joint);
        EXPECT_LE((r.force - e.force).norm(), 1e-6 * e.force.norm()) << r.joint;
        EXPECT_LE(r.torque.norm(), 1e-9 * e.force.norm()) << r.joint;
        ++reported;
      }
      EXPECT_EQ(reported, 3);
    }
    const int b = ball->dofIndex("ball_y");
    try {
      ball->setEffort(b, 1.0);
      ADD_FAILURE() << "an effort on a gimbal's angle was taken";
    } catch (const UsageError& e) {
      EXPECT_NE(std::string(e.what()).find("'ball_y' is one of three revolute joints through massless links"),
                std::string::npos) << e.what();
    }
    EXPECT_THROW(ball->driveDof(b), UsageError);
    // reset starts the angles again at the file's zero
    ball->reset();
    for (const char* j : {"ball", "ball_y", "ball_x"}) EXPECT_EQ(ball->position(ball->dofIndex(j)), 0.0);
  }
}

// A spherical mechanism whose closing point misses the common centre by a rounding (3e-7 m
// in 0.5 m, as placo's spherical parallel mechanism's 6-digit rpy do): its dependent
// equations disagree at the file's precision. Assembly accepts it with a note and meets its
// initial crank rate (to the file's precision); the joint formulation, whose closures take
// the rounding's rows as independent and stop the crank, is refused, and auto runs it in
// absolute coordinates, which hold the dependent rows dropped.
TEST(Dialects, RoundedSphericalMechanismAssemblesWithItsRates) {
  const std::string rounded = readText(kDir + "/spherical_four_bar_rounded.urdf");
  LoadOptions joint;
  joint.formulation = "joint";
  try {
    loadModelString(rounded, "spherical_four_bar_rounded.urdf", joint);
    ADD_FAILURE() << "the joint formulation ran a mechanism its closures lock";
  } catch (const LoadError& e) {
    EXPECT_NE(std::string(e.what()).find("change the assembled velocities"), std::string::npos) << e.what();
  }
  auto a = loadModelString(rounded, "spherical_four_bar_rounded.urdf");
  EXPECT_EQ(std::string(a->mechanism().formulation()), "absolute");
  bool noted = false;
  for (const std::string& n : a->notes()) noted = noted || n.find("dependent equations disagree by") != std::string::npos;
  EXPECT_TRUE(noted);
  EXPECT_NEAR(a->velocity(a->dofIndex("crank_joint")), 3.0, 1e-5 * 3.0);
}

TEST(Dialects, EachInvalidFileFailsWithItsMessage) {
  const std::string dir = kDir + "/invalid";
  std::set<std::string> files;
  for (const auto& entry : std::filesystem::directory_iterator(dir))
    if (entry.path().extension() == ".urdf") files.insert(entry.path().filename().string());
  std::ifstream table(dir + "/expected.txt");
  ASSERT_TRUE(table);
  std::map<std::string, std::string> expected;
  std::string line;
  while (std::getline(table, line)) {
    if (line.empty() || line[0] == '#') continue;
    const size_t bar = line.find(" | ");
    ASSERT_NE(bar, std::string::npos) << line;
    expected[line.substr(0, bar)] = line.substr(bar + 3);
  }
  EXPECT_EQ(files.size(), expected.size());
  for (const std::string& f : files) {
    ASSERT_TRUE(expected.count(f)) << f << " has no line in expected.txt";
    const std::string path = dir + "/" + f, stem = path.substr(0, path.size() - 5);
    try {
      loadModelFile(path);
      ADD_FAILURE() << f << " loaded";
    } catch (const LoadError& e) {
      const std::string msg = e.what();
      EXPECT_EQ(msg.rfind(stem + ".", 0), 0u) << msg;
      // FILE:LINE: then the message
      EXPECT_NE(msg.find(":", stem.size() + 1), std::string::npos) << msg;
      EXPECT_NE(msg.find(expected[f]), std::string::npos) << f << ": expected '" << expected[f] << "' in: " << msg;
      EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
    }
  }
}

}  // namespace
}  // namespace mechanism_sim
