#include "mechanism_sim/core/model/inertia.h"

#include <limits>

#include <Eigen/Eigenvalues>

#include "core/numerics.h"

namespace mechanism_sim {

Eigen::Vector3d nearestPhysicalMoments(const Eigen::Vector3d& l) {
  // Row i of A is the inequality l_i - l_j - l_k <= 0. For an active set S the nearest point
  // on {A_S mu = 0} is l - A_S^T (A_S A_S^T)^-1 A_S l; the projection onto the cone is the
  // nearest of these points that satisfies every inequality (it lies in the relative
  // interior of one face, where it is that face's own projection, and each candidate is
  // feasible, so none is nearer). S empty is l itself.
  Eigen::Matrix3d A;
  A << 1, -1, -1, -1, 1, -1, -1, -1, 1;
  const double scale = l.cwiseAbs().maxCoeff();
  Eigen::Vector3d best = Eigen::Vector3d::Zero();  // S = all three: the only common point is 0
  double best_d = l.squaredNorm();
  for (int S = 0; S < 7; ++S) {
    Eigen::Matrix<double, Eigen::Dynamic, 3> AS(0, 3);
    for (int i = 0; i < 3; ++i)
      if (S & (1 << i)) {
        AS.conservativeResize(AS.rows() + 1, 3);
        AS.row(AS.rows() - 1) = A.row(i);
      }
    Eigen::Vector3d mu = l;
    if (AS.rows() > 0) mu -= AS.transpose() * (AS * AS.transpose()).ldlt().solve(AS * l);
    if ((A * mu).maxCoeff() > 1e-14 * scale) continue;
    const double d = (mu - l).squaredNorm();
    if (d < best_d) best_d = d, best = mu;
  }
  return best;
}

Eigen::Matrix3d nearestPhysicalInertia(const Eigen::Matrix3d& J, Eigen::Vector3d* moments_before,
                                       Eigen::Vector3d* moments_after) {
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(0.5 * (J + J.transpose()));
  const Eigen::Vector3d mu = nearestPhysicalMoments(eig.eigenvalues());
  if (moments_before) *moments_before = eig.eigenvalues();
  if (moments_after) *moments_after = mu;
  if (mu == eig.eigenvalues()) return J;  // physical already: left exactly as it is
  const Eigen::Matrix3d& V = eig.eigenvectors();
  const Eigen::Matrix3d out = V * mu.asDiagonal() * V.transpose();
  return 0.5 * (out + out.transpose());
}

Eigen::Matrix<double, 6, 1> massFloor(double m, const Eigen::Matrix3d& Jp, const Eigen::Matrix<double, 6, 1>& stand_in,
                                      double mass_scale, double inertia_scale) {
  using numerics::kMassFloor;
  Eigen::Matrix<double, 6, 1> floor = Eigen::Matrix<double, 6, 1>::Zero();
  if (!(m > 1e-12 * mass_scale)) floor.head<3>() = kMassFloor * stand_in.head<3>();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig;
  eig.computeDirect(Jp, Eigen::EigenvaluesOnly);
  if (!(eig.eigenvalues()(0) > 1e-12 * inertia_scale)) floor.tail<3>() = kMassFloor * stand_in.tail<3>();
  return floor;
}

}  // namespace mechanism_sim
