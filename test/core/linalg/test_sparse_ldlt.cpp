// The sparse LDL^T (sparse_ldlt.h) against a dense solve: random sparse SPD matrices in a
// random pivot order, factored again with new values on the same pattern (the row patterns
// analyze() keeps), a semidefinite one with a zero pivot skipped or stopping the
// factorization, and a definite one factored after such a stop.
#include <gtest/gtest.h>

#include <algorithm>
#include <numeric>
#include <random>

#include <Eigen/Dense>

#include "core/linalg/sparse_ldlt.h"

namespace mechanism_sim {
namespace {

// A random pattern of R (rows x n, `per_row` entries a row), the pattern of R^T R in
// compressed columns (both triangles), and a random order.
struct Pattern {
  int n = 0;
  std::vector<std::vector<int>> rows;  // per row of R: its columns
  std::vector<int> Ap, Ai, perm;
};

Pattern randomPattern(int n, int nrows, int per_row, std::mt19937& rng) {
  Pattern P;
  P.n = n;
  std::uniform_int_distribution<int> col(0, n - 1);
  for (int r = 0; r < nrows; ++r) {
    std::vector<int> c;
    for (int k = 0; k < per_row; ++k) c.push_back(col(rng));
    std::sort(c.begin(), c.end());
    c.erase(std::unique(c.begin(), c.end()), c.end());
    P.rows.push_back(c);
  }
  std::vector<std::vector<int>> colrows(n);
  for (int j = 0; j < n; ++j) colrows[j].push_back(j);
  for (const auto& c : P.rows)
    for (int a : c)
      for (int b : c) colrows[b].push_back(a);
  P.Ap.assign(1, 0);
  for (int j = 0; j < n; ++j) {
    std::sort(colrows[j].begin(), colrows[j].end());
    colrows[j].erase(std::unique(colrows[j].begin(), colrows[j].end()), colrows[j].end());
    P.Ai.insert(P.Ai.end(), colrows[j].begin(), colrows[j].end());
    P.Ap.push_back(static_cast<int>(P.Ai.size()));
  }
  P.perm.resize(n);
  std::iota(P.perm.begin(), P.perm.end(), 0);
  std::shuffle(P.perm.begin(), P.perm.end(), rng);
  return P;
}

// A = R^T R + shift I on the pattern (random values of R), dense and as Ax
Eigen::MatrixXd randomValues(const Pattern& P, double shift, std::mt19937& rng, std::vector<double>& Ax) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Eigen::MatrixXd A = shift * Eigen::MatrixXd::Identity(P.n, P.n);
  for (const auto& c : P.rows) {
    Eigen::VectorXd r = Eigen::VectorXd::Zero(P.n);
    for (int a : c) r(a) = u(rng);
    A += r * r.transpose();
  }
  Ax.assign(P.Ai.size(), 0.0);
  for (int j = 0; j < P.n; ++j)
    for (int p = P.Ap[j]; p < P.Ap[j + 1]; ++p) Ax[p] = A(P.Ai[p], j);
  return A;
}

TEST(SparseLDLT, RandomDefiniteAgainstDense) {
  std::mt19937 rng(20261127u);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int trial = 0; trial < 20; ++trial) {
    const int n = 5 + 7 * trial;
    const Pattern P = randomPattern(n, n, 3, rng);
    SparseLDLT ldlt;
    ldlt.analyze(n, P.Ap, P.Ai, trial % 2 ? P.perm : std::vector<int>{});
    for (int values = 0; values < 3; ++values) {  // new values on the analysed pattern
      std::vector<double> Ax;
      const Eigen::MatrixXd A = randomValues(P, 0.1, rng, Ax);
      ASSERT_EQ(ldlt.factorize(Ax.data(), 1e-12, false), 0) << "trial " << trial;
      Eigen::VectorXd b(n);
      for (int k = 0; k < n; ++k) b(k) = u(rng);
      Eigen::VectorXd x = b;
      ldlt.solve(x.data());
      const Eigen::VectorXd ref = A.ldlt().solve(b);
      EXPECT_LT((x - ref).norm(), 1e-10 * ref.norm()) << "trial " << trial << ", values " << values;
      EXPECT_LT((A * x - b).norm(), 1e-10 * b.norm()) << "trial " << trial << ", values " << values;
    }
  }
}

TEST(SparseLDLT, ZeroPivotSkippedOrStopping) {
  std::mt19937 rng(7u);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const int n = 12;
  Pattern P = randomPattern(n, n, 3, rng);
  // row and column z of A zero (a dependent row of a semidefinite matrix: its pivot is 0)
  const int z = 5;
  SparseLDLT ldlt;
  ldlt.analyze(n, P.Ap, P.Ai, P.perm);
  std::vector<double> Ax;
  Eigen::MatrixXd A = randomValues(P, 0.1, rng, Ax);
  for (int j = 0; j < n; ++j)
    for (int p = P.Ap[j]; p < P.Ap[j + 1]; ++p)
      if (P.Ai[p] == z || j == z) Ax[p] = 0.0;
  A.row(z).setZero(), A.col(z).setZero();
  EXPECT_EQ(ldlt.factorize(Ax.data(), 1e-12, true), 1);
  EXPECT_TRUE(ldlt.zeroPivot(z));
  for (int k = 0; k < n; ++k)
    if (k != z) EXPECT_FALSE(ldlt.zeroPivot(k)) << k;
  Eigen::VectorXd b(n);
  for (int k = 0; k < n; ++k) b(k) = u(rng);
  b(z) = 0.0;
  Eigen::VectorXd x = b;
  ldlt.solve(x.data());
  EXPECT_EQ(x(z), 0.0);
  EXPECT_LT((A * x - b).norm(), 1e-10 * b.norm());
  // without skipping: stops at the zero pivot; a definite matrix factored after it is right
  EXPECT_EQ(ldlt.factorize(Ax.data(), 1e-12, false), 1);
  const Eigen::MatrixXd B = randomValues(P, 0.1, rng, Ax);
  ASSERT_EQ(ldlt.factorize(Ax.data(), 1e-12, false), 0);
  for (int k = 0; k < n; ++k) b(k) = u(rng);
  x = b;
  ldlt.solve(x.data());
  EXPECT_LT((B * x - b).norm(), 1e-10 * b.norm());
}

}  // namespace
}  // namespace mechanism_sim
