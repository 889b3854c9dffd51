// A body for the core tests: name, mass, central inertia and initial centre of mass.
#pragma once
#include <string>

#include "mechanism_sim/core/model/system.h"

namespace mechanism_sim {

inline Body body(const std::string& name, double m, const Matrix3d& Jp, const Vector3d& r) {
  Body b;
  b.name = name;
  b.m = m;
  b.Jp = Jp;
  b.r = r;
  return b;
}

// Helpers a test takes in with `using test_util::frame; using test_util::body;` in its own
// namespace (there they hide the Matrix3d body above).
namespace test_util {

inline JointFrame frame(const Vector3d& sp, const Matrix3d& Rp = Matrix3d::Identity()) {
  JointFrame f;
  f.sp_B = sp;
  f.Rp = Rp;
  return f;
}

// principal moments on the diagonal
inline Body body(const std::string& name, double m, const Vector3d& inertia, const Vector3d& r) {
  return mechanism_sim::body(name, m, Matrix3d(inertia.asDiagonal()), r);
}

}  // namespace test_util

}  // namespace mechanism_sim
