// Kinematic models (doc/method.md, "Kinematic models"): no moving body has mass, so each
// free dof is driven or held and the loops and couplers are solved for the rest at every
// step. Against the analytic four-bar (Freudenstein's closure equation, its rate and
// acceleration by implicit differentiation), a held arm, mimics, and the refusal of a
// model with only some massless moving bodies.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "mechanism_sim/urdf/model.h"

namespace mechanism_sim {
namespace {

const std::string kSource = MECHANISM_SIM_SOURCE_DIR;

bool hasNote(const MechanismModel& m, const std::string& text) {
  for (const std::string& n : m.notes())
    if (n == text) return true;
  return false;
}

// The four-bar of kinematic_four_bar.urdf in its plane (x, z), angles about y: crank tip
// P = b (sin t, cos t), rocker tip Q = (a, 0) + d (sin f, cos f), f the rocker's absolute
// angle (the sum of the three tree joints' angles). |Q - P| = c reads
//   F(t, f) = A(t) sin f + B(t) cos f - C(t) = 0,
//   A = 2 d (a - b sin t), B = -2 b d cos t, C = c^2 - a^2 - b^2 - d^2 + 2 a b sin t,
// whose branch through (0, 0) is f = asin(C / R) - atan2(B, A), R = |(A, B)|. With
// f' = df/dt = -F_t / F_f and f'' = -(F_tt + 2 F_tf f' + F_ff f'^2) / F_f, the rocker's
// rate is f' w and its acceleration f'' w^2 (crank at constant w).
struct FourBar {
  double a = 0.4, b = 0.1, c = std::sqrt(0.2), d = 0.3;
  double f(double t) const {
    const double A = 2 * d * (a - b * std::sin(t)), B = -2 * b * d * std::cos(t),
                 C = c * c - a * a - b * b - d * d + 2 * a * b * std::sin(t);
    return std::asin(C / std::hypot(A, B)) - std::atan2(B, A);
  }
  void derivatives(double t, double* f1, double* f2) const {
    const double phi = f(t), s = std::sin(phi), co = std::cos(phi), st = std::sin(t), ct = std::cos(t);
    const double A = 2 * d * (a - b * st), B = -2 * b * d * ct;
    const double A1 = -2 * b * d * ct, B1 = 2 * b * d * st, C1 = 2 * a * b * ct;
    const double A2 = 2 * b * d * st, B2 = 2 * b * d * ct, C2 = -2 * a * b * st;
    const double Ft = A1 * s + B1 * co - C1, Ff = A * co - B * s;
    const double Ftt = A2 * s + B2 * co - C2, Ftf = A1 * co - B1 * s, Fff = -A * s - B * co;
    *f1 = -Ft / Ff;
    *f2 = -(Ftt + 2 * Ftf * *f1 + Fff * *f1 * *f1) / Ff;
  }
};

TEST(Kinematic, AMasslessFourBarFollowsFreudensteinsSolution) {
  const double w = 3.0;
  LoadOptions o;
  o.drives = {{"crank_joint", w}};
  auto m = loadModelFile(kSource + "/test/urdf/kinematic_four_bar.urdf", o);
  EXPECT_TRUE(hasNote(*m, "kinematic: no moving body has mass; 0 dofs held, 1 driven, 2 solved from the loops and couplers"));
  EXPECT_STREQ(m->mechanism().formulation(), "absolute");
  const int crank = m->dofIndex("crank_joint"), coupler = m->dofIndex("coupler_joint"), rocker = m->dofIndex("rocker_joint");
  const Mechanism& mech = m->mechanism();
  auto acc = [&](int dof) { return mech.jointAcceleration(m->dofs()[dof].joint_index, 0); };
  const FourBar fb;
  double worst_q = 0, worst_v = 0, worst_a = 0;
  for (int i = 1; i <= 2500; ++i) {  // 2.5 s: more than a turn of the crank
    m->step(1e-3);
    if (i % 50) continue;
    const double t = m->position(crank);
    const double phi = t + m->position(coupler) + m->position(rocker);
    const double phi_dot = m->velocity(crank) + m->velocity(coupler) + m->velocity(rocker);
    const double phi_ddot = acc(crank) + acc(coupler) + acc(rocker);
    double f1, f2;
    fb.derivatives(t, &f1, &f2);
    EXPECT_NEAR(m->velocity(crank), w, 1e-12 * w);
    // the closure's angle f is defined modulo 2 pi
    const double dq = std::remainder(phi - fb.f(t), 2 * M_PI);
    worst_q = std::max(worst_q, std::abs(dq) / std::max(1.0, std::abs(fb.f(t))));
    worst_v = std::max(worst_v, std::abs(phi_dot - f1 * w) / w);
    worst_a = std::max(worst_a, std::abs(phi_ddot - f2 * w * w) / (w * w));
  }
  EXPECT_LT(worst_q, 1e-9);
  EXPECT_LT(worst_v, 1e-9);
  EXPECT_LT(worst_a, 1e-9);
  EXPECT_GT(m->position(crank), 2 * M_PI);
}

// Undriven, the crank is held and the loop holds the rest: nothing moves.
TEST(Kinematic, AnUndrivenFourBarIsHeld) {
  auto m = loadModelFile(kSource + "/test/urdf/kinematic_four_bar.urdf");
  EXPECT_TRUE(hasNote(*m, "kinematic: no moving body has mass; 1 dofs held, 0 driven, 2 solved from the loops and couplers"));
  for (int i = 0; i < 100; ++i) m->step(1e-3);
  for (size_t d = 0; d < m->dofs().size(); ++d) EXPECT_NEAR(m->position(static_cast<int>(d)), 0.0, 1e-12) << m->dofs()[d].name;
}

TEST(Kinematic, AMasslessArmWithoutDrivesHoldsStill) {
  LoadOptions o;
  o.positions = {{"joint_2", 0.7}};  // set (--set): held there
  auto m = loadModelFile(kSource + "/test/urdf/kinematic_arm.urdf", o);
  EXPECT_TRUE(hasNote(*m, "kinematic: no moving body has mass; 3 dofs held, 0 driven, 0 solved from the loops and couplers"));
  const Eigen::Vector3d tool = m->linkPose(m->linkIndex("tool0")).translation();
  for (int i = 0; i < 500; ++i) m->step(1e-3);  // gravity acts on nothing
  EXPECT_NEAR(m->position(m->dofIndex("joint_1")), 0.0, 1e-12);
  EXPECT_NEAR(m->position(m->dofIndex("joint_2")), 0.7, 1e-12);
  EXPECT_NEAR(m->position(m->dofIndex("joint_3")), 0.0, 1e-12);
  for (size_t d = 0; d < m->dofs().size(); ++d) EXPECT_NEAR(m->velocity(static_cast<int>(d)), 0.0, 1e-12);
  EXPECT_LT((m->linkPose(m->linkIndex("tool0")).translation() - tool).norm(), 1e-12);
  // the tool where joint_2 = 0.7 puts it: 0.9 m up the column's axis of joint_2 tilted by 0.7
  EXPECT_NEAR(tool.x(), 0.9 * std::sin(0.7), 1e-12);
  EXPECT_NEAR(tool.z(), 0.5 + 0.9 * std::cos(0.7), 1e-12);
  // a held dof is a velocity drive: it can be commanded like one
  m->commandDriveVelocity(m->dofIndex("joint_1"), 1.0, INFINITY);
  for (int i = 0; i < 100; ++i) m->step(1e-3);
  EXPECT_NEAR(m->position(m->dofIndex("joint_1")), 0.1, 1e-9);
}

// The boom is held (a mimic's leader takes no drive of the file: the loader refuses one
// there) and commanded like a velocity drive (the node's ~drive_command); the balancer and
// the rod follow it.
TEST(Kinematic, MimicsMoveTheSlavesWithTheMaster) {
  auto m = loadModelFile(kSource + "/test/urdf/kinematic_counterbalance.urdf");
  EXPECT_TRUE(hasNote(*m, "kinematic: no moving body has mass; 2 dofs held, 0 driven, 2 solved from the loops and couplers"));
  m->commandDriveVelocity(m->dofIndex("boom_joint"), 0.5, INFINITY);
  for (int i = 0; i < 1000; ++i) m->step(1e-3);
  const double q = m->position(m->dofIndex("boom_joint"));
  EXPECT_NEAR(q, 0.5, 1e-9);
  EXPECT_NEAR(m->position(m->dofIndex("balancer_joint")), -q, 1e-12);
  EXPECT_NEAR(m->position(m->dofIndex("rod_joint")), 0.05 * q + 0.1, 1e-12);
  EXPECT_NEAR(m->velocity(m->dofIndex("balancer_joint")), -0.5, 1e-12);
  EXPECT_NEAR(m->velocity(m->dofIndex("rod_joint")), 0.025, 1e-12);
  EXPECT_NEAR(m->position(m->dofIndex("wrist_joint")), 0.0, 1e-12);
}

// One massless moving link among massive ones: refused as before (no dof is held).
TEST(Kinematic, SomeMasslessMovingBodiesAreStillRefused) {
  const std::string path = kSource + "/test/invalid/massless_body_unmoved.urdf";
  try {
    loadModelFile(path);
    ADD_FAILURE() << "loaded";
  } catch (const LoadError& e) {
    EXPECT_EQ(std::string(e.what()),
              path + ": bodies that can move without moving any mass: 'wheel' (give them mass and inertia, or joints "
                     "that fix every direction they can move in)");
  }
}

TEST(Kinematic, AnInitialVelocityOfAHeldDofIsRefused) {
  LoadOptions o;
  o.velocities = {{"joint_1", 1.0}};
  try {
    loadModelFile(kSource + "/test/urdf/kinematic_arm.urdf", o);
    ADD_FAILURE() << "loaded";
  } catch (const LoadError& e) {
    EXPECT_NE(std::string(e.what()).find("dof 'joint_1' is held"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace mechanism_sim
