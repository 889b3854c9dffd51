// MuJoCo (2.2.2, Debian libmujoco-dev) as an independent oracle for the zoo's trees
// (test/zoo/): the same URDF text loaded by both engines, damping off in both, the same
// initial state, RK4 at 1e-4 s in both; after 1 s every joint angle agrees to 1e-8 rad.
// MuJoCo works in joint coordinates (a recursive tree algorithm), this project in absolute
// coordinates with constraints: an error in either one's dynamics shows up here.
//
// Conventions that differ (as MuJoCo 2.2.2's source and this test's runs show them), and
// what the test does about them:
// - <mimic>: MuJoCo ignores it. Trees with <mimic> are compared with their followers made
//   fixed joints (at 0) in the text given to both engines. The coupling itself is checked
//   in test_zoo (mimic four-bar against the same four-bar closed by a loop joint).
// - Limits: MuJoCo's are soft (a constraint that acts once the limit is passed, a penalty
//   with solref/solimp), ours are hard unilateral stops. The initial states (and each
//   case's gravity) keep every joint off its limits during the second; the test asserts so
//   on our side and prints the closest approach. Joints that cannot stay off their stops
//   (the UR gripper's drivers freed from their followers) are unlimited in the text given
//   to both: continuous, and with no lower/upper, because MuJoCo's URDF reader limits a
//   `continuous` joint whose <limit> has lower < upper (jnt_limited 1; urdfdom and this
//   loader give a continuous joint no limits). Made continuous with its lower/upper left,
//   humanoid's LHand (range [0, 1]) ran free here and into MuJoCo's soft stop there: the
//   0.41 rad jump by 0.1 s this test first measured.
// - Zero pose outside the limits (arm_gripper's arm_joint4, the humanoid's elbows, the
//   quadruped's calves): this loader starts such a joint at its nearest limit, MuJoCo at 0
//   (then pushes it in softly). Every such joint is given a position inside its limits.
// - Initial velocities: MuJoCo starts every dof where it is told (0 by default); this
//   loader holds the given ones and lets assembly choose the rest (the mass-orthogonal
//   projection from rest: least kinetic energy). Every dof is given its velocity (0 unless
//   the case says otherwise): from the seven given, wheeled_base's head_tilt started at
//   6.2 rad/s, reached its stop within 0.1 s and jumped 3e-2 rad. A floating base has no
//   dof: its velocity is assembly's (zero total momentum with the legs' rates held), and
//   MuJoCo's free joint is given it, with the base link's pose. Started at rest there,
//   the quadruped's joint angles parted from the first step (0.079 rad/s^2 on
//   FR_calf_joint, 3.9e-2 rad after 1 s).
// - Inertia: MuJoCo diagonalises a full inertia tensor (products of inertia, or the sum
//   of fused bodies) with mju_eig3, a Jacobi iteration that stops once an off-diagonal
//   element is below 1e-12 or a rotation's cosine is within 1e-12 of 1: principal axes up
//   to about 1.4e-6 rad off. Measured on the zoo: the tensors MuJoCo used differ from the
//   file's by 1e-10 to 5e-9 (relative) for the rotated link tensors, 7.6e-9 for
//   wheeled_base's chassis fused with its mast, 7.3e-7 for arm_gripper's link7 fused with
//   the hand. That was arm7's 2.9e-9 rad after 1 s (now 2.5e-12) and arm_gripper's
//   1.2e-5 rad/s^2 from the first step. MuJoCo is therefore given each <inertial> as its
//   principal moments and the rpy of its principal axes (computed here to 1e-16), and
//   <compiler fusestatic="false"> (mujocoText()).
// - Fixed joints: MuJoCo's URDF compiler fuses static bodies (fusestatic, on for URDF by
//   default) as this loader merges links joined by fixed joints. With fusestatic off (as
//   given here) a static body stays a body welded to its parent: the same mechanism. When
//   fusing, MuJoCo adds a static body's mass, centre of mass and inertia only if its mass
//   is at least mjMINVAL (1e-15): a mass-0 link's inertia is dropped (this loader too,
//   since ff04c4f); a link without <inertial> is a body of mass 0 in MuJoCo. The zoo's
//   mass-0 links all have inertia 0, so the two conventions never differ here.
// - Point masses (inertia 0) on a moving joint: MuJoCo refuses a body with a joint whose
//   mass or any principal moment is below mjMINVAL ("mass and inertia of moving bodies
//   must be larger than mjMINVAL") unless a static child body has both, and refuses to
//   fuse a point mass into another ("inertia must have positive eigenvalues in fusing
//   static body inertias"). quadruped.urdf carries <mujoco><compiler boundinertia="1e-12"
//   fusestatic="false"/> (a URDF extension element MuJoCo reads; urdfdom and this loader
//   ignore it): MuJoCo raises each principal moment of every body to at least 1e-12 kg m^2
//   (calves and toes alike), 2e-10 of the calves' 5e-3 kg m^2 about their knees.
// - armature 0, frictionloss from <dynamics friction> (0 in the zoo), gravity (0 0 -9.81)
//   are the same by default; contacts are disabled (the zoo has no collision geometry).
// - Joint names: a URDF `planar` joint becomes MuJoCo slides NAME_TX, NAME_TY and hinge
//   NAME_RZ (ours: NAME.x, NAME.y, NAME.rotation); a `floating` joint a free joint (ours
//   has no dofs: the base is compared by its link's world position and orientation).
#include <gtest/gtest.h>
#include <mujoco/mujoco.h>

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <map>
#include <memory>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "mechanism_sim/urdf/model.h"

