// Comparing two runs of one mechanism (the joint formulation against the absolute one).
#pragma once
#include <algorithm>
#include <cmath>

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

}  // namespace test_util
}  // namespace mechanism_sim
