// The closures' sparse solve (closure_solver.h): Z = L^-T R^T is formed by the inward pass
// on each row, two rows of a block at once where both are kept. Each of Z's columns must be
// the one the pass on its row alone gives, to the bit, or the factorization would change
// with which rows happen to be kept.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>

#include "core/joint_space/closure_solver.h"
#include "core/joint_space/loop_closure.h"
#include "mechanism_sim/core/models.h"

namespace mechanism_sim {
namespace {

TEST(ClosureSolver, ZColumnsOfPairedRowsAreEachRowsOwn) {
  Mechanism mech;
  models::fourBarChain(mech, 4, 0.4, 1.0, 0.7);
  mech.build();
  const System& sys = mech.system();
  TreeModel model(sys);
  TreeWorkspace ws(model);
  LoopClosures cl(model, sys);
  const int m = cl.m;
  ASSERT_GT(m, 2);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Eigen::VectorXd q = model.neutralPositions(sys), qdot = Eigen::VectorXd::Zero(model.nv), qdd;
  for (int k = 0; k < model.nv; ++k) q(k) += 0.3 * u(rng), qdot(k) = u(rng);
  forwardDynamics(model, sys, q, qdot, Eigen::VectorXd::Zero(model.nv), ws, qdd);  // (the articulated factors)
  // blocks as the closures lay them out, rows R random on each block's coordinates
  std::vector<int> first(cl.row);
  first.push_back(m);
  std::vector<std::vector<int>> cols;
  for (size_t i = 0; i < cl.constraints.size(); ++i) cols.push_back(cl.rowColumns(cl.row[i]));
  Eigen::MatrixXd R = Eigen::MatrixXd::Zero(m, model.nv);
  for (size_t i = 0; i < cols.size(); ++i)
    for (int e = first[i]; e < first[i + 1]; ++e)
      for (int k : cols[i]) R(e, k) = u(rng);
  ScaledLeastNorm dense(m);
  Eigen::MatrixXd A(m, m);
  ClosureSolver all(model, first, cols);
  all.factor(model, ws, R, Eigen::VectorXd::Ones(m), dense, A);  // (every block's rows in pairs)
  int compared = 0;
  for (int e = 0; e < m; ++e) {
    Eigen::VectorXd keep = Eigen::VectorXd::Zero(m), x = Eigen::VectorXd::Zero(m);
    keep(e) = 1.0, x(e) = 1.0;
    ClosureSolver alone(model, first, cols);  // (row e on its own: the single row's pass)
    alone.factor(model, ws, R, keep, dense, A);
    Eigen::VectorXd z_all = Eigen::VectorXd::Constant(model.nv, NAN), z_alone = z_all;
    ASSERT_TRUE(all.inwardOfRowsT(x, z_all.data()));
    ASSERT_TRUE(alone.inwardOfRowsT(x, z_alone.data()));
    for (int k = 0; k < model.nv; ++k) {
      EXPECT_EQ(std::memcmp(&z_all(k), &z_alone(k), sizeof(double)), 0) << "row " << e << " coordinate " << k;
      compared += z_all(k) != 0.0;
    }
  }
  EXPECT_GT(compared, m);  // (columns with entries were compared)
}

}  // namespace
}  // namespace mechanism_sim
