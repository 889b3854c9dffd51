// Known-answer motions of one joint type (test/core/model/joints/test_*.cpp), each run in
// both formulations: the absolute one (the joint's equations) and the joint one (its tree
// calculation), which must both give the answer.
#pragma once
#include <gtest/gtest.h>

#include "mechanism_sim/core/mechanism.h"

namespace mechanism_sim {
namespace test_util {

inline const char* const kFormulations[] = {"absolute", "joint"};

inline void useFormulation(Mechanism& m, const char* formulation) {
  IntegratorOptions o;
  o.formulation = formulation;
  m.setIntegrator(o);
}

// Steps, checking the violation bound at every step.
inline void runChecked(Mechanism& m, int steps, double h, double bound = 1e-10) {
  for (int s = 0; s < steps; ++s) {
    m.step(h);
    ASSERT_LE(m.positionViolation(), bound) << "t = " << m.time();
    ASSERT_LE(m.velocityViolation(), bound) << "t = " << m.time();
  }
}

}  // namespace test_util
}  // namespace mechanism_sim
