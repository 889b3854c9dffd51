// Comparing two runs of one mechanism (the joint formulation against the absolute one).
#pragma once
#include <algorithm>
#include <cmath>
#include <utility>

#include <Eigen/Core>

#include "mechanism_sim/core/mechanism.h"

namespace mechanism_sim {
namespace test_util {

// The largest difference of joint coordinates and body positions between two runs.
inline double difference(const Mechanism& a, const Mechanism& b) {
  double worst = 0;
  for (int k = 0; k < a.numJoints(); ++k)
    for (int c = 0; c < a.joint(k).dof(); ++c)
      worst = std::max(worst, std::fabs(a.jointPosition(k, c) - b.jointPosition(k, c)));
  for (int i = 1; i < a.numBodies(); ++i) worst = std::max(worst, (a.position(i) - b.position(i)).norm());
  return worst;
}

// The largest difference of two sets of body accelerations (6 per body: linear, angular),
// relative to the largest of acc2's (angular ones times the length scale), and at least to
// g (a mechanism its closures lock has accelerations of round-off size).
inline double accelerationDifference(const Eigen::VectorXd& acc1, const Eigen::VectorXd& acc2, int nb, double length,
                                     double g = 0) {
  double lin = 0, ang = 0, dlin = 0, dang = 0;
  for (int k = 0; k < nb; ++k) {
    lin = std::max(lin, acc2.segment<3>(6 * k).norm());
    ang = std::max(ang, acc2.segment<3>(6 * k + 3).norm());
    dlin = std::max(dlin, (acc1.segment<3>(6 * k) - acc2.segment<3>(6 * k)).norm());
    dang = std::max(dang, (acc1.segment<3>(6 * k + 3) - acc2.segment<3>(6 * k + 3)).norm());
  }
  const double A = std::max({lin, ang * length, g});
  return std::max(dlin / A, dang * length / A);
}

// From m's present state, `steps` steps of 1 ms under a varying effort on joint 0, twice:
// run, then restored to the start and run again; the two end states (equal bit for bit
// when a snapshot holds everything a step reads).
inline std::pair<State, State> runTwiceFromSnapshot(Mechanism& m, int steps) {
  const Mechanism::Snapshot snap = m.snapshot();
  auto run = [&]() {
    for (int k = 0; k < steps; ++k) {
      m.setJointEffort(0, 0, 0.5 * std::sin(0.01 * k));
      m.step(1e-3);
    }
    return m.snapshot();
  };
  State a = run();
  m.restore(snap);
  State b = run();
  return {a, b};
}

}  // namespace test_util
}  // namespace mechanism_sim
