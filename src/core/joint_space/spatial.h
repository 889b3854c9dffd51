// Spatial algebra of the joint-space tree, after Featherstone, "Rigid Body Dynamics
// Algorithms" (RBDA), Springer 2008, chapter 2: motion vectors m = (omega; v_O), force
// vectors f = (n_O; f), both in Plucker coordinates of a body's centre-of-mass frame with
// the body's axes (the seed lecture's r_i and A_Oi), so a body's spatial inertia is
// diag(J'_i, m_i 1). Private to the joint-space formulation.
#pragma once
#include <Eigen/Core>

#include "core/joint_space/tree.h"

namespace mechanism_sim {

// ---- spatial algebra (RBDA ch. 2: Plucker transforms, spatial cross products)

// m1 x m2, the motion cross product (RBDA ch. 2, crm).
inline Vector6d crossMotion(const Vector6d& m1, const Vector6d& m2) {
  Vector6d out;
  out.head<3>() = m1.head<3>().cross(m2.head<3>());
  out.tail<3>() = m1.head<3>().cross(m2.tail<3>()) + m1.tail<3>().cross(m2.head<3>());
  return out;
}

// m x* f, the force cross product (RBDA ch. 2, crf).
inline Vector6d crossForce(const Vector6d& m, const Vector6d& f) {
  Vector6d out;
  out.head<3>() = m.head<3>().cross(f.head<3>()) + m.tail<3>().cross(f.tail<3>());
  out.tail<3>() = m.head<3>().cross(f.tail<3>());
  return out;
}

// X^T I X: an inertia in B coordinates back to A coordinates (table 7.1's X^T I^a X), with
// the blocks of X = [E 0; -E rho~ E] written out: with I = [I11 I12; I12^T I22] in A-rotated
// components (E^T I E), X^T I X = [I11 + rho~ I12^T - I12 rho~ - rho~ I22 rho~, I12 + rho~ I22;
// .., I22] (all products 3x3: cheaper than the 6x6 product, which multiplies zeros).
// The products with rho~ are cross products (rho~ M: rho x each column; M rho~: each row
// crossed with rho, (m^T rho~)^T = m x rho), and the symmetric blocks' rotations fill one
// triangle (I is symmetric: an articulated or composite inertia).
inline Matrix3d rotateSymmetric(const Matrix3d& Et, const Matrix3d& S) {  // Et S Et^T
  const Matrix3d T = Et * S;
  Matrix3d out;
  for (int i = 0; i < 3; ++i)
    for (int j = i; j < 3; ++j) out(i, j) = out(j, i) = T.row(i).dot(Et.row(j));
  return out;
}

inline void addTransformedInertia(const Matrix3d& E, const Vector3d& rho, const Matrix6d& I, Matrix6d& target) {
  const Matrix3d Et = E.transpose();
  const Matrix3d I11 = rotateSymmetric(Et, I.topLeftCorner<3, 3>());
  const Matrix3d I12 = Et * I.topRightCorner<3, 3>() * E;
  const Matrix3d I22 = rotateSymmetric(Et, I.bottomRightCorner<3, 3>());
  Matrix3d B = I12;  // top-right block: I12 + rho~ I22
  for (int c = 0; c < 3; ++c) B.col(c) += rho.cross(I22.col(c));
  // top-left: I11 + rho~ I12^T - B rho~ (= I11 + rho~ I12^T - I12 rho~ - rho~ I22 rho~), symmetric
  Matrix3d P, Q;  // rho~ I12^T (columns rho x row j of I12) and B rho~ (rows: row i of B x rho)
  for (int j = 0; j < 3; ++j) {
    P.col(j) = rho.cross(I12.row(j).transpose());
    Q.row(j) = B.row(j).transpose().cross(rho).transpose();
  }
  Matrix3d T;
  for (int i = 0; i < 3; ++i)
    for (int j = i; j < 3; ++j) T(i, j) = T(j, i) = I11(i, j) + P(i, j) - Q(i, j);
  target.topLeftCorner<3, 3>() += T;
  target.topRightCorner<3, 3>() += B;
  target.bottomLeftCorner<3, 3>() += B.transpose();
  target.bottomRightCorner<3, 3>() += I22;
}

// Body spatial inertia at the centre of mass times a motion vector: (J' omega; m v).
inline Vector6d inertiaTimes(const Body& B, const Vector6d& m) {
  Vector6d out;
  out.head<3>() = B.Jp * m.head<3>();
  out.tail<3>() = B.m * m.tail<3>();
  return out;
}

}  // namespace mechanism_sim
