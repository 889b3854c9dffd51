// A body for the core tests: name, mass, central inertia and initial centre of mass.
#pragma once
#include <string>

#include "mechanism_sim/core/system.h"

namespace mechanism_sim {

inline Body body(const std::string& name, double m, const Matrix3d& Jp, const Vector3d& r) {
  Body b;
  b.name = name;
  b.m = m;
  b.Jp = Jp;
  b.r = r;
  return b;
}

}  // namespace mechanism_sim
