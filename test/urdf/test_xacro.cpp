// xacro models, expanded by ROS's own xacro (doc/xacro.md): test/xacro/robot.urdf.xacro and
// the description package test/xacro/ws/src/acme_description expand to what their macros,
// properties, YAML files and arguments say; arguments change them; $(find) reaches a sibling
// package with or without ROS_PACKAGE_PATH; a ROS installation's xacro is preferred; broken
// files give one line naming the file; the simulate CLI and scripts/xacro take arguments.
#include <gtest/gtest.h>

#include <sys/stat.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>

#include <Eigen/Eigenvalues>
#include <urdf_parser/urdf_parser.h>

#include "mechanism_sim/urdf/model.h"
#include "run_command.h"
#include "xacro.h"

namespace mechanism_sim {
namespace {

const std::string kSource = MECHANISM_SIM_SOURCE_DIR;
const std::string kRobot = kSource + "/test/xacro/robot.urdf.xacro";

// $(find mechanism_sim) in the fixture: this source tree is the package.
class Xacro : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { setenv("ROS_PACKAGE_PATH", kSource.c_str(), 1); }
};

// One rod of the fixture's macro: its mass, length and inertia as the model has them.
struct Rod {
  double mass, joint_to_next, joint_to_com;
  Eigen::Vector3d moments;  // principal moments about the centre of mass, ascending
};

Rod rod(const MechanismModel& m, const std::string& link, const std::string& next) {
  const int l = m.linkIndex(link);
  EXPECT_GE(l, 0) << link;
  const Body& b = m.mechanism().body(m.links()[l].body);
  const Eigen::Vector3d origin = m.linkPose(l).translation();
  Rod r;
  r.mass = b.m;
  r.joint_to_com = (b.r - origin).norm();
  r.joint_to_next = next.empty() ? 0.0 : (m.linkPose(m.linkIndex(next)).translation() - origin).norm();
  r.moments = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(b.Jp).eigenvalues();
  return r;
}

// A solid rod of radius 0.01 (the fixture's property): ixx = iyy = m (3 r^2 + L^2) / 12, izz = m r^2 / 2.
void expectRod(const Rod& r, double mass, double length, const std::string& what) {
  const double radius = 0.01;
  EXPECT_NEAR(r.mass, mass, 1e-12) << what;
  EXPECT_NEAR(r.joint_to_com, length / 2, 1e-9) << what;
  EXPECT_NEAR(r.moments[0], mass * radius * radius / 2, 1e-12) << what;
  EXPECT_NEAR(r.moments[1], mass * (3 * radius * radius + length * length) / 12, 1e-12) << what;
  EXPECT_NEAR(r.moments[2], mass * (3 * radius * radius + length * length) / 12, 1e-12) << what;
}

TEST_F(Xacro, DefaultsGiveWhatTheMacrosSay) {
  auto m = loadModelFile(kRobot);
  EXPECT_EQ(m->name(), "xacro_pendulum");
  ASSERT_EQ(m->links().size(), 3u);
  ASSERT_EQ(m->dofs().size(), 2u);
  EXPECT_EQ(m->dofs()[0].name, "upper_joint");  // the macro's ${name}_joint
  EXPECT_EQ(m->dofs()[1].name, "lower_joint");
  ASSERT_EQ(m->treeJoints().size(), 2u);
  EXPECT_EQ(m->treeJoints()[1].parent, "upper");
  EXPECT_EQ(m->treeJoints()[1].child, "lower");
  const Rod upper = rod(*m, "upper", "lower"), lower = rod(*m, "lower", "");
  expectRod(upper, 1.0, 0.3, "upper: length $(arg length) default 0.3");
  EXPECT_NEAR(upper.joint_to_next, 0.3, 1e-9);  // lower hangs at xyz="0 0 ${-l}"
  expectRod(lower, 0.5, 0.6, "lower: length ${2*l}, mass $(arg tip_mass) default 0.5");
  // <mechanism_sim:initial position="${pi/2}"> passed through the expansion
  EXPECT_NEAR(m->position(m->dofIndex("upper_joint")), M_PI / 2, 1e-9);
  EXPECT_NEAR(m->position(m->dofIndex("lower_joint")), 0.0, 1e-9);
}

TEST_F(Xacro, ArgumentsOverrideTheDefaults) {
  LoadOptions o;
  o.xacro_args = {{"length", "0.5"}, {"tip_mass", "0.8"}};
  auto m = loadModelFile(kRobot, o);
  const Rod upper = rod(*m, "upper", "lower"), lower = rod(*m, "lower", "");
  expectRod(upper, 1.0, 0.5, "upper with length:=0.5");
  EXPECT_NEAR(upper.joint_to_next, 0.5, 1e-9);
  expectRod(lower, 0.8, 1.0, "lower with length:=0.5 tip_mass:=0.8");
  // and the model runs
  for (int i = 0; i < 100; ++i) m->step(1e-3);
  EXPECT_LE(m->positionViolation(), 1e-10);
}

// Each broken file: a LoadError of one line, "FILE: xacro: what".
TEST_F(Xacro, BrokenFilesGiveOneLineNamingTheFile) {
  const std::string dir = kSource + "/test/xacro/broken/";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"undefined_property.urdf.xacro",
       "xacro: name 'wheel_radius' is not defined when evaluating expression 'wheel_radius'"},
      {"unknown_macro.urdf.xacro", "xacro: unknown macro name: xacro:wheel"},
      {"bad_xml.urdf.xacro", "xacro: XML parsing error: mismatched tag: line 5, column 2"},
      {"missing_include.urdf.xacro", "xacro: No such file or directory: " + dir + "no_such_file.xacro"},
      {"undefined_arg.urdf.xacro", "xacro: Undefined substitution argument prefix"},
      {"yaml_error.urdf.xacro", "xacro: while scanning a quoted scalar"},
      {"missing_package.urdf.xacro",
       "xacro: $(find no_such_description): package 'no_such_description' not found on ROS_PACKAGE_PATH"},
      // expands; the URDF it expands to is wrong: the loader's message, lines of the expansion
      {"negative_mass.urdf.xacro", "(xacro expansion):"},
  };
  for (const auto& [file, expect] : cases) {
    const std::string path = dir + file;
    try {
      loadModelFile(path);
      ADD_FAILURE() << file << " loaded";
    } catch (const LoadError& e) {
      const std::string msg = e.what();
      EXPECT_EQ(msg.rfind(path + ": " + expect, 0) == 0 || msg.rfind(path + " " + expect, 0) == 0, true)
          << file << ": expected '" << path << ": " << expect << "...', got: " << msg;
      EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
    }
  }
  try {
    loadModelFile(dir + "negative_mass.urdf.xacro");
  } catch (const LoadError& e) {
    EXPECT_NE(std::string(e.what()).find("mass"), std::string::npos) << e.what();
  }
}

