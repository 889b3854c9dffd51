// The branch passages' decomposition of a planar loop's two rows over three columns
// (branch_passage.cpp) runs Eigen's JacobiSVD in fixed-size storage; it must give the bits
// of the fixed-capacity one it stands for (singular values, U, the first two columns of V),
// near-dependent rows included, or the four-bars' results would change with it. Its gate
// for two rows (passageGateTwoRows) must decide as Eigen's LLT of W W^T - shift I, at the
// gate too.
#include <gtest/gtest.h>

#include <cstring>
#include <random>

#include <Eigen/Cholesky>
#include <Eigen/QR>
#include <Eigen/SVD>

#include "core/joint_space/loop_closure.h"

namespace mechanism_sim {
namespace {

using Small6 = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, 6, 6>;
using Fixed23 = Eigen::Matrix<double, 2, 3>;

template <class A, class B>
bool sameBits(const A& a, const B& b) {
  if (a.rows() != b.rows() || a.cols() != b.cols()) return false;
  for (Eigen::Index i = 0; i < a.rows(); ++i)
    for (Eigen::Index j = 0; j < a.cols(); ++j) {
      const double x = a(i, j), y = b(i, j);
      if (std::memcmp(&x, &y, sizeof x) != 0) return false;
    }
  return true;
}

TEST(PassageSvd, FixedTwoByThreeMatchesFixedCapacityBitwise) {
  std::mt19937 rng(20261127u);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Eigen::JacobiSVD<Small6> dyn;
  Eigen::JacobiSVD<Fixed23> fixed;
  int differ = 0;
  for (int t = 0; t < 20000; ++t) {
    Fixed23 W;
    for (int k = 0; k < 6; ++k) W.data()[k] = u(rng);
    const double scale = std::pow(10.0, -12.0 * (t % 7) / 6.0);  // rows from independent to nearly dependent
    if (t % 2) W.row(1) = W.row(0) * (1.0 + scale * u(rng)) + scale * W.row(1);
    const Small6 Wd = W;
    dyn.compute(Wd, Eigen::ComputeFullU | Eigen::ComputeThinV);
    fixed.compute(W, Eigen::ComputeFullU | Eigen::ComputeFullV);
    if (!sameBits(dyn.singularValues(), fixed.singularValues()) || !sameBits(dyn.matrixU(), fixed.matrixU()) ||
        !sameBits(dyn.matrixV(), fixed.matrixV().leftCols(2)))
      ++differ;
  }
  EXPECT_EQ(differ, 0);
}

TEST(PassageSvd, TwoRowGateDecidesAsTheCholeskyFactorization) {
  std::mt19937 rng(11u);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const double shift = kPassageGate * kPassageGate + 1e-10;
  int differ = 0, at_gate = 0, passed_at_gate = 0;
  for (int t = 0; t < 40000; ++t) {
    const int k = 2 + t % 4;
    Eigen::MatrixXd W(2, k);
    if (t % 2) {  // the smaller singular value within 1e-15..1e-13 of the gate
      const Eigen::MatrixXd V = Eigen::HouseholderQR<Eigen::MatrixXd>(Eigen::MatrixXd::Random(k, k)).householderQ();
      const double th = 3.2 * u(rng);
      Eigen::Matrix2d U, S;
      U << std::cos(th), -std::sin(th), std::sin(th), std::cos(th);
      S << 1.0 + 0.5 * u(rng), 0.0, 0.0, std::sqrt(shift) * (1.0 + (t % 4 == 1 ? 1e-15 : 1e-13) * u(rng));
      W = U * S * V.leftCols(2).transpose();
      ++at_gate;
    } else {
      for (int i = 0; i < 2; ++i)
        for (int j = 0; j < k; ++j) W(i, j) = u(rng);
    }
    Eigen::MatrixXd gram = W * W.transpose();
    gram.diagonal().array() -= shift;
    const bool llt = Eigen::LLT<Eigen::MatrixXd>(gram).info() == Eigen::Success;
    const bool gate = passageGateTwoRows(W, shift);
    differ += llt != gate;
    passed_at_gate += (t % 2) && gate;
  }
  EXPECT_EQ(differ, 0);
  EXPECT_GT(passed_at_gate, at_gate / 10);  // (both sides of the gate were met)
  EXPECT_LT(passed_at_gate, at_gate - at_gate / 10);
}

}  // namespace
}  // namespace mechanism_sim
