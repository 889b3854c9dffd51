// Physical rotational inertias. A rigid body's principal moments about its centre of mass
// satisfy the triangle inequality, each at most the sum of the other two (which makes each
// one >= 0). Real files break it (a gripper finger with iyy = izz = 0, products of inertia
// rounded past it); the loader replaces such an inertia by the nearest physical one
// (doc/robots.md, "Inertias that are not physical").
#pragma once
#include <Eigen/Core>

namespace mechanism_sim {

// The physical inertia nearest to a symmetric J in the Frobenius norm, |J - J*|_F minimal.
// The physical inertias are the symmetric matrices whose eigenvalues lie in the convex,
// permutation-invariant cone K = {l : l_i <= l_j + l_k}; the nearest such matrix keeps J's
// principal axes (Lewis, "Convex analysis on the Hermitian matrices", 1996) and moves the
// principal moments to their Euclidean projection onto K, found exactly by trying each set
// of active inequalities (three, so eight sets) and keeping the nearest feasible point.
// moments_before / moments_after: the principal moments (ascending) of J and of J*.
Eigen::Matrix3d nearestPhysicalInertia(const Eigen::Matrix3d& J, Eigen::Vector3d* moments_before = nullptr,
                                       Eigen::Vector3d* moments_after = nullptr);

// The Euclidean projection of principal moments l onto K (what nearestPhysicalInertia
// applies along the principal axes).
Eigen::Vector3d nearestPhysicalMoments(const Eigen::Vector3d& l);

// What the constraint solver's factorizations of H = M + Phi_q^T W Phi_q add to the
// diagonal of a body's mass block diag(m I, Jp) where that block is singular: 1e-6 of the
// body's stand-ins `stand_in` (the diagonal of System::Minv's inverse) on the translations
// when m is not above 1e-12 of mass_scale, on the rotations when Jp's least principal
// moment is not above 1e-12 of inertia_scale; zero for every other body. Only the
// preconditioner holds it (the refinement solves the exact equations), so it decides only
// the motions that move no mass at all, which H leaves singular: a gimbal's massless links
// turning about its lined-up axes at the lock, a point mass turning about itself. They
// keep their rate. Assembly's mass-rank check does not add it.
Eigen::Matrix<double, 6, 1> massFloor(double m, const Eigen::Matrix3d& Jp, const Eigen::Matrix<double, 6, 1>& stand_in,
                                      double mass_scale, double inertia_scale);

}  // namespace mechanism_sim