TEST_F(Xacro, ArgumentsForAPlainUrdfAreAnError) {
  LoadOptions o;
  o.xacro_args = {{"length", "0.5"}};
  try {
    loadModelFile(kSource + "/urdf/four_bar.urdf", o);
    FAIL();
  } catch (const LoadError& e) {
    EXPECT_NE(std::string(e.what()).find("four_bar.urdf: xacro arguments (name:=value) given, but the file is not a .xacro file"),
              std::string::npos)
        << e.what();
  }
}

// Restores an environment variable on leaving the scope.
class EnvOverride {
 public:
  EnvOverride(const char* name, const std::string& value) : name_(name) {
    const char* old = std::getenv(name);
    had_ = old != nullptr;
    if (had_) old_ = old;
    setenv(name, value.c_str(), 1);
  }
  ~EnvOverride() { had_ ? setenv(name_, old_.c_str(), 1) : unsetenv(name_); }

 private:
  const char* name_;
  bool had_;
  std::string old_;
};

TEST_F(Xacro, AMissingProgramIsNamed) {
  EnvOverride program("MECHANISM_SIM_XACRO", "/nonexistent/xacro");
  try {
    loadModelFile(kRobot);
    FAIL();
  } catch (const LoadError& e) {
    EXPECT_EQ(std::string(e.what()), kRobot + ": xacro: no program '/nonexistent/xacro' to run (MECHANISM_SIM_XACRO)");
  }
}

// A script that never answers is killed at the time limit.
TEST_F(Xacro, AHungExpansionIsKilled) {
  const std::string hang = ::testing::TempDir() + "/hang.sh";
  std::ofstream(hang) << "#!/bin/sh\nexec sleep 30\n";
  ASSERT_EQ(chmod(hang.c_str(), 0755), 0);
  EnvOverride program("MECHANISM_SIM_XACRO", hang);
  const auto start = std::chrono::steady_clock::now();
  try {
    expandXacro(kRobot, {}, 0.5);
    FAIL();
  } catch (const LoadError& e) {
    EXPECT_NE(std::string(e.what()).find("within 0.5 s (killed)"), std::string::npos) << e.what();
  }
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 5.0);
}

using mechanism_sim::testing_util::runCommand;

