// The seed's constraint primitives C(n1), C(n2), C(p1), C(p2), point coincidence,
// the relative rotation angle (7.38) and the screw constraint (A8.8), each with its
// value Phi, its variation (Jacobian row(s) over [r_i, theta'_i, r_j, theta'_j])
// and its acceleration right-hand side gamma. See notation.h for the symbols.
#pragma once
#include "mechanism_sim/core/model/math.h"

namespace mechanism_sim {

// Kinematic state of one body as the constraints see it. Ground: r = 0, A = I, v = w = 0.
struct BodyKin {
  Vector3d r = Vector3d::Zero();
  Matrix3d A_Oi = Matrix3d::Identity();
  Vector3d v = Vector3d::Zero();
  Vector3d w = Vector3d::Zero();  // omega', body components
};

// A unit vector fixed in a body: a = A_Oi a'.
struct FixedVector {
  Vector3d a;      // global components
  Matrix3d a_th;   // da/dtheta' = -A_Oi tilde(a')                         (8.10)
  Vector3d a_dot;  // A_Oi (w x a')
  Vector3d a_cen;  // A_Oi (w x (w x a')): the part of a_ddot free of w_dot
};
// (Into f: a joint's geometry fills its members in place.) Without rates: a and a_th alone,
// what the value and the Jacobian read (a_dot and a_cen zero).
void fixedVector(const BodyKin& b, const Vector3d& ap, FixedVector& f, bool rates = true);
inline FixedVector fixedVector(const BodyKin& b, const Vector3d& ap) {
  FixedVector f;
  fixedVector(b, ap, f);
  return f;
}

// d_ij = r_j + A_Oj sp_jB - r_i - A_Oi sp_iB and its derivatives.
struct Gap {
  Vector3d d, d_dot, d_cen;
  Matrix3d d_thi;  // dd/dtheta'_i = A_Oi tilde(sp_iB)                    (7.16)
  Matrix3d d_thj;  // dd/dtheta'_j = -A_Oj tilde(sp_jB)
};
// Without rates: d, d_thi and d_thj alone (d_dot and d_cen zero).
void gap(const BodyKin& bi, const Vector3d& sp_iB, const BodyKin& bj, const Vector3d& sp_jB, Gap& g,
         bool rates = true);
inline Gap gap(const BodyKin& bi, const Vector3d& sp_iB, const BodyKin& bj, const Vector3d& sp_jB) {
  Gap g;
  gap(bi, sp_iB, bj, sp_jB, g);
  return g;
}

// One scalar equation: value, time derivative, Jacobian row and gamma.
struct Row {
  double Phi = 0, Phi_dot = 0, gamma = 0;
  Row12 J = Row12::Zero();
};
// Three rows (the seed's 3-component primitives).
struct Rows3 {
  Vector3d Phi, gamma;
  Eigen::Matrix<double, 3, 12> J;
};

// C(n1)(a_i, a_j) = a_i^T a_j = 0                                           (8.11)
Row Cn1(const FixedVector& ai, const FixedVector& aj);
// C(n2)(a_i, d_ij) = a_i^T d_ij = 0                                         (8.13)
Row Cn2(const FixedVector& ai, const Gap& d);
// C(p1)(a_i, a_j) = tilde(a_i) a_j = 0, 3 rows of rank 2                     (8.15)
Rows3 Cp1(const FixedVector& ai, const FixedVector& aj);
// C(p2)(a_i, d_ij) = tilde(a_i) d_ij = 0, 3 rows of rank 2                   (8.17)
Rows3 Cp2(const FixedVector& ai, const Gap& d);
// Point coincidence d_ij = 0 (spherical joint), 3 rows of rank 3.
Rows3 Cpoint(const Gap& d);

// Angle phi = atan2(s, c) of two rows that are (proportional to) its sine and
// cosine, on the branch nearest phi_ref (so that it counts whole turns).
Row angleOf(const Row& c, const Row& s, double phi_ref);
// Relative rotation of body j about bz_i: phi = atan2(by_i . bx_j, bx_i . bx_j).
// Its variation is exact in every pose; on the joint axis (bz_i || bz_j) it equals
// the seed's (7.38): delta phi = bzp_i^T (A_ij dtheta_j - dtheta_i).
Row relativeAngle(const FixedVector& bx_i, const FixedVector& by_i, const FixedVector& bx_j,
                  double phi_ref);
// Its value alone, from the vectors' global components (FixedVector::a): the same
// operations as relativeAngle's Phi, so the same bits, without the variation and the rates.
double relativeAngleValue(const Vector3d& bx_i, const Vector3d& by_i, const Vector3d& bx_j, double phi_ref);
// The seed's (7.38) as printed, for checks: delta phi = e'_z^T (A_ij dtheta_j - dtheta_i).
Row12 variation738(const BodyKin& bi, const BodyKin& bj, const Vector3d& ezp_i);

// C(sc) = C(n2)(bz_i, d_ij) - alpha (phi - phi0) = 0                          (A8.8)
Row Csc(const FixedVector& bz_i, const Gap& d, const Row& phi, double alpha, double phi0);
// The seed's (A8.10) with the typo corrected (see primitives.cpp), for checks.
Row12 variationA810(const BodyKin& bi, const Vector3d& sp_iB, const BodyKin& bj,
                    const Vector3d& sp_jB, const Vector3d& bzp_i, double alpha);

}  // namespace mechanism_sim
