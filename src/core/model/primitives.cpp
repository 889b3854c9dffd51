// Constraint primitives of the seed lecture (shared/seed), with gamma derived by
// differentiating each equation twice along a motion (notation.h).
#include "mechanism_sim/core/model/primitives.h"

#include <cmath>

namespace mechanism_sim {

void fixedVector(const BodyKin& b, const Vector3d& ap, FixedVector& f, bool rates) {
  f.a = b.A_Oi * ap;
  f.a_th = -timesTilde(b.A_Oi, ap);  // (8.10): delta a = -A_Oi tilde(a') dtheta'
  if (!rates) {
    f.a_dot.setZero(), f.a_cen.setZero();
    return;
  }
  const Vector3d wxa = b.w.cross(ap);
  f.a_dot = b.A_Oi * wxa;
  f.a_cen = b.A_Oi * b.w.cross(wxa);
}

void gap(const BodyKin& bi, const Vector3d& sp_iB, const BodyKin& bj, const Vector3d& sp_jB, Gap& g, bool rates) {
  g.d = bj.r + bj.A_Oi * sp_jB - bi.r - bi.A_Oi * sp_iB;
  if (rates) {
    const Vector3d wsi = bi.w.cross(sp_iB), wsj = bj.w.cross(sp_jB);
    g.d_dot = bj.v + bj.A_Oi * wsj - bi.v - bi.A_Oi * wsi;
    g.d_cen = bj.A_Oi * bj.w.cross(wsj) - bi.A_Oi * bi.w.cross(wsi);
  } else {
    g.d_dot.setZero(), g.d_cen.setZero();
  }
  // (7.16): delta d = delta r_j - A_Oj tilde(sp_jB) dtheta_j - delta r_i + A_Oi tilde(sp_iB) dtheta_i
  g.d_thi = timesTilde(bi.A_Oi, sp_iB);
  g.d_thj = -timesTilde(bj.A_Oi, sp_jB);
}

// (8.11)  delta C(n1) = -{a'_i^T A_ij tilde(a'_j) dtheta_j + a'_j^T A_ji tilde(a'_i) dtheta_i}
Row Cn1(const FixedVector& ai, const FixedVector& aj) {
  Row row;
  row.Phi = ai.a.dot(aj.a);
  row.Phi_dot = ai.a_dot.dot(aj.a) + ai.a.dot(aj.a_dot);
  row.J.segment<3>(3) = aj.a.transpose() * ai.a_th;
  row.J.segment<3>(9) = ai.a.transpose() * aj.a_th;
  row.gamma = -(ai.a_cen.dot(aj.a) + 2.0 * ai.a_dot.dot(aj.a_dot) + ai.a.dot(aj.a_cen));
  return row;
}

// (8.13)  delta C(n2) = a'_i^T A_Oi^T (delta r_j - A_Oj tilde(sp_jB) dtheta_j - delta r_i
//                        + A_Oi tilde(sp_iB) dtheta_i) - d^T A_Oi tilde(a'_i) dtheta_i
Row Cn2(const FixedVector& ai, const Gap& d) {
  Row row;
  row.Phi = ai.a.dot(d.d);
  row.Phi_dot = ai.a_dot.dot(d.d) + ai.a.dot(d.d_dot);
  row.J.segment<3>(0) = -ai.a.transpose();
  row.J.segment<3>(3) = ai.a.transpose() * d.d_thi + d.d.transpose() * ai.a_th;
  row.J.segment<3>(6) = ai.a.transpose();
  row.J.segment<3>(9) = ai.a.transpose() * d.d_thj;
  row.gamma = -(ai.a_cen.dot(d.d) + 2.0 * ai.a_dot.dot(d.d_dot) + ai.a.dot(d.d_cen));
  return row;
}

// (8.15)  delta C(p1) = -tilde(a_i) A_Oj tilde(a'_j) dtheta_j + tilde(a_j) A_Oi tilde(a'_i) dtheta_i
Rows3 Cp1(const FixedVector& ai, const FixedVector& aj) {
  Rows3 rows;
  rows.J.setZero();
  rows.Phi = ai.a.cross(aj.a);
  rows.J.block<3, 3>(0, 3) = -tilde(aj.a) * ai.a_th;
  rows.J.block<3, 3>(0, 9) = tilde(ai.a) * aj.a_th;
  rows.gamma = -(ai.a_cen.cross(aj.a) + 2.0 * ai.a_dot.cross(aj.a_dot) + ai.a.cross(aj.a_cen));
  return rows;
}

// (8.17)  delta C(p2) = A_Oi tilde(a'_i) A_Oi^T (delta d) + tilde(d) A_Oi tilde(a'_i) dtheta_i
Rows3 Cp2(const FixedVector& ai, const Gap& d) {
  Rows3 rows;
  const Matrix3d at = tilde(ai.a);
  rows.Phi = ai.a.cross(d.d);
  rows.J.block<3, 3>(0, 0) = -at;
  rows.J.block<3, 3>(0, 3) = at * d.d_thi - tilde(d.d) * ai.a_th;
  rows.J.block<3, 3>(0, 6) = at;
  rows.J.block<3, 3>(0, 9) = at * d.d_thj;
  rows.gamma = -(ai.a_cen.cross(d.d) + 2.0 * ai.a_dot.cross(d.d_dot) + ai.a.cross(d.d_cen));
  return rows;
}

// Spherical joint: d_ij = 0, delta d_ij as in (7.16).
Rows3 Cpoint(const Gap& d) {
  Rows3 rows;
  rows.Phi = d.d;
  rows.J.block<3, 3>(0, 0) = -Matrix3d::Identity();
  rows.J.block<3, 3>(0, 3) = d.d_thi;
  rows.J.block<3, 3>(0, 6) = Matrix3d::Identity();
  rows.J.block<3, 3>(0, 9) = d.d_thj;
  rows.gamma = -d.d_cen;
  return rows;
}

// phi = atan2(s, c):  delta phi = (c delta s - s delta c) / (c^2 + s^2).
// phi_ddot = (c s_ddot - s c_ddot)/rho2 - 2 phi_dot (c c_dot + s s_dot)/rho2, and with
// c_ddot = J_c a - gamma_c (likewise s) the part free of a gives gamma below.
Row angleOf(const Row& c, const Row& s, double phi_ref) {
  Row row;
  const double rho2 = c.Phi * c.Phi + s.Phi * s.Phi;
  row.Phi = unwrapNear(std::atan2(s.Phi, c.Phi), phi_ref);
  row.J = (c.Phi * s.J - s.Phi * c.J) / rho2;
  row.Phi_dot = (c.Phi * s.Phi_dot - s.Phi * c.Phi_dot) / rho2;
  row.gamma = (c.Phi * s.gamma - s.Phi * c.gamma) / rho2 +
              2.0 * row.Phi_dot * (c.Phi * c.Phi_dot + s.Phi * s.Phi_dot) / rho2;
  return row;
}

// The seed defines phi through C(phi) = bx_i^T bx_j - cos(phi) = 0 (A8.9), whose slope
// vanishes at phi = n pi, exactly where a screw starts. Departure from the seed: we use
// the atan2 of the sine and cosine components, which has full rank at every angle.
Row relativeAngle(const FixedVector& bx_i, const FixedVector& by_i, const FixedVector& bx_j,
                  double phi_ref) {
  return angleOf(Cn1(bx_i, bx_j), Cn1(by_i, bx_j), phi_ref);
}

// (angleOf's Phi of the two C(n1) values)
double relativeAngleValue(const Vector3d& bx_i, const Vector3d& by_i, const Vector3d& bx_j, double phi_ref) {
  return unwrapNear(std::atan2(by_i.dot(bx_j), bx_i.dot(bx_j)), phi_ref);
}

// (7.38)  delta phi = e'_z^T (A_ij dtheta'_j - dtheta'_i)
Row12 variation738(const BodyKin& bi, const BodyKin& bj, const Vector3d& ezp_i) {
  Row12 J = Row12::Zero();
  J.segment<3>(3) = -ezp_i.transpose();
  J.segment<3>(9) = ezp_i.transpose() * bi.A_Oi.transpose() * bj.A_Oi;
  return J;
}

// (A8.8)  C(sc) = C(n2)(bz_i, d_ij) - alpha (phi - phi0); its variation is (A8.10).
Row Csc(const FixedVector& bz_i, const Gap& d, const Row& phi, double alpha, double phi0) {
  const Row n2 = Cn2(bz_i, d);
  Row row;
  row.Phi = n2.Phi - alpha * (phi.Phi - phi0);
  row.Phi_dot = n2.Phi_dot - alpha * phi.Phi_dot;
  row.J = n2.J - alpha * phi.J;
  row.gamma = n2.gamma - alpha * phi.gamma;
  return row;
}

// (A8.10) as typeset reads "- bz'_i^T A_ij (tilde(s'_i^B) + alpha I) dtheta_j". The running
// derivation above it (and a finite difference) gives tilde(s'_j^B): corrected here.
//   delta C(sc) = bz'^T A_Oi^T delta r_j - bz'^T A_Oi^T delta r_i
//               - bz'^T A_ij (tilde(sp_jB) + alpha I) dtheta_j
//               + {bz'^T (tilde(sp_iB) + alpha I) - d^T A_Oi tilde(bz')} dtheta_i
Row12 variationA810(const BodyKin& bi, const Vector3d& sp_iB, const BodyKin& bj,
                    const Vector3d& sp_jB, const Vector3d& bzp_i, double alpha) {
  const Matrix3d A_ij = bi.A_Oi.transpose() * bj.A_Oi;
  const Vector3d d = bj.r + bj.A_Oi * sp_jB - bi.r - bi.A_Oi * sp_iB;
  const Matrix3d I = Matrix3d::Identity();
  Row12 J;
  J.segment<3>(0) = -bzp_i.transpose() * bi.A_Oi.transpose();
  J.segment<3>(3) = bzp_i.transpose() * (tilde(sp_iB) + alpha * I) -
                    d.transpose() * bi.A_Oi * tilde(bzp_i);
  J.segment<3>(6) = bzp_i.transpose() * bi.A_Oi.transpose();
  J.segment<3>(9) = -bzp_i.transpose() * A_ij * (tilde(sp_jB) + alpha * I);
  return J;
}

}  // namespace mechanism_sim