TEST_F(Xacro, SimulateTakesXacroArguments) {
  const std::string csv = ::testing::TempDir() + "/xacro.csv";
  auto r = runCommand(std::string(SIMULATE_BIN) + " " + kRobot + " length:=0.5 --duration 0.1 --csv " + csv + " 2>&1");
  ASSERT_EQ(r.code, 0) << r.out;
  std::ifstream in(csv);
  std::string header;
  std::getline(in, header);
  EXPECT_EQ(header.rfind("time,upper_joint.position,", 0), 0u) << header;
  // a xacro argument for a plain URDF is a usage error
  r = runCommand(std::string(SIMULATE_BIN) + " " + kSource + "/urdf/four_bar.urdf length:=0.5 --duration 0.1 2>&1");
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_NE(r.out.find("is not a .xacro file"), std::string::npos) << r.out;
  // a broken xacro: one line, exit code 1
  r = runCommand(std::string(SIMULATE_BIN) + " " + kSource + "/test/xacro/broken/unknown_macro.urdf.xacro 2>&1");
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_EQ(r.out, "simulate: " + kSource + "/test/xacro/broken/unknown_macro.urdf.xacro: xacro: unknown macro name: xacro:wheel\n");
}

const std::string kAcme = kSource + "/test/xacro/ws/src/acme_description/urdf/acme.urdf.xacro";

// The URDF that scripts/xacro writes for `file args`, as urdfdom reads it (nullptr: no URDF).
urdf::ModelInterfaceSharedPtr expandToUrdf(const std::string& file, const std::string& args,
                                           const std::string& env = "") {
  const auto r = runCommand(env + " " + kSource + "/scripts/xacro " + file + " " + args);
  EXPECT_EQ(r.code, 0) << r.out;
  return r.code == 0 ? urdf::parseURDF(r.out) : nullptr;
}

double degrees(double d) { return d * M_PI / 180.0; }

// The acme package uses what the makers' descriptions use; each value below is what ROS's
// xacro gives for the expression or YAML entry that the fixture's comment names.
TEST_F(Xacro, ADescriptionPackageExpandsAsRosXacroSays) {
  // $(find acme_grippers) and $(find acme_description) from the workspace around the file:
  // ROS_PACKAGE_PATH names neither package.
  const auto m = expandToUrdf(kAcme, "prefix:=left_", "ROS_PACKAGE_PATH=" + kSource);
  ASSERT_TRUE(m);
  EXPECT_EQ(m->getName(), "acme");
  // (prefix + 'BASE').lower()
  ASSERT_TRUE(m->getLink("left_base"));
  // load_yaml with !degrees / !radians, limits[name]['key'] and limits[name].key
  const auto pan = m->getJoint("left_shoulder_pan");
  ASSERT_TRUE(pan && pan->limits);
  EXPECT_NEAR(pan->limits->lower, degrees(-170), 1e-15);
  EXPECT_NEAR(pan->limits->upper, degrees(170), 1e-15);
  EXPECT_NEAR(pan->limits->velocity, degrees(180), 1e-15);
  EXPECT_EQ(pan->limits->effort, 150.0);
  EXPECT_EQ(pan->axis.z, 1.0);  // the macro's axis argument
  const auto elbow = m->getJoint("left_elbow");
  ASSERT_TRUE(elbow && elbow->limits);
  EXPECT_NEAR(elbow->limits->upper, degrees(135), 1e-15);
  EXPECT_EQ(elbow->axis.y, 1.0);  // the macro's default axis:='0 1 0'
  // !millimeters through xacro.dotify: the elbow sits 425 mm above the shoulder, and the
  // upper arm's mass is 2.5 + 0.5 * (0.425 > 0.4)
  EXPECT_NEAR(elbow->parent_to_joint_origin_transform.position.z, 0.425, 1e-15);
  EXPECT_EQ(m->getLink("left_upper_arm")->inertial->mass, 3.0);
  // a property whose value spans two lines: iyy == ixx of the solid cylinder
  const auto& I = *m->getLink("left_forearm")->inertial;
  EXPECT_NEAR(I.iyy, 1.5 * (3 * 0.03 * 0.03 + 0.39 * 0.39) / 12, 1e-15);
  EXPECT_EQ(I.iyy, I.ixx);
  // wrist-2020 is not in ['wrist-2010', 'wrist-2017']: 0.1 m, int(split('-')[1]) names it
  ASSERT_TRUE(m->getLink("left_wrist_2020"));
  EXPECT_EQ(m->getLink("left_wrist_2020")->inertial->mass, 0.3);  // $(eval ... if ... else ...)
  EXPECT_EQ(m->getJoint("left_wrist")->axis.y, 1.0);              // python.isinstance(...) and year < 2015
  // the recursive macro: two finger segments, each half as long as the one above
  ASSERT_TRUE(m->getJoint("left_wrist_2020_s2_s1_joint"));
  EXPECT_FALSE(m->getLink("left_wrist_2020_s2_s1_s0"));
  EXPECT_NEAR(m->getJoint("left_wrist_2020_s2_s1_joint")->parent_to_joint_origin_transform.position.z, 0.05, 1e-15);
  // the gripper from the sibling package, its prefix:=^ from the caller's property
  ASSERT_TRUE(m->getJoint("left_finger_joint"));
  EXPECT_EQ(m->getJoint("left_finger_joint")->limits->upper, 0.05);
  // scope="parent" read back with lazy_eval="false": the first joint the macro made, and
  // $(optenv) with its default
  EXPECT_TRUE(m->getLink("left_note_first_joint_left_shoulder_pan"));
}

