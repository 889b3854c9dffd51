// Joint types whose coordinates are positions (a coupler, a coupling or a limit takes
// those), random joints of them, and bodies placed where a coordinate reads a known value, for the coordinate
// constraints' tests (test_couplers.cpp, test_coupling.cpp).
#pragma once
#include <memory>
#include <random>
#include <string>

#include "fd_util.h"
#include "mechanism_sim/core/models.h"

namespace mechanism_sim {
namespace test_util {

inline Matrix3d rotZ(double x) { return Eigen::AngleAxisd(x, Vector3d::UnitZ()).toRotationMatrix(); }

// The relative motion coordinate k alone makes (the others zero): a rotation about frame
// i's z or a translation along one of its axes.
struct CoordinateCase {
  const char* type;
  int dof;
  bool (*rotation)(int k);
  int axis[3];  // the frame axis each coordinate turns about or slides along
};
inline const CoordinateCase kCoordinateCases[] = {
    {"revolute", 1, [](int) { return true; }, {2, 0, 0}},
    {"prismatic", 1, [](int) { return false; }, {2, 0, 0}},
    {"cylindrical", 2, [](int k) { return k == 0; }, {2, 2, 0}},
    {"planar", 3, [](int k) { return k == 2; }, {0, 1, 2}},
};

// A joint of case c between bodies bi and bj, its frames at random (offsets within 0.8).
inline std::unique_ptr<Joint> randomJoint(const CoordinateCase& c, const std::string& name, int bi, int bj,
                                          std::mt19937& rng) {
  JointFrame fi, fj;
  fi.sp_B = test::randomVector(rng, 0.8);
  fj.sp_B = test::randomVector(rng, 0.8);
  fi.Rp = test::randomRotation(rng);
  fj.Rp = test::randomRotation(rng);
  return makeJoint(c.type, name, bi, fi, bj, fj);
}

// Body j placed where coordinate k of the joint reads q (its other coordinates zero).
inline BodyKin placeJ(const Joint& joint, const CoordinateCase& c, int k, double q, const BodyKin& ki, BodyKin kj) {
  Matrix3d R = Matrix3d::Identity();
  Vector3d t = Vector3d::Zero();
  if (c.rotation(k)) R = rotZ(q);
  else t(c.axis[k]) = q;
  const JointFrame &fi = joint.frameI(), &fj = joint.frameJ();
  kj.A_Oi = ki.A_Oi * fi.Rp * R * fj.Rp.transpose();
  kj.r = ki.r + ki.A_Oi * (fi.sp_B + fi.Rp * t) - kj.A_Oi * fj.sp_B;
  return kj;
}

}  // namespace test_util
}  // namespace mechanism_sim
