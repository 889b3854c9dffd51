// Random trees closed by random joints, for the core tests (joint_space/test_loop_closure.cpp,
// test_random_loop_runs.cpp; the Builder also for joint_space/test_loop_closure_rows.cpp): bodies at random poses, joints of random types at random
// points with random axes, each built where its two frames coincide (joint coordinates
// zero), so the initial pose is assembled.
#pragma once
#include <cmath>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "bodies.h"
#include "mechanism_sim/core/model/couplers.h"
#include "mechanism_sim/core/model/drive.h"
#include "core/joint_space/tree.h"
#include "mechanism_sim/core/model/system.h"

namespace mechanism_sim {
namespace test_util {

inline double uniform(std::mt19937& rng, double lo, double hi) {
  return std::uniform_real_distribution<double>(lo, hi)(rng);
}
inline Matrix3d randomRotation(std::mt19937& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  return Quaterniond(n(rng), n(rng), n(rng), n(rng)).normalized().toRotationMatrix();
}

// Bodies at given poses; joints at a global point with global axes (frames coincide now).
struct Builder {
  std::unique_ptr<System> sys = std::make_unique<System>();
  double length = 1.0;
  Builder(double L, double gravity_factor) : length(L) {
    sys->gravity = Vector3d(0, 0, -9.81 * gravity_factor);
    Body ground;
    ground.name = "ground";
    sys->bodies.push_back(ground);
  }
  int addBody(double m, const Vector3d& moments, const Vector3d& r, const Matrix3d& R) {
    Body b = mechanism_sim::body("b" + std::to_string(sys->bodies.size()), m,
                                 R * (m * length * length * moments).asDiagonal() * R.transpose(), r);
    b.p = Quaterniond(R);
    sys->bodies.push_back(b);
    return static_cast<int>(sys->bodies.size()) - 1;
  }
  JointFrame frameOn(int b, const Vector3d& P, const Matrix3d& axes) const {
    JointFrame f;
    const Matrix3d A = b == 0 ? Matrix3d::Identity() : sys->bodies[b].p.toRotationMatrix();
    const Vector3d r = b == 0 ? Vector3d::Zero() : sys->bodies[b].r;
    f.sp_B = A.transpose() * (P - r);
    f.Rp = A.transpose() * axes;
    return f;
  }
  int addJoint(const std::string& type, int bi, int bj, const Vector3d& P, const Matrix3d& axes) {
    auto j = makeJoint(type, type + std::to_string(sys->joints.size()), bi, frameOn(bi, P, axes), bj, frameOn(bj, P, axes));
    sys->joints.push_back(j.get());
    sys->joint_constraint.push_back(sys->numConstraints());
    sys->constraints.push_back(std::shared_ptr<Constraint>(std::move(j)));
    return sys->numJoints() - 1;
  }
  void addCoupler(int ja, int jb, double multiplier, double offset) {
    sys->constraints.push_back(std::make_shared<CoordinateCoupler>("mimic", *sys->joints[ja], 0, *sys->joints[jb], 0,
                                                                   multiplier, offset));
  }
  void addLimit(int j, int k, double lower, double upper) {
    LimitSpec l;
    l.joint = j, l.k = k, l.lower = lower, l.upper = upper;
    sys->limits.push_back(l);
  }
  void addDrive(int j, int k, const DriveProfile& p, double q0) {
    DriveSpec d;
    d.joint = j, d.k = k, d.profile = p, d.q0 = q0;
    sys->drives.push_back(d);
  }
};

// A random tree of n bodies (random poses, joints of random types at random points) closed
// by `loops` random joints between two random bodies (or a body and ground).
inline Builder randomLoops(unsigned seed, int n, int loops, double L, double g) {
  static const char* const kTree[] = {"revolute", "prismatic", "cylindrical", "universal", "spherical", "planar", "screw"};
  static const char* const kClose[] = {"spherical", "revolute", "universal", "cylindrical"};
  std::mt19937 rng(seed);
  Builder b(L, g);
  std::vector<int> parent(n + 1, 0);
  for (int k = 1; k <= n; ++k) {
    const Vector3d r = L * Vector3d(uniform(rng, -1, 1), uniform(rng, -1, 1), uniform(rng, -1, 1));
    b.addBody(uniform(rng, 0.5, 2.0), Vector3d(uniform(rng, 0.05, 0.1), uniform(rng, 0.05, 0.1), uniform(rng, 0.05, 0.1)), r,
              randomRotation(rng));
  }
  for (int k = 1; k <= n; ++k) {
    parent[k] = static_cast<int>(rng() % k);
    const Vector3d P = L * Vector3d(uniform(rng, -1, 1), uniform(rng, -1, 1), uniform(rng, -1, 1));
    const std::string type = kTree[rng() % 7];
    if (rng() % 2) b.addJoint(type, parent[k], k, P, randomRotation(rng));
    else b.addJoint(type, k, parent[k], P, randomRotation(rng));
  }
  for (int l = 0; l < loops; ++l) {
    int a = 0, c = 0;
    while (a == c || parent[c] == a || parent[a] == c) a = static_cast<int>(rng() % (n + 1)), c = static_cast<int>(rng() % (n + 1));
    const Vector3d P = L * Vector3d(uniform(rng, -1, 1), uniform(rng, -1, 1), uniform(rng, -1, 1));
    b.addJoint(kClose[rng() % 4], a, c, P, randomRotation(rng));
  }
  return b;
}

// Whether tree coordinate k of a link is a translation (metres; the others are radians).
inline bool isTranslation(const TreeLink& link, int k) {
  return link.kind == TreeJointKind::kPrismatic || (link.kind == TreeJointKind::kCylindrical && k == 1) ||
         (link.kind == TreeJointKind::kPlanar && k < 2);
}

// The absolute State of a joint state (tree joints' tracked angles at their coordinates),
// with the context (time, limit sides, drives) of `ctx_from`, or the initial state's.
inline State absoluteFromJoint(const System& sys, const TreeModel& model, TreeWorkspace& ws, const Eigen::VectorXd& q,
                               const Eigen::VectorXd& qd, const State* ctx_from = nullptr) {
  forwardKinematics(model, q, qd, ws);
  State s = ctx_from ? *ctx_from : initialState(sys);
  absoluteState(model, ws, s.x, s.u);
  for (int j = 0; j < sys.numJoints(); ++j) {
    if (model.joint_link[j] < 0) continue;
    const Joint& J = *sys.joints[j];
    const TreeLink& L = model.links[model.joint_link[j]];
    for (int k = 0; k < J.dof(); ++k)
      if (J.trackedSlot(k) >= 0) s.tracked[sys.joint_constraint[j]][J.trackedSlot(k)] = q(L.iq + k);
  }
  return s;
}

}  // namespace test_util
}  // namespace mechanism_sim
