// Mechanisms built part by part at a file's pose, for the assembly tests and the coupler
// embedding's: bodies at their centres, joints given by points and axes in global
// components at that pose (where they differ the joint starts open); the planar four-bar
// with its two closed branches.
#pragma once
#include <cmath>
#include <vector>

#include "bodies.h"
#include "mechanism_sim/core/mechanism.h"

namespace mechanism_sim {
namespace test_util {
namespace assembly {

using test_util::frame;
constexpr double kPi = 3.141592653589793;

inline Matrix3d axisTo(const Vector3d& z) {  // a rotation whose z column is z
  return Eigen::Quaterniond::FromTwoVectors(Vector3d::UnitZ(), z.normalized()).toRotationMatrix();
}
inline Matrix3d aboutZ(double a) { return Eigen::AngleAxisd(a, Vector3d::UnitZ()).toRotationMatrix(); }

// Bodies at their centres with identity orientations. A joint's frames are given by a
// point and axes on each body (in global components at the file's pose): where they differ,
// the file's pose leaves the joint open; or by one point P and one axis on both bodies, so
// that the joint starts at 0.
struct Parts {
  Mechanism& m;
  std::vector<Vector3d> r{Vector3d::Zero()};
  int add(const char* name, double mass, const Vector3d& at) {
    r.push_back(at);
    return m.addBody(test_util::body(name, mass, mass * Vector3d(0.004, 0.005, 0.006), at));
  }
  int join(const char* type, const char* name, int parent, const Vector3d& Pp, const Matrix3d& Rp, int child,
           const Vector3d& Pc, const Matrix3d& Rc) {
    return m.addJoint(makeJoint(type, name, parent, frame(Pp - r[parent], Rp), child, frame(Pc - r[child], Rc)));
  }
  int join(const char* type, const char* name, int parent, int child, const Vector3d& P, const Vector3d& axis) {
    const Matrix3d R = axisTo(axis);
    return join(type, name, parent, P, R, child, P, R);
  }
  // Where a point of body b (given at the file's pose) is now.
  Vector3d now(int b, const Vector3d& P) const { return m.position(b) + m.rotation(b) * (P - r[b]); }
};

inline Vector3d inPlane(double angle) { return Vector3d(std::cos(angle), 0, std::sin(angle)); }  // x-z plane

// The planar four-bar in x-z (axes along global y): ground pivots O and D = (d, 0, 0),
// crank a, coupler b, rocker c. At the file's pose the crank points at theta0, the coupler
// at beta0 from the crank's end B0, the rocker at gamma0 from D; the closing joint's frames
// sit at the coupler's end C1 and the rocker's end C2, the rocker's turned by `turn` about
// the axis.
struct FourBar {
  double a = 0.4, b = 1.0, c = 0.9, d = 1.0;
  double theta0 = 1.2, beta0 = 0.3, gamma0 = 2.2, turn = 3.0;
  Vector3d O = Vector3d::Zero(), D, B0, C1, C2;
  int crank = 0, coupler = 0, rocker = 0, closure = -1, crank_joint = -1, rocker_joint = -1;

  void build(Parts& p) {
    D = Vector3d(d, 0, 0);
    B0 = O + a * inPlane(theta0);
    C1 = B0 + b * inPlane(beta0);
    C2 = D + c * inPlane(gamma0);
    const Matrix3d Y = axisTo(Vector3d::UnitY());
    crank = p.add("crank", 0.5, 0.5 * (O + B0));
    coupler = p.add("coupler", 1.0, 0.5 * (B0 + C1));
    rocker = p.add("rocker", 0.8, 0.5 * (D + C2));
    crank_joint = p.join("revolute", "crank_joint", 0, O, Y, crank, O, Y);
    p.join("revolute", "coupler_joint", crank, B0, Y, coupler, B0, Y);
    rocker_joint = p.join("revolute", "rocker_joint", 0, D, Y, rocker, D, Y);
    closure = p.join("revolute", "closure", coupler, C1, Y, rocker, C2, Y * aboutZ(turn));
  }

  // The rocker's angle where the four-bar, assembled with no limit and no target, closes.
  double freeRockerAngle() const {
    Mechanism m;
    Parts p{m};
    FourBar fb = *this;
    fb.build(p);
    m.assemble();
    return m.jointPosition(fb.rocker_joint, 0);
  }

  // The two closed poses' coupler-rocker points for the crank's end at B: the circles
  // about B (radius b) and D (radius c) meet at `up` (on the side of n, B-D turned by +90
  // degrees in x-z, side() > 0) and `down`.
  void branches(const Vector3d& B, Vector3d& up, Vector3d& down) const {
    const Vector3d BD = D - B;
    const double l = BD.norm(), x = (l * l + b * b - c * c) / (2 * l), h = std::sqrt(b * b - x * x);
    const Vector3d e = BD / l, n(-e.z(), 0, e.x());  // n: e turned by +90 degrees in x-z
    up = B + x * e + h * n;
    down = B + x * e - h * n;
  }
};

// Which side of the line from B to D point C lies on (+1: the side of n above).
inline double side(const Vector3d& B, const Vector3d& D, const Vector3d& C) {
  const Vector3d e = D - B, w = C - B;
  return e.x() * w.z() - e.z() * w.x();
}

}  // namespace assembly
}  // namespace test_util
}  // namespace mechanism_sim