namespace mechanism_sim {
namespace {

const std::string kSource = MECHANISM_SIM_SOURCE_DIR;
constexpr double kStep = 1e-4, kDuration = 1.0, kAgreement = 1e-8;

std::string readZoo(const std::string& file) {
  std::ifstream in(kSource + "/test/zoo/" + file);
  EXPECT_TRUE(in.good()) << file;
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// The text with every <mimic> follower made a fixed joint (at 0) and the named joints
// made unlimited (revolute: continuous, and no lower/upper: MuJoCo 2.2.2's URDF reader
// limits a continuous joint that has them; prismatic: limits far away).
std::string withoutMimic(std::string xml, const std::vector<std::string>& unlimit) {
  const std::regex follower("<joint name=\"([^\"]*)\" type=\"[a-z]*\">((?:(?!</joint>)[^])*)<mimic[^>]*/>");
  xml = std::regex_replace(xml, follower, "<joint name=\"$1\" type=\"fixed\">$2");
  for (const auto& j : unlimit) {
    const std::regex rev("(<joint name=\"" + j + "\" type=\")revolute\"");
    xml = std::regex_replace(xml, rev, "$1continuous\"");
    const std::regex con("(<joint name=\"" + j + "\" type=\"continuous\">(?:(?!</joint>)[^])*<limit )lower=\"[^\"]*\" upper=\"[^\"]*\" ");
    xml = std::regex_replace(xml, con, "$1");
    const std::regex pri("(<joint name=\"" + j + "\" type=\"prismatic\">(?:(?!</joint>)[^])*<limit )lower=\"[^\"]*\" upper=\"[^\"]*\"");
    xml = std::regex_replace(xml, pri, "$1lower=\"-10\" upper=\"10\"");
  }
  return xml;
}

double attribute(const std::string& element, const std::string& name) {
  std::smatch m;
  if (!std::regex_search(element, m, std::regex("\\b" + name + "=\"([^\"]*)\""))) return 0.0;
  return std::stod(m[1]);
}

// The text MuJoCo is given: the same mechanism, written so that MuJoCo's compiler computes
// nothing inexactly (see the conventions above):
// - every <inertial> as its principal moments and the principal axes' rpy, found here to
//   1e-16 (MuJoCo diagonalises a full tensor with mju_eig3, a Jacobi iteration that stops
//   once a rotation's cosine is within 1e-12 of 1: principal axes up to 1.4e-6 rad off);
// - <compiler fusestatic="false"> (unless the file has a <mujoco> element of its own):
//   static bodies stay bodies, welded to their parent, instead of being fused into it
//   (fusing adds the inertias and diagonalises the sum with mju_eig3 again).
std::string mujocoText(const std::string& xml) {
  const std::regex inertial("<inertial>((?:(?!</inertial>)[^])*)</inertial>");
  const auto robot = xml.cbegin() + static_cast<long>(xml.find("<robot"));  // not the header comments
  std::string out(xml.cbegin(), robot);
  auto last = robot;
  for (std::sregex_iterator it(robot, xml.cend(), inertial), end; it != end; ++it) {
    const std::string body = (*it)[1];
    std::smatch m;
    Eigen::Vector3d xyz = Eigen::Vector3d::Zero(), rpy = Eigen::Vector3d::Zero();
    if (std::regex_search(body, m, std::regex("<origin[^>]*>"))) {
      std::smatch v;
      const std::string o = m[0];
      if (std::regex_search(o, v, std::regex("xyz=\"([^\"]*)\""))) std::istringstream(v[1]) >> xyz[0] >> xyz[1] >> xyz[2];
      if (std::regex_search(o, v, std::regex("rpy=\"([^\"]*)\""))) std::istringstream(v[1]) >> rpy[0] >> rpy[1] >> rpy[2];
    }
    EXPECT_TRUE(std::regex_search(body, m, std::regex("<mass[^>]*>")));
    const double mass = attribute(m[0], "value");
    EXPECT_TRUE(std::regex_search(body, m, std::regex("<inertia[^>]*>")));
    const std::string in = m[0];
    Eigen::Matrix3d I;
    I << attribute(in, "ixx"), attribute(in, "ixy"), attribute(in, "ixz"), attribute(in, "ixy"), attribute(in, "iyy"),
        attribute(in, "iyz"), attribute(in, "ixz"), attribute(in, "iyz"), attribute(in, "izz");
    const Eigen::Matrix3d R = (Eigen::AngleAxisd(rpy[2], Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(rpy[1], Eigen::Vector3d::UnitY()) *
                               Eigen::AngleAxisd(rpy[0], Eigen::Vector3d::UnitX()))
                                  .toRotationMatrix();
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(R * I * R.transpose());
    Eigen::Matrix3d V = eig.eigenvectors();
    if (V.determinant() < 0) V.col(2) = -V.col(2);
    const Eigen::Vector3d ypr = V.eulerAngles(2, 1, 0);  // V = Rz(yaw) Ry(pitch) Rx(roll)
    char text[600];
    std::snprintf(text, sizeof text,
                  "<inertial><origin xyz=\"%.17g %.17g %.17g\" rpy=\"%.17g %.17g %.17g\"/><mass value=\"%.17g\"/>"
                  "<inertia ixx=\"%.17g\" iyy=\"%.17g\" izz=\"%.17g\" ixy=\"0\" ixz=\"0\" iyz=\"0\"/></inertial>",
                  xyz[0], xyz[1], xyz[2], ypr[2], ypr[1], ypr[0], mass, std::max(eig.eigenvalues()[0], 0.0),
                  std::max(eig.eigenvalues()[1], 0.0), std::max(eig.eigenvalues()[2], 0.0));
    out.append(last, (*it)[0].first);
    out += text;
    last = (*it)[0].second;
  }
  out.append(last, xml.cend());
  if (out.find("<mujoco>") == std::string::npos)
    out.insert(out.find('>', out.find("<robot")) + 1, "\n  <mujoco><compiler fusestatic=\"false\"/></mujoco>");
  return out;
}

struct MjDeleter {
  void operator()(mjModel* m) const { mj_deleteModel(m); }
  void operator()(mjData* d) const { mj_deleteData(d); }
};

std::unique_ptr<mjModel, MjDeleter> mujocoLoad(const std::string& xml, const std::string& name) {
  mjVFS vfs;
  mj_defaultVFS(&vfs);
  const std::string fname = name + ".urdf";
  EXPECT_EQ(mj_makeEmptyFileVFS(&vfs, fname.c_str(), static_cast<int>(xml.size())), 0);
  std::memcpy(vfs.filedata[mj_findFileVFS(&vfs, fname.c_str())], xml.data(), xml.size());
  char err[1000] = "";
  mjModel* m = mj_loadXML(fname.c_str(), &vfs, err, sizeof err);
  mj_deleteVFS(&vfs);
  EXPECT_NE(m, nullptr) << name << ": " << err;
  return std::unique_ptr<mjModel, MjDeleter>(m);
}

// MuJoCo's joint name of one of our dofs.
std::string mujocoJointName(const Dof& d) {
  static const std::map<std::string, std::string> planar = {{"x", "_TX"}, {"y", "_TY"}, {"rotation", "_RZ"}};
  const auto dot = d.name.find('.');
  if (dot == std::string::npos) return d.name;
  return d.name.substr(0, dot) + planar.at(d.name.substr(dot + 1));
}

struct Case {
  std::string file;
  std::vector<std::pair<std::string, double>> positions, velocities;
  std::vector<std::string> unlimit;  // joints made unlimited in both engines (see above)
  std::string base_link;             // a floating base: compare its world position too
  // Gravity in both engines: the arms hang from a ceiling (+z), so that they swing about a
  // stable pose for the second; falling from upright they tumble chaotically, and any two
  // integrations (ours at two step sizes alike) part by more than 1e-8 within 1 s.
  Eigen::Vector3d gravity{0, 0, -9.81};
};

void PrintTo(const Case& c, std::ostream* os) { *os << c.file; }

class Oracle : public ::testing::TestWithParam<Case> {};

TEST_P(Oracle, JointAnglesAgreeWithMuJoCoRK4After1s) {
  const Case& c = GetParam();
  std::vector<std::string> unlimit = c.unlimit;
  if (std::getenv("ORACLE_UNLIMIT_ALL")) {
    std::regex jn("<joint name=\"([^\"]*)\" type=\"(revolute|prismatic)\"");
    const std::string text = readZoo(c.file);
    for (std::sregex_iterator it(text.begin(), text.end(), jn), end; it != end; ++it) unlimit.push_back((*it)[1]);
  }
  const std::string xml = withoutMimic(readZoo(c.file), unlimit);
  LoadOptions o;
  o.positions = c.positions;
  o.velocities = c.velocities;
  // Every dof's velocity is given (0 unless the case says otherwise): assembly holds the
  // given ones and chooses the others (head_tilt of wheeled_base started at 6.2 rad/s from
  // the case's seven), MuJoCo starts them where it is told. The floating base's velocity,
  // which has no dof, is assembly's; MuJoCo's free joint is given it below.
  const auto given = loadModelString(xml, c.file, o);
  for (const Dof& dof : given->dofs())
    if (std::none_of(c.velocities.begin(), c.velocities.end(), [&](const auto& v) { return v.first == dof.name; }))
      o.velocities.push_back({dof.name, 0.0});
  auto ours = loadModelString(xml, c.file, o);
  for (const Dof& d : ours->dofs()) ours->mechanism().setJointDamping(d.joint_index, d.k, 0.0);

  auto m = mujocoLoad(mujocoText(xml), c.file.substr(0, c.file.size() - 5));
  ASSERT_TRUE(m);
  std::unique_ptr<mjData, MjDeleter> d(mj_makeData(m.get()));
  m->opt.integrator = mjINT_RK4;
  m->opt.timestep = kStep;
  m->opt.disableflags |= mjDSBL_CONTACT;
  for (int i = 0; i < m->nv; ++i) m->dof_damping[i] = 0.0;
  for (int k = 0; k < 3; ++k) ASSERT_EQ(m->opt.gravity[k], ours->gravity()[k]);  // the same default
  ours->setGravity(c.gravity);
  for (int k = 0; k < 3; ++k) m->opt.gravity[k] = c.gravity[k];

  // dof -> MuJoCo qpos / qvel address; every MuJoCo joint matched (a free joint by the base)
  std::vector<int> qadr, vadr;
  int matched = 0;
  for (const Dof& dof : ours->dofs()) {
    const int j = mj_name2id(m.get(), mjOBJ_JOINT, mujocoJointName(dof).c_str());
    ASSERT_GE(j, 0) << c.file << ": MuJoCo has no joint '" << mujocoJointName(dof) << "'";
    ASSERT_NE(m->jnt_type[j], mjJNT_FREE);
    qadr.push_back(m->jnt_qposadr[j]);
    vadr.push_back(m->jnt_dofadr[j]);
    ++matched;
  }
  const int free_joints = c.base_link.empty() ? 0 : 1;
  ASSERT_EQ(matched + free_joints, m->njnt) << c.file;
  for (size_t i = 0; i < qadr.size(); ++i) {
    d->qpos[qadr[i]] = ours->position(static_cast<int>(i));
    d->qvel[vadr[i]] = ours->velocity(static_cast<int>(i));
  }
  // A floating base: MuJoCo's free joint (qpos: the link frame's position and quaternion;
  // qvel: its origin's velocity in world axes, its angular velocity in its own axes) is
  // given our base link's pose and velocity.
  const int base_body = c.base_link.empty() ? -1 : mj_name2id(m.get(), mjOBJ_BODY, c.base_link.c_str());
  if (!c.base_link.empty()) {
    ASSERT_GE(base_body, 0);
    const int j = m->body_jntadr[base_body];
    ASSERT_EQ(m->jnt_type[j], mjJNT_FREE);
    const Link& link = ours->links()[ours->linkIndex(c.base_link)];
    const Eigen::Isometry3d pose = ours->linkPose(ours->linkIndex(c.base_link));
    const Eigen::Quaterniond q(pose.linear());
    const Eigen::Matrix3d R = ours->mechanism().rotation(link.body);
    const Eigen::Vector3d v = ours->mechanism().state().u.segment<3>(6 * (link.body - 1));
    const Eigen::Vector3d w = ours->mechanism().state().u.segment<3>(6 * (link.body - 1) + 3);  // body axes
    const Eigen::Vector3d v_origin = v + R * w.cross(link.body_T_link.translation());
    const Eigen::Vector3d w_link = link.body_T_link.linear().transpose() * w;
    double* qpos = d->qpos + m->jnt_qposadr[j];
    double* qvel = d->qvel + m->jnt_dofadr[j];
    for (int k = 0; k < 3; ++k) qpos[k] = pose.translation()[k], qvel[k] = v_origin[k], qvel[3 + k] = w_link[k];
    qpos[3] = q.w(), qpos[4] = q.x(), qpos[5] = q.y(), qpos[6] = q.z();
  }
  mj_forward(m.get(), d.get());

  // The stops are never reached on our side (the comparison assumes none is active).
  const auto& limits = ours->mechanism().system().limits;
  double margin = INFINITY;
  std::string closest;
  const long steps = std::lround(kDuration / kStep);
  for (long s = 0; s < steps; ++s) {
    ours->step(kStep);
    mj_step(m.get(), d.get());
    if (std::getenv("ORACLE_TRACE") && (s == 0 || s == 9 || s == 99 || s == 999 || s == 4999)) {
      double e = 0; std::string w;
      for (size_t i = 0; i < qadr.size(); ++i)
        if (std::fabs(ours->position(static_cast<int>(i)) - d->qpos[qadr[i]]) > e)
          e = std::fabs(ours->position(static_cast<int>(i)) - d->qpos[qadr[i]]), w = ours->dofs()[i].name;
      std::printf("  step %ld: %.3e (%s)\n", s + 1, e, w.c_str());
    }
    for (const auto& l : limits) {
      const double q = ours->mechanism().jointPosition(l.joint, l.k);
      if (std::min(q - l.lower, l.upper - q) < margin)
        margin = std::min(q - l.lower, l.upper - q), closest = ours->mechanism().joint(l.joint).name();
    }
  }
  EXPECT_GT(margin, 0.0) << c.file << ": a joint reached its limit; MuJoCo's are soft, the comparison needs none";

  double worst = 0;
  std::string worst_dof;
  for (size_t i = 0; i < qadr.size(); ++i) {
    const double e = std::fabs(ours->position(static_cast<int>(i)) - d->qpos[qadr[i]]);
    EXPECT_LT(e, kAgreement) << c.file << " dof " << ours->dofs()[i].name << ": ours " << ours->position(static_cast<int>(i))
                             << ", MuJoCo " << d->qpos[qadr[i]];
    if (e > worst) worst = e, worst_dof = ours->dofs()[i].name;
  }
  if (!c.base_link.empty()) {
    mj_kinematics(m.get(), d.get());
    const Eigen::Isometry3d pose = ours->linkPose(ours->linkIndex(c.base_link));
    const Eigen::Vector3d r_mj(d->xpos + 3 * base_body);
    const Eigen::Quaterniond q_mj(d->xquat[4 * base_body], d->xquat[4 * base_body + 1], d->xquat[4 * base_body + 2],
                                  d->xquat[4 * base_body + 3]);
    const double dr = (r_mj - pose.translation()).norm(), angle = Eigen::AngleAxisd(q_mj.toRotationMatrix().transpose() * pose.linear()).angle();
    EXPECT_LT(dr, kAgreement) << c.file << " base position";
    EXPECT_LT(angle, kAgreement) << c.file << " base orientation";
    std::printf("[ oracle ] %-22s base: |r - r_MuJoCo| = %.2e m, rotation between them %.2e rad\n", c.file.c_str(), dr, angle);
  }
  std::printf("[ oracle ] %-22s %2zu dofs: largest |q - q_MuJoCo| after %g s = %.2e rad (%s); closest approach to a limit %.3f (%s)\n",
              c.file.c_str(), qadr.size(), kDuration, worst, worst_dof.c_str(), margin, closest.c_str());
}

const Eigen::Vector3d kCeiling{0, 0, 9.81};

// Each case's state keeps every joint off its stops for the second (the test asserts it on
// our side); the closest approach is printed.
INSTANTIATE_TEST_SUITE_P(
    Zoo, Oracle,
    ::testing::Values(
        Case{"arm7.urdf",
             {{"joint1", 0.3}, {"joint2", 0.4}, {"joint3", -0.5}, {"joint4", -0.5}, {"joint5", 0.6}, {"joint6", 0.4},
              {"joint7", 0.2}},
             {{"joint1", 0.5}, {"joint3", -0.3}, {"joint7", 1.0}}, {}, "", kCeiling},
        // A weak sideways gravity: at 9.81 m/s^2 along each axis, both ways, and at 2 m/s^2
        // along +-z, +x and +y, from the poses tried, the light wrist and hand swing a joint
        // onto a stop within the second. The finger (limits [0, 0.04] kept) moves between
        // 0.020 and 0.010.
        Case{"arm_gripper.urdf",
             {{"arm_joint2", -0.3}, {"arm_joint4", -1.5}, {"arm_joint6", 1.8}, {"finger_joint1", 0.02}},
             {{"arm_joint1", 0.4}, {"arm_joint3", -0.2}, {"finger_joint1", -0.03}}, {}, "", {0, 0.5, 0}},
        // The drivers, freed from their followers, reach their stops: unlimited in both.
        Case{"ur_fourbar_mimic.urdf",
             {{"shoulder_lift", 0.3}, {"elbow", 0.4}, {"wrist_1", -0.3}, {"wrist_2", 0.4}},
             {{"shoulder_pan", 0.5}},
             {"left_driver_joint", "right_driver_joint"},
             "", kCeiling},
        // Without gravity: hanging from its fixed torso, its equilibrium rests on stops (the
        // elbows straight at -0.04, LHipPitch at 0.5: found by letting it settle, damped), and
        // from mid-range poses the light wrists and ankles swing onto a stop within the second
        // at every gravity tried (0.2 to 9.81 m/s^2, down, up and sideways). Every joint starts
        // in mid-range (the elbows' zero pose lies outside their limits; the loader would start
        // them at -0.04, MuJoCo at 0): 25 dofs in coupled free motion, 0.43 from a stop at least.
        Case{"humanoid.urdf",
             {{"HeadPitch", -0.05}, {"LHipYawPitch", -0.2}, {"LHipRoll", 0.2}, {"LHipPitch", -0.5}, {"LKneePitch", 1.0},
              {"LAnklePitch", -0.15}, {"LAnkleRoll", 0.19}, {"RHipRoll", -0.2}, {"RHipPitch", -0.5}, {"RKneePitch", 1.0},
              {"RAnklePitch", -0.15}, {"RAnkleRoll", -0.19}, {"LShoulderRoll", 0.5}, {"LElbowRoll", -0.77}, {"LHand", 0.5},
              {"RShoulderRoll", -0.5}, {"RElbowRoll", -0.77}, {"RHand", 0.5}},
             {{"HeadYaw", 0.2}, {"LHipRoll", 0.1}, {"RShoulderRoll", -0.2}, {"LKneePitch", 0.3}, {"RAnklePitch", -0.2},
              {"LWristYaw", 0.3}, {"LElbowYaw", -0.2}},
             {}, "", Eigen::Vector3d::Zero()},
        // Falling freely (the file's gravity), its legs moving; calves start inside their
        // limits (their zero pose is outside them).
        Case{"quadruped.urdf",
             {{"FR_thigh_joint", 0.8}, {"FL_thigh_joint", 0.7}, {"RR_thigh_joint", 0.9}, {"RL_thigh_joint", 0.8},
              {"FR_calf_joint", -1.6}, {"FL_calf_joint", -1.5}, {"RR_calf_joint", -1.7}, {"RL_calf_joint", -1.6}},
             {{"FR_hip_joint", 0.3}, {"RL_thigh_joint", -0.4}, {"FL_calf_joint", 0.5}}, {}, "trunk"},
        Case{"wheeled_base.urdf",
             {{"head_tilt", 0.9}},
             {{"base_planar.x", 0.4}, {"base_planar.rotation", 0.6}, {"left_wheel_joint", 3.0}, {"right_wheel_joint", 5.0},
              {"front_caster_swivel", 1.0}, {"front_caster_wheel_joint", 8.0}, {"head_pan", 0.3}},
             {}, ""}),
    [](const auto& info) { return info.param.file.substr(0, info.param.file.size() - 5); });

}  // namespace
}  // namespace mechanism_sim
