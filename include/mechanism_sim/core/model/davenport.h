// Davenport angles: a rotation as three turns about fixed unit axes taken in turn,
//   R = Rot(e0, t0) Rot(e1, t1) Rot(e2, t2),
// the axes given in the frame the first turn is about (Davenport 1973; Shuster and
// Markley, "Generalization of the Euler angles", J. Astronaut. Sci. 51, 2003). Euler and
// Tait-Bryan angles are the cases with coordinate axes. With each axis perpendicular to the
// next the three reach every rotation; the loader uses them to report a ball that a file
// writes as three revolute joints (src/urdf/massless_gimbals.h) by the file's three angles.
#pragma once
#include <array>

#include <Eigen/Core>

namespace mechanism_sim {

using Angles3 = std::array<double, 3>;

class DavenportAxes {
 public:
  // Throws UsageError unless e0 _|_ e1 and e1 _|_ e2 (to 1e-9) and each has unit length (to
  // 1e-9; they are normalized).
  DavenportAxes(const Eigen::Vector3d& e0, const Eigen::Vector3d& e1, const Eigen::Vector3d& e2);
  const Eigen::Vector3d& axis(int k) const { return e_[k]; }

  Eigen::Matrix3d rotation(const Angles3& t) const;
  // The angles of R nearest `near`: of the two solutions, each angle shifted by whole turns
  // to lie nearest its `near`, the one with the smaller sum of squared distances. The
  // middle angle fixes how e0 and Rot(e1, t1) e2 lie; where they line up (the gimbal's
  // lock) only a sum or difference of t0 and t2 is determined, and t0 stays at near[0].
  Angles3 angles(const Eigen::Matrix3d& R, const Angles3& near) const;
  // omega = J(t) t_dot, omega the angular velocity of the last frame relative to the
  // first, in the first: columns e0, Rot(e0, t0) e1, Rot(e0, t0) Rot(e1, t1) e2.
  Eigen::Matrix3d rateMatrix(const Angles3& t) const;
  // t_dot from omega (the least-norm rates at the lock, where J is singular).
  Angles3 rates(const Angles3& t, const Eigen::Vector3d& omega) const;
  // t_ddot from omega_dot (the derivative of omega's components in the first frame):
  // J t_ddot = omega_dot - J_dot t_dot.
  Angles3 accelerations(const Angles3& t, const Angles3& t_dot, const Eigen::Vector3d& omega_dot) const;

 private:
  std::array<Eigen::Vector3d, 3> e_;
  double lambda_ = 0.0;  // the angle from e2 to e0 about e1: cos = e0.e2, sin = e0.(e1 x e2)
};

}  // namespace mechanism_sim
