// Every primitive's variation (Jacobian), rate and gamma against finite differences at
// random poses with both bodies rotated and joint points away from the reference points.
#include <gtest/gtest.h>

#include "fd_util.h"
#include "mechanism_sim/core/model/primitives.h"

namespace mechanism_sim {
namespace {

using test::fdGamma;
using test::fdJacobian;
using test::fdRate;
using test::velocityOf;

constexpr int kPoses = 100;

struct PoseSetup {
  std::vector<BodyKin> kin;
  Vector3d ap_i, ap_j, sp_i, sp_j;
};

PoseSetup randomSetup(std::mt19937& rng) {
  PoseSetup s;
  s.kin = {test::randomBody(rng), test::randomBody(rng)};
  s.ap_i = test::randomVector(rng).normalized();
  s.ap_j = test::randomVector(rng).normalized();
  s.sp_i = test::randomVector(rng, 0.8);
  s.sp_j = test::randomVector(rng, 0.8);
  return s;
}

// The column-wise product A tilde(s) the primitives use is the product with the skew matrix.
TEST(Primitives, TimesTildeIsTheProductWithTheSkewMatrix) {
  std::mt19937 rng(5);
  for (int n = 0; n < kPoses; ++n) {
    const Matrix3d A = test::randomBody(rng).A_Oi;
    const Vector3d s = test::randomVector(rng, 3.0);
    EXPECT_LT((timesTilde(A, s) - A * tilde(s)).cwiseAbs().maxCoeff(), 1e-15 * 3.0) << n;
  }
}

// Checks value-Jacobian-gamma-rate consistency of f, given its analytic J, gamma, rate.
void expectConsistent(const test::Phis& f, const std::vector<BodyKin>& kin,
                      const Eigen::MatrixXd& J, const Eigen::VectorXd& gamma,
                      const Eigen::VectorXd& rate, const char* what) {
  const double scale = 1.0 + J.cwiseAbs().maxCoeff();
  EXPECT_LT((fdJacobian(f, kin) - J).cwiseAbs().maxCoeff(), 1e-7 * scale) << what;
  EXPECT_LT((fdGamma(f, kin) - gamma).cwiseAbs().maxCoeff(), 2e-5 * (1.0 + gamma.cwiseAbs().maxCoeff())) << what;
  EXPECT_LT((fdRate(f, kin) - rate).cwiseAbs().maxCoeff(), 1e-7 * scale) << what;
  EXPECT_LT((J * velocityOf(kin) - rate).cwiseAbs().maxCoeff(), 1e-12 * scale) << what;
}

Eigen::VectorXd one(double x) { return Eigen::VectorXd::Constant(1, x); }

TEST(Primitives, Cn1MatchesFiniteDifferences_8_11) {
  std::mt19937 rng(1);
  for (int n = 0; n < kPoses; ++n) {
    const PoseSetup s = randomSetup(rng);
    auto f = [&](const std::vector<BodyKin>& k) {
      return one(Cn1(fixedVector(k[0], s.ap_i), fixedVector(k[1], s.ap_j)).Phi);
    };
    const Row r = Cn1(fixedVector(s.kin[0], s.ap_i), fixedVector(s.kin[1], s.ap_j));
    expectConsistent(f, s.kin, r.J, one(r.gamma), one(r.Phi_dot), "C(n1)");
  }
}

TEST(Primitives, Cn2MatchesFiniteDifferences_8_13) {
  std::mt19937 rng(2);
  for (int n = 0; n < kPoses; ++n) {
    const PoseSetup s = randomSetup(rng);
    auto f = [&](const std::vector<BodyKin>& k) {
      return one(Cn2(fixedVector(k[0], s.ap_i), gap(k[0], s.sp_i, k[1], s.sp_j)).Phi);
    };
    const Row r = Cn2(fixedVector(s.kin[0], s.ap_i), gap(s.kin[0], s.sp_i, s.kin[1], s.sp_j));
    expectConsistent(f, s.kin, r.J, one(r.gamma), one(r.Phi_dot), "C(n2)");
  }
}

TEST(Primitives, Cp1MatchesFiniteDifferences_8_15) {
  std::mt19937 rng(3);
  for (int n = 0; n < kPoses; ++n) {
    const PoseSetup s = randomSetup(rng);
    auto f = [&](const std::vector<BodyKin>& k) -> Eigen::VectorXd {
      return Cp1(fixedVector(k[0], s.ap_i), fixedVector(k[1], s.ap_j)).Phi;
    };
    const Rows3 r = Cp1(fixedVector(s.kin[0], s.ap_i), fixedVector(s.kin[1], s.ap_j));
    expectConsistent(f, s.kin, r.J, r.gamma, r.J * velocityOf(s.kin), "C(p1)");
  }
}

TEST(Primitives, Cp2MatchesFiniteDifferences_8_17) {
  std::mt19937 rng(4);
  for (int n = 0; n < kPoses; ++n) {
    const PoseSetup s = randomSetup(rng);
    auto f = [&](const std::vector<BodyKin>& k) -> Eigen::VectorXd {
      return Cp2(fixedVector(k[0], s.ap_i), gap(k[0], s.sp_i, k[1], s.sp_j)).Phi;
    };
    const Rows3 r = Cp2(fixedVector(s.kin[0], s.ap_i), gap(s.kin[0], s.sp_i, s.kin[1], s.sp_j));
    expectConsistent(f, s.kin, r.J, r.gamma, r.J * velocityOf(s.kin), "C(p2)");
  }
}

TEST(Primitives, PointCoincidenceMatchesFiniteDifferences) {
  std::mt19937 rng(5);
  for (int n = 0; n < kPoses; ++n) {
    const PoseSetup s = randomSetup(rng);
    auto f = [&](const std::vector<BodyKin>& k) -> Eigen::VectorXd {
      return Cpoint(gap(k[0], s.sp_i, k[1], s.sp_j)).Phi;
    };
    const Rows3 r = Cpoint(gap(s.kin[0], s.sp_i, s.kin[1], s.sp_j));
    expectConsistent(f, s.kin, r.J, r.gamma, r.J * velocityOf(s.kin), "point");
  }
}

// The seed's 3-row C(p1) and C(p2) have rank 2 wherever they vanish.
TEST(Primitives, ParallelPrimitivesHaveRankTwoWhenSatisfied) {
  std::mt19937 rng(6);
  for (int n = 0; n < kPoses; ++n) {
    PoseSetup s = randomSetup(rng);
    // Make a_j parallel to a_i and d along a_i.
    s.ap_j = s.kin[1].A_Oi.transpose() * s.kin[0].A_Oi * s.ap_i;
    s.kin[1].r = s.kin[0].r + s.kin[0].A_Oi * s.sp_i + 0.3 * (s.kin[0].A_Oi * s.ap_i) -
                 s.kin[1].A_Oi * s.sp_j;
    const Rows3 p1 = Cp1(fixedVector(s.kin[0], s.ap_i), fixedVector(s.kin[1], s.ap_j));
    const Rows3 p2 = Cp2(fixedVector(s.kin[0], s.ap_i), gap(s.kin[0], s.sp_i, s.kin[1], s.sp_j));
    EXPECT_LT(p1.Phi.norm(), 1e-12);
    EXPECT_LT(p2.Phi.norm(), 1e-12);
    EXPECT_EQ(test::rankOf(p1.J), 2);
    EXPECT_EQ(test::rankOf(p2.J), 2);
  }
}

TEST(Primitives, RelativeAngleMatchesFiniteDifferences) {
  std::mt19937 rng(7);
  for (int n = 0; n < kPoses; ++n) {
    const PoseSetup s = randomSetup(rng);
    const Matrix3d R = test::randomRotation(rng);
    auto row = [&](const std::vector<BodyKin>& k, double ref) {
      return relativeAngle(fixedVector(k[0], R.col(0)), fixedVector(k[0], R.col(1)),
                           fixedVector(k[1], R.col(0)), ref);
    };
    const Row r = row(s.kin, 0.0);
    auto f = [&](const std::vector<BodyKin>& k) { return one(row(k, r.Phi).Phi); };
    expectConsistent(f, s.kin, r.J, one(r.gamma), one(r.Phi_dot), "angle");
  }
}

// On the joint axis (bz_i || bz_j) the exact variation equals the seed's (7.38).
TEST(Primitives, RelativeAngleEqualsSeed_7_38_OnTheAxis) {
  std::mt19937 rng(8);
  std::uniform_real_distribution<double> ang(-10.0, 10.0);
  for (int n = 0; n < kPoses; ++n) {
    std::vector<BodyKin> kin = {test::randomBody(rng), test::randomBody(rng)};
    const Matrix3d Ri = test::randomRotation(rng), Rj = test::randomRotation(rng);
    const double phi = ang(rng);
    // Frame j = frame i turned by phi about its z axis.
    kin[1].A_Oi = kin[0].A_Oi * Ri * Eigen::AngleAxisd(phi, Vector3d::UnitZ()).toRotationMatrix() * Rj.transpose();
    const Row r = relativeAngle(fixedVector(kin[0], Ri.col(0)), fixedVector(kin[0], Ri.col(1)),
                                fixedVector(kin[1], Rj.col(0)), phi);
    EXPECT_NEAR(r.Phi, phi, 1e-9);  // counted through turns from the reference
    const Row12 seed = variation738(kin[0], kin[1], Ri.col(2));
    EXPECT_LT((seed - r.J).cwiseAbs().maxCoeff(), 1e-10);
  }
}

TEST(Primitives, ScrewMatchesFiniteDifferencesAndSeed_A8_10) {
  std::mt19937 rng(9);
  for (int n = 0; n < kPoses; ++n) {
    PoseSetup s = randomSetup(rng);
    const Matrix3d R = test::randomRotation(rng);
    const double alpha = 0.05 * (n % 2 ? 1 : -1), phi0 = 0.3;
    auto row = [&](const std::vector<BodyKin>& k, double ref) {
      const FixedVector bx = fixedVector(k[0], R.col(0)), by = fixedVector(k[0], R.col(1));
      const Row phi = relativeAngle(bx, by, fixedVector(k[1], R.col(0)), ref);
      return Csc(fixedVector(k[0], R.col(2)), gap(k[0], s.sp_i, k[1], s.sp_j), phi, alpha, phi0);
    };
    const Row r0 = relativeAngle(fixedVector(s.kin[0], R.col(0)), fixedVector(s.kin[0], R.col(1)),
                                 fixedVector(s.kin[1], R.col(0)), 0.0);
    const Row r = row(s.kin, r0.Phi);
    auto f = [&](const std::vector<BodyKin>& k) { return one(row(k, r0.Phi).Phi); };
    expectConsistent(f, s.kin, r.J, one(r.gamma), one(r.Phi_dot), "screw");

    // On a cylindrical pose (frames share the z axis) the seed's (A8.10), corrected, holds.
    std::vector<BodyKin> kin = s.kin;
    const Matrix3d Rj = test::randomRotation(rng);
    kin[1].A_Oi = kin[0].A_Oi * R * Eigen::AngleAxisd(1.1, Vector3d::UnitZ()).toRotationMatrix() * Rj.transpose();
    kin[1].r = kin[0].r + kin[0].A_Oi * s.sp_i + 0.2 * kin[0].A_Oi * R.col(2) - kin[1].A_Oi * s.sp_j;
    const Row exact = Csc(fixedVector(kin[0], R.col(2)), gap(kin[0], s.sp_i, kin[1], s.sp_j),
                          relativeAngle(fixedVector(kin[0], R.col(0)), fixedVector(kin[0], R.col(1)),
                                        fixedVector(kin[1], Rj.col(0)), 1.1),
                          alpha, phi0);
    const Row12 seed = variationA810(kin[0], s.sp_i, kin[1], s.sp_j, R.col(2), alpha);
    EXPECT_LT((seed - exact.J).cwiseAbs().maxCoeff(), 1e-10);
  }
}

// (A8.10) row by hand: [dr_i, dtheta_i, dr_j, dtheta_j] of C(sc) on a cylindrical pose.
// The dtheta_j block is - bz'_i^T A_ij (tilde(s'_j) + alpha I); the table as typeset has
// s'_i there (as_typeset = true).
Row12 tableA810(const BodyKin& bi, const Vector3d& sp_i, const BodyKin& bj, const Vector3d& sp_j,
                const Vector3d& bzp_i, double alpha, bool as_typeset) {
  const Matrix3d A_ij = bi.A_Oi.transpose() * bj.A_Oi;
  const Vector3d d = bj.r + bj.A_Oi * sp_j - bi.r - bi.A_Oi * sp_i;
  const Matrix3d I = Matrix3d::Identity();
  Row12 J;
  J.segment<3>(0) = -bzp_i.transpose() * bi.A_Oi.transpose();
  J.segment<3>(3) = bzp_i.transpose() * (tilde(sp_i) + alpha * I) - d.transpose() * bi.A_Oi * tilde(bzp_i);
  J.segment<3>(6) = bzp_i.transpose() * bi.A_Oi.transpose();
  J.segment<3>(9) = -bzp_i.transpose() * A_ij * (tilde(as_typeset ? sp_i : sp_j) + alpha * I);
  return J;
}

// The table's (A8.10) as typeset (s'_i in the dtheta_j term) is wrong: against finite
// differences of C(sc) itself, the corrected row (by hand and the library's) agrees to
// 1e-7 at every pose and the typeset row misses by far more.
TEST(Primitives, SeedTableTypoInA8_10IsDetectedByFiniteDifferences) {
  std::mt19937 rng(10);
  double worst_corrected = 0, least_typeset = 1e300;
  for (int n = 0; n < kPoses; ++n) {
    const PoseSetup s = randomSetup(rng);
    const Matrix3d Ri = test::randomRotation(rng), Rj = test::randomRotation(rng);
    const double alpha = 0.05 * (n % 2 ? 1 : -1), phi0 = 0.3, phi = 1.1, slide = 0.2;
    // A cylindrical pose: frame j is frame i turned by phi about and moved along z_i.
    std::vector<BodyKin> kin = s.kin;
    kin[1].A_Oi = kin[0].A_Oi * Ri * Eigen::AngleAxisd(phi, Vector3d::UnitZ()).toRotationMatrix() * Rj.transpose();
    kin[1].r = kin[0].r + kin[0].A_Oi * s.sp_i + slide * kin[0].A_Oi * Ri.col(2) - kin[1].A_Oi * s.sp_j;
    auto f = [&](const std::vector<BodyKin>& k) {
      const Row angle = relativeAngle(fixedVector(k[0], Ri.col(0)), fixedVector(k[0], Ri.col(1)),
                                      fixedVector(k[1], Rj.col(0)), phi);
      return one(Csc(fixedVector(k[0], Ri.col(2)), gap(k[0], s.sp_i, k[1], s.sp_j), angle, alpha, phi0).Phi);
    };
    const Eigen::RowVectorXd fd = test::fdJacobian(f, kin).row(0);
    const Row12 corrected = tableA810(kin[0], s.sp_i, kin[1], s.sp_j, Ri.col(2), alpha, false);
    const Row12 typeset = tableA810(kin[0], s.sp_i, kin[1], s.sp_j, Ri.col(2), alpha, true);
    const Row12 library = variationA810(kin[0], s.sp_i, kin[1], s.sp_j, Ri.col(2), alpha);
    const double e_corrected = (fd - corrected).cwiseAbs().maxCoeff();
    const double e_typeset = (fd - typeset).cwiseAbs().maxCoeff();
    EXPECT_LT(e_corrected, 1e-7) << "pose " << n;
    EXPECT_LT((fd - library).cwiseAbs().maxCoeff(), 1e-7) << "pose " << n;
    EXPECT_GT(e_typeset, 1e-3) << "pose " << n;
    worst_corrected = std::max(worst_corrected, e_corrected);
    least_typeset = std::min(least_typeset, e_typeset);
  }
  // The typeset row's error is orders of magnitude above the finite-difference noise.
  EXPECT_GT(least_typeset, 1e4 * worst_corrected);
}

}  // namespace
}  // namespace mechanism_sim
