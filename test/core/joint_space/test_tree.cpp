// The joint-space tree model (tree.cpp): motion subspaces against the relative poses'
// derivatives, on random trees of every joint type (either orientation); loops cut into
// closures; damping and friction left to the steppers.
#include <gtest/gtest.h>

#include "bodies.h"
#include "compare.h"
#include "random_trees.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "core/joint_space/closure_solver.h"
#include "core/joint_space/tree.h"
#include "core/joint_space/joint_stepper.h"
#include "mechanism_sim/core/models.h"
#include "core/absolute/stepper.h"

namespace mechanism_sim {
namespace {

using test_util::frame;
using test_util::uniform;


// S q_dot and the bias c against central differences of JointTypeInfo::relativePose
// (through jointTransform's pose, which the ABA uses), each type, both orientations.
TEST(JointSpace, MotionSubspacesMatchTheRelativePoseDerivatives) {
  std::mt19937 rng(7);
  for (int trial = 0; trial < 4; ++trial)
    for (int type = 0; type < 9; ++type)
      for (int reversed = 0; reversed < 2; ++reversed) {
        TreeLink L;
        L.kind = static_cast<TreeJointKind>(type);
        L.reversed = reversed;
        L.params.alpha = 0.07, L.params.phi0 = 0.3;
        const int nqs[] = {0, 1, 1, 2, 1, 2, 4, 3, 7}, nvs[] = {0, 1, 1, 2, 1, 2, 3, 3, 6};
        L.nq = nqs[type], L.nv = nvs[type];
        Eigen::VectorXd q(L.nq), qd(L.nv);
        for (int k = 0; k < L.nq; ++k) q(k) = uniform(rng, -1.2, 1.2);
        for (int k = 0; k < L.nv; ++k) qd(k) = uniform(rng, -2, 2);
        auto normalize = [&](Eigen::VectorXd& x) {
          if (L.kind == TreeJointKind::kSpherical) x.normalize();
          if (L.kind == TreeJointKind::kFree) x.segment<4>(3).normalize();
        };
        normalize(q);
        // q(t) along the rates: exact for the quaternions (exp of the constant rate)
        auto at = [&](double h) {
          Eigen::VectorXd x = q;
          if (L.kind == TreeJointKind::kSpherical) {
            const Quaterniond Q = expRotation(h * Vector3d(qd(0), qd(1), qd(2))) * Quaterniond(q(0), q(1), q(2), q(3));
            x << Q.w(), Q.x(), Q.y(), Q.z();
          } else if (L.kind == TreeJointKind::kFree) {
            const Quaterniond P = Quaterniond(q(3), q(4), q(5), q(6)) * expRotation(h * Vector3d(qd(3), qd(4), qd(5)));
            x.head<3>() += h * qd.head<3>();
            x.segment<4>(3) << P.w(), P.x(), P.y(), P.z();
          } else {
            x += h * qd;
          }
          return x;
        };
        Matrix3d R, Rp, Rm;
        Vector3d t, tp, tm;
        MotionSubspace S, Sp, Sm;
        Vector6d c, cp, cm;
        const double h = 1e-5;
        const Eigen::VectorXd q_p = at(h), q_m = at(-h);
        jointTransform(L, q.data(), qd.data(), R, t, S, c);
        jointTransform(L, q_p.data(), qd.data(), Rp, tp, Sp, cp);
        jointTransform(L, q_m.data(), qd.data(), Rm, tm, Sm, cm);
        // velocity of the child frame relative to the parent's, child components
        const Matrix3d W = R.transpose() * (Rp - Rm) / (2 * h);
        Vector6d vJ;
        vJ << W(2, 1), W(0, 2), W(1, 0), R.transpose() * (tp - tm) / (2 * h);
        const Vector6d Sqd = S * qd;
        EXPECT_LE((vJ - Sqd).norm(), 1e-8 * (1 + Sqd.norm())) << "type " << type << " reversed " << reversed;
        // the bias: the rate of change of S's coordinates along the motion
        const Vector6d cfd = (Sp * qd - Sm * qd) / (2 * h);
        EXPECT_LE((cfd - c).norm(), 1e-7 * (1 + Sqd.squaredNorm())) << "type " << type << " reversed " << reversed;
      }
}

// ---- against the absolute solver

TEST(JointSpace, LoopsAreCutJointsAndJointSpaceUnsupportedNamesThem) {
  System sys;
  Body ground;
  ground.name = "ground";
  sys.bodies.push_back(ground);
  for (int b = 1; b <= 2; ++b) sys.bodies.push_back(body("b" + std::to_string(b), 1, Matrix3d::Identity() * 0.1, Vector3d::Zero()));
  auto add = [&](std::unique_ptr<Joint> j) {
    sys.joints.push_back(j.get());
    sys.joint_constraint.push_back(sys.numConstraints());
    sys.constraints.push_back(std::shared_ptr<Constraint>(std::move(j)));
  };
  add(makeJoint("revolute", "first", 0, frame(Vector3d::Zero()), 1, frame(Vector3d::Zero())));
  add(makeJoint("revolute", "second", 1, frame(Vector3d::Zero()), 2, frame(Vector3d::Zero())));
  add(makeJoint("spherical", "closing", 2, frame(Vector3d::Zero()), 0, frame(Vector3d::Zero())));
  sys.damping.assign(3, {{0.5, 0, 0}});
  sys.finalize();
  // breadth-first from ground: the loop is cut at whichever of its joints comes last
  const TreeModel model(sys);
  ASSERT_EQ(model.cut_joints.size(), 1u);
  EXPECT_EQ(model.cut_joints[0], 1);
  EXPECT_EQ(model.joint_link[1], -1);
  EXPECT_EQ(model.nv, 1 + 3);
  const std::string why = jointSpaceUnsupported(sys);
  std::printf("jointSpaceUnsupported: %s\n", why.c_str());
  EXPECT_NE(why.find("joint 'second'"), std::string::npos) << why;
  EXPECT_EQ(jointSpaceUnsupported(sys, true), "");  // as closures (loop_closure.h)
}

TEST(JointSpace, DampingAndFrictionAreNotTheTreeModelsBusiness) {
  Mechanism mech;
  models::pendulumChain(mech, 3);
  mech.build();
  System sys = mech.system();
  sys.damping.assign(sys.numJoints(), {{0.1, 0, 0}});
  EXPECT_NO_THROW(TreeModel{sys});
  EXPECT_EQ(jointSpaceUnsupported(sys), "");
  sys.friction.assign(sys.numJoints(), {{0.1, 0, 0}});
  EXPECT_NO_THROW(TreeModel{sys});
  EXPECT_EQ(jointSpaceUnsupported(sys), "");  // an effort too (JointStepper::frictionFor)
}

// ---- cost

}  // namespace
}  // namespace mechanism_sim
