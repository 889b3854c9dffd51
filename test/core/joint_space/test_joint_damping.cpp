// The joint formulation's damping (joint_damping.cpp): the coordinate inverse-mass bound
// that decides which damped coordinates are stiff, against the exact inverse inertia (the
// composite-rigid-body algorithm's H) on random trees.
#include <gtest/gtest.h>

#include "bodies.h"
#include "compare.h"
#include "random_trees.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "core/joint_space/closure_solver.h"
#include "core/joint_space/joint_damping.h"
#include "core/joint_space/tree.h"
#include "core/joint_space/joint_stepper.h"
#include "mechanism_sim/core/models.h"
#include "core/absolute/stepper.h"

namespace mechanism_sim {
namespace {

using test_util::absoluteFromJoint;
using test_util::kinematicsOf;
using test_util::randomJointState;
using test_util::RandomTree;
using test_util::randomTree;
using test_util::uniform;


// coordinateInverseMassBound (JointDamping::classify's test 1) against the exact
// inverse inertia: on random trees of every joint type (one floating), in metres and
// millimetres, at random states, beta_k >= (H^-1)_kk for every joint coordinate (H by the
// composite-rigid-body algorithm); for revolute joints beta_k is the same at every state
// (the stepper keeps it); and with random closure rows G and damping c the Gershgorin sums
// s_k = sum_l sqrt(c_k c_l) |P_lk|, P = H^-1 - H^-1 G^T (G H^-1 G^T)^-1 G H^-1, are at most
// u_k = sqrt(c_k beta_k) sum_l sqrt(c_l beta_l).
TEST(JointSpace, CoordinateInverseMassBoundHoldsOnRandomTrees) {
  double worst_diag = 0, worst_sum = 0, worst_revolute = 0;
  int coordinates = 0;
  for (double L : {1.0, 1e3})
    for (unsigned seed = 1; seed <= 16; ++seed) {
      RandomTree t = randomTree(seed, 3 + static_cast<int>(seed % 7), seed % 3 == 0, L, L);
      const System& sys = *t.sys;
      TreeModel model(sys);
      TreeWorkspace ws(model);
      std::vector<double> revolute_beta(model.nv, -1.0);
      for (unsigned at = 0; at < 3; ++at) {
        Eigen::VectorXd q, qd;
        randomJointState(model, sys, 1000 * seed + at, L, q, qd);
        const State s = absoluteFromJoint(sys, model, ws, q, qd);
        const std::vector<BodyKin> kin = kinematicsOf(sys, s);
        const Eigen::VectorXd zero = Eigen::VectorXd::Zero(model.nv);
        forwardKinematics(model, q, zero, ws);
        AlignedVector<Matrix6d> Ic;
        Eigen::MatrixXd H = Eigen::MatrixXd::Zero(model.nv, model.nv);
        jointSpaceInertia(model, ws, Ic, H);
        const Eigen::MatrixXd Minv = H.llt().solve(Eigen::MatrixXd::Identity(model.nv, model.nv));
        std::vector<int> index;  // the joints' velocity coordinates (not a free body's)
        std::vector<double> beta;
        for (const TreeLink& link : model.links) {
          if (link.joint < 0) continue;
          const Joint& J = *link.ptr;
          Row rows[kMaxJointDofs];
          J.coordinates(kin[J.bodyI()], kin[J.bodyJ()], s.tracked[J.id()], rows);
          for (int k = 0; k < link.nv; ++k) {
            const int v = link.iv + k;
            const double b = coordinateInverseMassBound(sys, J, rows[k]);
            ASSERT_TRUE(std::isfinite(b)) << J.name();
            EXPECT_LE(Minv(v, v), b * (1 + 1e-12)) << "seed " << seed << ", L " << L << ", " << J.name() << " " << k;
            worst_diag = std::max(worst_diag, Minv(v, v) / b);
            if (link.kind == TreeJointKind::kRevolute) {
              if (revolute_beta[v] < 0) revolute_beta[v] = b;
              worst_revolute = std::max(worst_revolute, std::fabs(b / revolute_beta[v] - 1));
            }
            index.push_back(v);
            beta.push_back(b);
            ++coordinates;
          }
        }
        // closure rows on the joints' coordinates (couplers, limits, drives as the stepper
        // sees them), two at a time, and damping over three decades
        std::mt19937 rng(77 * seed + at);
        const int nc = static_cast<int>(index.size());
        const int m = std::min(2, nc - 1);
        Eigen::MatrixXd G = Eigen::MatrixXd::Zero(m, model.nv);
        for (int e = 0; e < m; ++e)
          for (int v : index) G(e, v) = uniform(rng, -1, 1);
        Eigen::MatrixXd P = Minv;
        if (m > 0) P -= Minv * G.transpose() * (G * Minv * G.transpose()).inverse() * G * Minv;
        std::vector<double> c(nc);
        double spread = 0;
        for (int a = 0; a < nc; ++a) c[a] = std::pow(10.0, uniform(rng, -2, 1)), spread += std::sqrt(c[a] * beta[a]);
        for (int a = 0; a < nc; ++a) {
          double sk = 0;
          for (int b = 0; b < nc; ++b) sk += std::sqrt(c[a] * c[b]) * std::fabs(P(index[b], index[a]));
          const double uk = std::sqrt(c[a] * beta[a]) * spread;
          EXPECT_LE(sk, uk * (1 + 1e-12)) << "seed " << seed << ", L " << L << ", coordinate " << index[a];
          worst_sum = std::max(worst_sum, sk / uk);
        }
      }
    }
  EXPECT_LT(worst_revolute, 1e-12);
  std::printf("[inverse-mass bound] %d coordinates: (M^-1)_kk / beta_k at most %.3f, s_k / u_k at most %.3f "
              "(closures), revolute beta_k the same at every state to %.1e\n",
              coordinates, worst_diag, worst_sum, worst_revolute);
}

}  // namespace
}  // namespace mechanism_sim
