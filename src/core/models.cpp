#include "mechanism_sim/core/models.h"

#include <cmath>
#include <string>

namespace mechanism_sim {
namespace models {

Matrix3d rodInertia(double m, double L) {
  const double radius = 0.01;
  return Vector3d(0.5 * m * radius * radius, m * L * L / 12.0, m * L * L / 12.0).asDiagonal();
}

JointFrame axisY(const Vector3d& sp) {
  JointFrame f;
  f.sp_B = sp;
  f.Rp = Eigen::AngleAxisd(-M_PI / 2, Vector3d::UnitX()).toRotationMatrix();  // z -> +y
  return f;
}

namespace {

// A rod from point a to point b (x-z plane), its body x axis along the rod.
int addRod(Mechanism& m, const std::string& name, const Vector3d& a, const Vector3d& b,
           double mass) {
  Body body;
  body.name = name;
  body.m = mass;
  const double L = (b - a).norm();
  body.Jp = rodInertia(mass, L);
  body.r = 0.5 * (a + b);
  // Rotation about +y taking x onto b - a: a negative angle lifts x towards +z.
  const Vector3d e = (b - a) / L;
  body.p = Quaterniond(Eigen::AngleAxisd(-std::atan2(e.z(), e.x()), Vector3d::UnitY()));
  return m.addBody(body);
}

// Joint frame at global point P on a body: axis along global y, expressed in the body.
JointFrame frameAt(const Body& b, const Vector3d& P) {
  const Matrix3d A = b.p.toRotationMatrix();
  JointFrame f = axisY(A.transpose() * (P - b.r));
  f.Rp = A.transpose() * f.Rp;
  return f;
}

JointFrame groundFrame(const Vector3d& P) { return axisY(P); }

}  // namespace

int pendulumChain(Mechanism& m, int n, double L, double mass, double theta0) {
  const Vector3d dir(std::cos(theta0), 0, -std::sin(theta0));
  int first = -1, prev = Mechanism::kGround;
  for (int k = 0; k < n; ++k) {
    const Vector3d a = k * L * dir, b = (k + 1) * L * dir;
    const int body = addRod(m, "link" + std::to_string(k + 1), a, b, mass);
    if (first < 0) first = body;
    const JointFrame fi = prev == Mechanism::kGround ? groundFrame(a) : frameAt(m.body(prev), a);
    m.addJoint(makeJoint("revolute", "joint" + std::to_string(k + 1), prev, fi, body,
                         frameAt(m.body(body), a)));
    prev = body;
  }
  return first;
}

int fourBarChain(Mechanism& m, int n, double r, double d, double theta0) {
  const Vector3d up(std::cos(theta0), 0, std::sin(theta0));
  std::vector<int> cranks;
  int first = -1;
  for (int k = 0; k <= n; ++k) {
    const Vector3d a(k * d, 0, 0);
    const int c = addRod(m, "crank" + std::to_string(k), a, a + r * up, 1.0);
    if (first < 0) first = c;
    cranks.push_back(c);
    m.addJoint(makeJoint("revolute", "pivot" + std::to_string(k), Mechanism::kGround,
                         groundFrame(a), c, frameAt(m.body(c), a)));
  }
  for (int k = 0; k < n; ++k) {
    const Vector3d a = Vector3d(k * d, 0, 0) + r * up, b = Vector3d((k + 1) * d, 0, 0) + r * up;
    const int c = addRod(m, "coupler" + std::to_string(k), a, b, 1.0);
    m.addJoint(makeJoint("revolute", "pin" + std::to_string(k) + "a", cranks[k],
                         frameAt(m.body(cranks[k]), a), c, frameAt(m.body(c), a)));
    m.addJoint(makeJoint("revolute", "pin" + std::to_string(k) + "b", c, frameAt(m.body(c), b),
                         cranks[k + 1], frameAt(m.body(cranks[k + 1]), b)));
  }
  return first;
}

}  // namespace models
}  // namespace mechanism_sim