TEST_F(Xacro, ArgumentsSelectTheBranchesOfADescription) {
  const auto m = expandToUrdf(kAcme, "wrist_model:=wrist-2010 fingers:=3 gripper:=false",
                              "ACME_NOTE='set by env'");
  ASSERT_TRUE(m);
  ASSERT_TRUE(m->getLink("wrist_2010"));
  EXPECT_EQ(m->getLink("wrist_2010")->inertial->mass, 0.4);
  EXPECT_EQ(m->getJoint("wrist")->axis.x, 1.0);
  EXPECT_NEAR(m->getJoint("wrist_2010_s3_joint")->parent_to_joint_origin_transform.position.z, 0.08, 1e-15);
  EXPECT_TRUE(m->getJoint("wrist_2010_s3_s2_s1_joint"));
  EXPECT_FALSE(m->getJoint("finger_joint"));
  EXPECT_TRUE(m->getLink("note_set_by_env"));
  // the same file runs in the simulator, through the loader's expansion
  LoadOptions o;
  o.xacro_args = {{"wrist_model", "wrist-2017"}};
  const auto model = loadModelFile(kAcme, o);
  EXPECT_GE(model->dofIndex("finger_joint"), 0);
  EXPECT_GE(model->linkIndex("wrist_2017"), 0);
}

// A ROS installation's xacro (found by rospack) is preferred to the PyPI package.
TEST_F(Xacro, ARosInstallationsXacroIsPreferred) {
  const std::string ros = ::testing::TempDir() + "/ros_share";
  const std::string pkg = ros + "/xacro", mod = pkg + "/src/xacro";
  ASSERT_EQ(runCommand("mkdir -p " + mod).code, 0);
  std::ofstream(pkg + "/package.xml") << "<package format=\"2\"><name>xacro</name><version>1.14.99</version>"
                                          "<description>a stand-in</description><maintainer email=\"a@b.c\">a</maintainer>"
                                          "<license>BSD</license></package>\n";
  std::ofstream(mod + "/__init__.py")
      << "import xml.dom.minidom\n__version__ = '1.14.99'\nfilestack = []\nmacrostack = []\n"
         "def process_file(path, mappings=None):\n"
         "    return xml.dom.minidom.parseString('<robot name=\"from_ros\"><link name=\"%s\"/></robot>' % mappings.get('l', 'x'))\n";
  std::ofstream(mod + "/substitution_args.py") << "_eval_find = None\n";
  const std::string env = "ROS_PACKAGE_PATH=" + ros + " ROS_HOME=" + ros + "/home";
  const auto v = runCommand(env + " " + kSource + "/scripts/xacro --version");
  EXPECT_EQ(v.out, "xacro 1.14.99 (ROS installation: " + mod + ")\n");
  const auto r = runCommand(env + " " + kSource + "/scripts/xacro " + kRobot + " l:=arm");
  EXPECT_NE(r.out.find("<robot name=\"from_ros\">"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("<link name=\"arm\"/>"), std::string::npos) << r.out;
  // without it, the project's PyPI package
  const auto pypi = runCommand("ROS_PACKAGE_PATH=" + kSource + " " + kSource + "/scripts/xacro --version");
  EXPECT_EQ(pypi.out.rfind("xacro 2.1.1 (PyPI: ", 0), 0u) << pypi.out;
}

// scripts/xacro (launch/simulate.launch's robot_description): a plain URDF byte for byte,
// a xacro file expanded with its arguments.
TEST_F(Xacro, ScriptCopiesPlainUrdfAndExpandsXacro) {
  const std::string plain = kSource + "/urdf/four_bar.urdf";
  std::ifstream in(plain);
  std::stringstream file;
  file << in.rdbuf();
  EXPECT_EQ(runCommand(kSource + "/scripts/xacro " + plain).out, file.str());
  const auto r = runCommand(kSource + "/scripts/xacro " + kRobot + " length:=0.5");
  ASSERT_EQ(r.code, 0);
  EXPECT_NE(r.out.find("<origin xyz=\"0 0 -0.5\" rpy=\"0 0 0\"/>"), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("xacro:"), std::string::npos) << r.out;
  const auto bad = runCommand(kSource + "/scripts/xacro " + kSource + "/test/xacro/broken/unknown_macro.urdf.xacro 2>&1");
  EXPECT_EQ(bad.code, 1);
  EXPECT_EQ(std::count(bad.out.begin(), bad.out.end(), '\n'), 1) << bad.out;
}

}  // namespace
}  // namespace mechanism_sim
