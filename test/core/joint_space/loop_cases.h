// Closed loops on the joint-space tree for the closures' tests: a planar four-bar and a
// spatial RSSR loop, each built at a pose where every joint's two frames coincide (joint
// coordinates zero: assembled), the closing joint last.
#pragma once
#include <cmath>
#include <random>

#include "random_loops.h"

namespace mechanism_sim {
namespace test_util {

inline Matrix3d axesWithZ(const Vector3d& z) {  // a right-handed frame with bz = z
  const Vector3d zn = z.normalized();
  const Vector3d x = (std::fabs(zn.x()) < 0.9 ? Vector3d::UnitX() : Vector3d::UnitY()).cross(zn).normalized();
  Matrix3d R;
  R << x, zn.cross(x), zn;
  return R;
}

// The planar four-bar in x-z (axes along y): crank O-B, coupler B-C, rocker D-C; not a
// parallelogram. The closing joint (coupler-rocker at C) is the last one.
inline Builder fourBar(double L, double g) {
  Builder b(L, g);
  const double pi = 3.141592653589793;
  const Vector3d O(0, 0, 0), D(1.0 * L, 0, 0);
  const Vector3d B = O + 0.35 * L * Vector3d(std::cos(1.1), 0, std::sin(1.1));
  const Vector3d C = D + 0.8 * L * Vector3d(std::cos(pi * 0.6), 0, std::sin(pi * 0.6));
  const Matrix3d I = Matrix3d::Identity();
  auto rod = [&](const Vector3d& a, const Vector3d& c, double m) {
    const Vector3d x = (c - a).normalized();
    Matrix3d R;
    R << x, Vector3d::UnitY(), x.cross(Vector3d::UnitY());
    const double l = (c - a).norm() / L;
    return b.addBody(m, Vector3d(0.002, l * l / 12, l * l / 12 + 0.002), 0.5 * (a + c), R);
  };
  const int crank = rod(O, B, 0.7), coupler = rod(B, C, 1.3), rocker = rod(D, C, 1.0);
  (void)I;
  const Matrix3d Y = axesWithZ(Vector3d::UnitY());
  b.addJoint("revolute", 0, crank, O, Y);
  b.addJoint("revolute", crank, coupler, B, Y);
  b.addJoint("revolute", 0, rocker, D, Y);
  b.addJoint("revolute", coupler, rocker, C, Y);
  return b;
}

// RSSR: crank about z at O, coupler by spheres at B and C, rocker about x at D.
inline Builder rssr(double L, double g) {
  Builder b(L, g);
  const Vector3d O(0, 0, 0), B(0.3 * L, 0.1 * L, 0), C(0.9 * L, 0.4 * L, 0.5 * L), D(1.0 * L, 0.2 * L, 0.1 * L);
  std::mt19937 rng(7);
  const int crank = b.addBody(0.8, Vector3d(0.05, 0.06, 0.07), 0.5 * (O + B), randomRotation(rng));
  const int coupler = b.addBody(1.2, Vector3d(0.08, 0.06, 0.09), 0.5 * (B + C), randomRotation(rng));
  const int rocker = b.addBody(1.0, Vector3d(0.05, 0.07, 0.06), 0.5 * (C + D), randomRotation(rng));
  b.addJoint("revolute", 0, crank, O, axesWithZ(Vector3d::UnitZ()));
  b.addJoint("spherical", crank, coupler, B, axesWithZ(Vector3d(1, 1, 0)));
  b.addJoint("revolute", 0, rocker, D, axesWithZ(Vector3d::UnitX()));
  b.addJoint("spherical", coupler, rocker, C, axesWithZ(Vector3d(0, 1, 1)));
  return b;
}

}  // namespace test_util
}  // namespace mechanism_sim
