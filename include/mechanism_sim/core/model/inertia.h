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

}  // namespace mechanism_sim
