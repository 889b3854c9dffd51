// Random trees for the joint-space tests: every joint type, either orientation, an optional
// floating body, any length scale; random joint states; the absolute kinematics of a State.
#pragma once
#include <algorithm>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "bodies.h"
#include "core/joint_space/tree.h"
#include "random_loops.h"

namespace mechanism_sim {
namespace test_util {

inline const char* const kTypes[] = {"revolute", "prismatic", "cylindrical", "screw",
                              "universal", "spherical", "planar",    "fixed"};

// A random tree: bodies numbered in a shuffled order (parents not always first), each
// joined to a random earlier node by a random joint type, written parent-first or
// child-first; one body (with `free_body`) joined to nothing, so it and its subtree float.
// Lengths scale with `length`; gravity is g0 times `gravity_factor` (mm units: 1000).
struct RandomTree {
  std::unique_ptr<System> sys;
  double length = 1.0;
};

inline RandomTree randomTree(unsigned seed, int n, bool free_body, double length = 1.0, double gravity_factor = 1.0,
                      const char* only_type = nullptr) {
  std::mt19937 rng(seed);
  RandomTree t;
  t.length = length;
  t.sys = std::make_unique<System>();
  System& sys = *t.sys;
  sys.gravity = Vector3d(0, 0, -9.81 * gravity_factor);
  Body ground;
  ground.name = "ground";
  sys.bodies.push_back(ground);
  std::vector<int> body_of(n + 1, 0);  // node -> body index
  std::vector<int> perm(n);
  for (int k = 0; k < n; ++k) perm[k] = k + 1;
  std::shuffle(perm.begin(), perm.end(), rng);
  for (int k = 1; k <= n; ++k) body_of[k] = perm[k - 1];
  sys.bodies.resize(n + 1);
  for (int k = 1; k <= n; ++k) {
    const double m = uniform(rng, 0.5, 2.0);
    // principal moments within a factor 2 of each other: the triangle inequality holds
    const Vector3d moments(uniform(rng, 0.05, 0.1), uniform(rng, 0.05, 0.1), uniform(rng, 0.05, 0.1));
    const Matrix3d R = randomRotation(rng);
    Body b = mechanism_sim::body("b" + std::to_string(k), m, R * (m * length * length * moments).asDiagonal() * R.transpose(),
                  Vector3d::Zero());
    sys.bodies[body_of[k]] = b;
  }
  const int free_node = free_body ? 1 + static_cast<int>(rng() % n) : -1;
  for (int k = 1; k <= n; ++k) {
    if (k == free_node) continue;
    const int parent_node = static_cast<int>(rng() % k);  // 0 .. k-1 (0: ground)
    const int parent = parent_node == 0 ? 0 : body_of[parent_node];
    const int child = body_of[k];
    const std::string type = only_type ? only_type : kTypes[rng() % 8];
    JointParams params;
    if (type == "screw") params.alpha = uniform(rng, -0.1, 0.1) * length, params.phi0 = uniform(rng, -1, 1);
    const JointFrame fp = frame(length * Vector3d(uniform(rng, -0.5, 0.5), uniform(rng, -0.5, 0.5), uniform(rng, -0.5, 0.5)),
                                randomRotation(rng));
    const JointFrame fc = frame(length * Vector3d(uniform(rng, -0.5, 0.5), uniform(rng, -0.5, 0.5), uniform(rng, -0.5, 0.5)),
                                randomRotation(rng));
    const bool reversed = uniform(rng, 0, 1) < 0.3;
    const std::string name = "j" + std::to_string(k) + "_" + type + (reversed ? "_rev" : "");
    std::unique_ptr<Joint> j = reversed ? makeJoint(type, name, child, fc, parent, fp, params)
                                        : makeJoint(type, name, parent, fp, child, fc, params);
    sys.joints.push_back(j.get());
    sys.joint_constraint.push_back(sys.numConstraints());
    sys.damping.push_back({0, 0, 0});
    sys.friction.push_back({0, 0, 0});
    sys.constraints.push_back(std::shared_ptr<Constraint>(std::move(j)));
  }
  sys.finalize();
  return t;
}

// A random joint state: angles anywhere (universal's second away from gimbal lock),
// translations and rates of the model's size.
inline void randomJointState(const TreeModel& model, const System& sys, unsigned seed, double length, Eigen::VectorXd& q,
                      Eigen::VectorXd& qd) {
  std::mt19937 rng(seed);
  q = model.neutralPositions(sys);
  qd = Eigen::VectorXd::Zero(model.nv);
  const double pi = 3.141592653589793;
  for (const TreeLink& L : model.links) {
    double* x = q.data() + L.iq;
    double* v = qd.data() + L.iv;
    auto angle = [&] { return uniform(rng, -pi, pi); };
    auto travel = [&] { return uniform(rng, -0.3, 0.3) * length; };
    auto rate = [&] { return uniform(rng, -2, 2); };
    auto speed = [&] { return uniform(rng, -0.5, 0.5) * length; };
    switch (L.kind) {
      case TreeJointKind::kFixed: break;
      case TreeJointKind::kRevolute:
      case TreeJointKind::kScrew: x[0] = angle(), v[0] = rate(); break;
      case TreeJointKind::kPrismatic: x[0] = travel(), v[0] = speed(); break;
      case TreeJointKind::kCylindrical: x[0] = angle(), x[1] = travel(), v[0] = rate(), v[1] = speed(); break;
      case TreeJointKind::kUniversal:
        x[0] = angle(), x[1] = uniform(rng, -1.2, 1.2), v[0] = rate(), v[1] = rate();
        break;
      case TreeJointKind::kPlanar:
        x[0] = travel(), x[1] = travel(), x[2] = angle();
        v[0] = speed(), v[1] = speed(), v[2] = rate();
        break;
      case TreeJointKind::kSpherical: {
        // a rotation of angle below pi (the rotation vector is then unique)
        const Vector3d axis = Vector3d(uniform(rng, -1, 1), uniform(rng, -1, 1), uniform(rng, -1, 1)).normalized();
        const Quaterniond Q(Eigen::AngleAxisd(uniform(rng, 0, 3.0), axis));
        x[0] = Q.w(), x[1] = Q.x(), x[2] = Q.y(), x[3] = Q.z();
        v[0] = rate(), v[1] = rate(), v[2] = rate();
        break;
      }
      case TreeJointKind::kFree: {
        const Quaterniond Q(randomRotation(rng));
        x[0] = travel(), x[1] = travel(), x[2] = travel();
        x[3] = Q.w(), x[4] = Q.x(), x[5] = Q.y(), x[6] = Q.z();
        for (int k = 0; k < 3; ++k) v[k] = speed(), v[3 + k] = rate();
        break;
      }
    }
  }
}

inline std::vector<BodyKin> kinematicsOf(const System& sys, const State& s) {
  std::vector<BodyKin> kin(sys.numBodies());
  for (int b = 1; b <= sys.nb; ++b) {
    const int k = b - 1;
    kin[b].r = s.x.segment<3>(7 * k);
    kin[b].A_Oi = Quaterniond(s.x(7 * k + 3), s.x(7 * k + 4), s.x(7 * k + 5), s.x(7 * k + 6)).toRotationMatrix();
    kin[b].v = s.u.segment<3>(6 * k);
    kin[b].w = s.u.segment<3>(6 * k + 3);
  }
  return kin;
}

}  // namespace test_util
}  // namespace mechanism_sim
