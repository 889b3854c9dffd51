// The block Cholesky factorization against a dense one: a tree (no fill) and a graph
// with loops (fill), random SPD blocks; a quasi-definite KKT matrix in tree order (signed
// pivots); and the zero pivot of a semidefinite matrix.
#include <gtest/gtest.h>

#include <algorithm>
#include <random>

#include <Eigen/Dense>

#include "core/linalg/block_cholesky.h"

namespace mechanism_sim {
namespace {

Eigen::MatrixXd assembleRandom(BlockCholesky& chol, int nb, const std::vector<std::pair<int, int>>& edges,
                               std::mt19937& rng, double spread) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  chol.analyze(nb, edges);
  chol.setZero();
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(6 * nb, 6 * nb);
  auto add = [&](int i, int j, const BlockCholesky::Block& B) {
    A.block<6, 6>(6 * i, 6 * j) += B;
    if (i != j) A.block<6, 6>(6 * j, 6 * i) += B.transpose();
    bool t = false;
    const int a = chol.address(i, j, &t);
    if (t) chol.block(a) += B.transpose();
    else chol.block(a) += B;
  };
  for (const auto& e : edges) {  // a coupling term J^T J over the two bodies
    Eigen::Matrix<double, 5, 12> J;
    for (int r = 0; r < 5; ++r)
      for (int c = 0; c < 12; ++c) J(r, c) = u(rng);
    const Eigen::Matrix<double, 12, 12> JtJ = spread * J.transpose() * J;
    add(e.first, e.first, JtJ.topLeftCorner<6, 6>());
    add(e.second, e.second, JtJ.bottomRightCorner<6, 6>());
    add(e.first, e.second, JtJ.topRightCorner<6, 6>());
  }
  for (int b = 0; b < nb; ++b) {
    BlockCholesky::Block M = BlockCholesky::Block::Zero();
    M.diagonal().setConstant(1.0 + 0.1 * b);
    add(b, b, M);
  }
  return A;
}

void expectSolves(int nb, const std::vector<std::pair<int, int>>& edges, double spread) {
  std::mt19937 rng(5);
  BlockCholesky chol;
  const Eigen::MatrixXd A = assembleRandom(chol, nb, edges, rng, spread);
  ASSERT_EQ(chol.factorize(0.0, false), 0);
  Eigen::VectorXd b = Eigen::VectorXd::Random(6 * nb), x = b;
  chol.solve(x.data());
  EXPECT_LT((A * x - b).norm(), 1e-12 * (A.norm() * x.norm() + b.norm()));
}

TEST(BlockCholesky, ChainSolvesLikeDense) {
  std::vector<std::pair<int, int>> edges;
  for (int b = 1; b < 30; ++b) edges.push_back({b - 1, b});
  expectSolves(30, edges, 1.0);
  expectSolves(30, edges, 1e7);  // stiff coupling as in H = M + kappa J^T W J
}

TEST(BlockCholesky, LoopsWithFillSolveLikeDense) {
  std::vector<std::pair<int, int>> edges;
  for (int b = 1; b < 20; ++b) edges.push_back({b - 1, b});
  edges.push_back({0, 19});
  edges.push_back({3, 11});
  edges.push_back({5, 7});
  expectSolves(20, edges, 1.0);
}

TEST(BlockCholesky, TreeOrderHasNoFill) {
  std::vector<std::pair<int, int>> edges = {{0, 1}, {0, 2}, {0, 3}, {3, 4}, {3, 5}, {5, 6}};
  BlockCholesky chol;
  chol.analyze(7, edges);
  EXPECT_EQ(chol.offDiagonalBlocks(), static_cast<int>(edges.size()));
}

// L S L^T of a KKT matrix [M J^T; J 0] in tree order (Baraff 1996): a chain of 12 bodies,
// each tied to the one before by 5 random equations (the first to the ground), block rows
// 0..11 the bodies, 12..23 the equations (padded to 6 with -1: decoupled), eliminated
// body, its joint, the next body, ...; then the same with the order reversed, where the
// first pivot is a joint's zero block: it is found, not divided by.
TEST(BlockCholesky, QuasiDefiniteKktInTreeOrderSolvesLikeDense) {
  const int nb = 12, nodes = 2 * nb;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<std::pair<int, int>> edges;
  std::vector<int> order;
  std::vector<signed char> signs(nodes, 1);
  for (int b = nb - 1; b >= 0; --b) {  // body b hangs from body b - 1 by joint nb + b
    edges.push_back({nb + b, b});
    if (b > 0) edges.push_back({nb + b, b - 1});
    signs[nb + b] = -1;
    order.push_back(b);
    order.push_back(nb + b);
  }
  for (const bool reversed : {false, true}) {
    std::vector<int> o = order;
    if (reversed) std::reverse(o.begin(), o.end());
    BlockCholesky kkt;
    kkt.analyze(nodes, edges, o, signs);
    if (!reversed) {
      EXPECT_EQ(kkt.offDiagonalBlocks(), static_cast<int>(edges.size()));  // no fill
    }
    kkt.setZero();
    Eigen::MatrixXd A = Eigen::MatrixXd::Zero(6 * nodes, 6 * nodes);
    auto put = [&](int i, int j, const BlockCholesky::Block& B) {
      A.block<6, 6>(6 * i, 6 * j) = B;
      if (i != j) A.block<6, 6>(6 * j, 6 * i) = B.transpose();
      bool t = false;
      const int a = kkt.address(i, j, &t);
      kkt.block(a) = t ? BlockCholesky::Block(B.transpose()) : B;
    };
    for (int b = 0; b < nb; ++b) {
      BlockCholesky::Block M = BlockCholesky::Block::Zero();
      M.diagonal() << 2, 2, 2, 0.01, 0.02, 0.03;  // kg and kg m^2: a small body
      put(b, b, M);
      BlockCholesky::Block pad = BlockCholesky::Block::Zero();
      pad(5, 5) = -1;
      put(nb + b, nb + b, pad);
      for (int side = 0; side < (b > 0 ? 2 : 1); ++side) {
        BlockCholesky::Block J = BlockCholesky::Block::Zero();
        for (int r = 0; r < 5; ++r)
          for (int c = 0; c < 6; ++c) J(r, c) = u(rng);
        put(nb + b, b - side, J);
      }
    }
    if (reversed) {
      EXPECT_GT(kkt.factorize(0.0, false), 0);
      continue;
    }
    ASSERT_EQ(kkt.factorize(0.0, false), 0);
    Eigen::VectorXd rhs = Eigen::VectorXd::Random(6 * nodes), x = rhs;
    kkt.solve(x.data());
    const Eigen::VectorXd dense = A.fullPivLu().solve(rhs);
    EXPECT_LT((A * x - rhs).norm(), 1e-11 * (A.norm() * x.norm() + rhs.norm()));
    EXPECT_LT((x - dense).norm(), 1e-9 * dense.norm());
  }
}

TEST(BlockCholesky, ZeroPivotIsFoundAndNamed) {
  BlockCholesky chol;
  chol.analyze(2, {{0, 1}});
  auto fill = [&] {
    chol.setZero();
    bool t = false;
    chol.block(chol.address(0, 0, &t)).diagonal().setOnes();
    chol.block(chol.address(1, 1, &t)).diagonal() << 1, 1, 1, 0, 1, 1;  // entry 3 of body 1 moves no mass
  };
  fill();
  EXPECT_EQ(chol.factorize(1e-12, true), 1);
  EXPECT_TRUE(chol.zeroPivot(1, 3));
  EXPECT_FALSE(chol.zeroPivot(0, 3));
  fill();
  EXPECT_EQ(chol.factorize(0.0, false), 1);
}

}  // namespace
}  // namespace mechanism_sim
