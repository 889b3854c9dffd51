// ScaledLeastNorm (scaled_least_norm.h) on each of its paths (at most kSmall rows kept; more
// kept but not all; all kept) against the dense formula x = D (D A D)^+ D b with Eigen's
// complete orthogonal decomposition as the oracle: dependent rows, dropped rows held at 0,
// zero diagonals, the rank, and the answer's independence of each row's units.
#include <gtest/gtest.h>

#include <random>

#include <Eigen/QR>

#include "core/linalg/scaled_least_norm.h"

namespace mechanism_sim {
namespace {

// A = G G^T with G n x k (rank k: n - k dependent rows), rows scaled by `units` (a row of
// lengths beside a row of angles), rows in `zero` without any term.
Eigen::MatrixXd semiDefinite(int n, int k, const std::vector<int>& zero, std::mt19937& rng) {
  std::normal_distribution<double> g;
  Eigen::MatrixXd G(n, k);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < k; ++j) G(i, j) = g(rng);
  for (int e : zero) G.row(e).setZero();
  Eigen::VectorXd units(n);
  for (int i = 0; i < n; ++i) units(i) = std::pow(10.0, (i % 3) - 1);  // 0.1, 1, 10
  G = units.asDiagonal() * G;
  return G * G.transpose();
}

// The oracle: x = D (D A D)^+ D b over the kept rows, 0 elsewhere.
Eigen::VectorXd oracle(const Eigen::MatrixXd& A, const Eigen::VectorXd& b, const Eigen::VectorXd& keep) {
  const Eigen::Index n = A.rows();
  Eigen::VectorXd d = Eigen::VectorXd::Zero(n);
  for (Eigen::Index e = 0; e < n; ++e)
    if (keep(e) > 0 && A(e, e) > 0) d(e) = 1.0 / std::sqrt(A(e, e));
  std::vector<Eigen::Index> kept;
  for (Eigen::Index e = 0; e < n; ++e)
    if (d(e) != 0) kept.push_back(e);
  Eigen::MatrixXd S(kept.size(), kept.size());
  Eigen::VectorXd c(kept.size());
  for (size_t i = 0; i < kept.size(); ++i) {
    c(i) = d(kept[i]) * b(kept[i]);
    for (size_t j = 0; j < kept.size(); ++j) S(i, j) = d(kept[i]) * A(kept[i], kept[j]) * d(kept[j]);
  }
  Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd> cod;
  cod.setThreshold(kClosureRankThreshold);
  cod.compute(S);
  const Eigen::VectorXd y = cod.solve(c);
  Eigen::VectorXd x = Eigen::VectorXd::Zero(n);
  for (size_t i = 0; i < kept.size(); ++i) x(kept[i]) = d(kept[i]) * y(i);
  return x;
}

struct PathCase {
  const char* name;
  int n, k;
  std::vector<int> zero, dropped;
  int rank;  // factor()'s: the kept rows' rank, plus one per row not kept
};

TEST(ScaledLeastNorm, EachPathGivesTheScaledLeastNormSolution) {
  const std::vector<PathCase> cases = {
      {"small", 6, 4, {}, {2}, 4 + 1},                   // 5 kept: the fixed-capacity path
      {"compact", 14, 8, {3}, {5, 9}, 8 + 3},            // 11 kept of 14 (a zero row, two dropped)
      {"full", 12, 7, {}, {}, 7},                        // every row kept
  };
  for (const PathCase& pc : cases) {
    SCOPED_TRACE(pc.name);
    std::mt19937 rng(21);
    const Eigen::MatrixXd A = semiDefinite(pc.n, pc.k, pc.zero, rng);
    Eigen::VectorXd keep = Eigen::VectorXd::Ones(pc.n);
    for (int e : pc.dropped) keep(e) = 0;
    // a right-hand side in A's range on the kept rows (a consistent system), and one that is not
    std::normal_distribution<double> g;
    Eigen::VectorXd y(pc.n), noise(pc.n);
    for (int i = 0; i < pc.n; ++i) y(i) = g(rng), noise(i) = g(rng);
    for (const Eigen::VectorXd& b : {Eigen::VectorXd(A * y), Eigen::VectorXd(A * y + 0.1 * noise)}) {
      ScaledLeastNorm sln(pc.n);
      Eigen::MatrixXd work = A;
      EXPECT_EQ(sln.factor(work, pc.dropped.empty() ? nullptr : &keep), pc.rank);
      Eigen::VectorXd x;
      x.setZero(pc.n);
      sln.solve(b, x);
      const Eigen::VectorXd expected = oracle(A, b, keep);
      EXPECT_LE((x - expected).cwiseAbs().maxCoeff(), 1e-10 * expected.cwiseAbs().maxCoeff());
      for (int e : pc.dropped) EXPECT_EQ(x(e), 0.0);
      for (int e : pc.zero) EXPECT_EQ(x(e), 0.0);
    }
  }
}

// Row e in other units (A -> S A S, b -> S b) gives x -> S^-1 x: the Jacobi scaling makes the
// rank decision and the least-norm choice independent of each row's units.
TEST(ScaledLeastNorm, TheAnswerDoesNotDependOnEachRowsUnits) {
  for (const int n : {6, 12}) {
    std::mt19937 rng(22);
    const Eigen::MatrixXd A = semiDefinite(n, n - 2, {}, rng);
    std::normal_distribution<double> g;
    Eigen::VectorXd y(n), s(n);
    for (int i = 0; i < n; ++i) y(i) = g(rng), s(i) = std::pow(10.0, 3 * ((i % 5) - 2));  // 1e-6 .. 1e6
    const Eigen::VectorXd b = A * y;
    ScaledLeastNorm plain(n), scaled(n);
    Eigen::MatrixXd A1 = A, A2 = s.asDiagonal() * A * s.asDiagonal();
    EXPECT_EQ(plain.factor(A1), n - 2);
    EXPECT_EQ(scaled.factor(A2), n - 2);
    Eigen::VectorXd x1 = Eigen::VectorXd::Zero(n), x2 = Eigen::VectorXd::Zero(n);
    plain.solve(b, x1);
    scaled.solve(Eigen::VectorXd(s.asDiagonal() * b), x2);
    const Eigen::VectorXd back = s.asDiagonal() * x2;
    EXPECT_LE((back - x1).cwiseAbs().maxCoeff(), 1e-9 * x1.cwiseAbs().maxCoeff()) << n;
    // and it solves the system
    EXPECT_LE((A * x1 - b).cwiseAbs().maxCoeff(), 1e-10 * b.cwiseAbs().maxCoeff()) << n;
  }
}

}  // namespace
}  // namespace mechanism_sim
