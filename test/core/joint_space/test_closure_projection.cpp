// The closures' projections (closure_projection.cpp) for what they compute, against dense
// formulas (the oracle: H by the composite-rigid-body algorithm, G from the closures'
// evaluation, Eigen's complete orthogonal decomposition for the pseudo-inverse):
//   rates:     q_dot* = q_dot - H^-1 G^T (G H^-1 G^T)^+ (G q_dot - nu), the H-nearest rates on
//              the closures, in one correction;
//   positions: each Newton step dq = -H^-1 G^T (G H^-1 G^T)^+ Phi, until Phi = 0;
//   retract:   q (+) dv moves Phi by G dv to first order, spherical joints included.
// On a planar four-bar (idle out-of-plane rows, two kept) and a spatial RSSR loop (a spherical
// joint on the tree, in quaternions).
#include <gtest/gtest.h>

#include <random>

#include <Eigen/QR>

#include "core/joint_space/loop_closure.h"
#include "loop_cases.h"
#include "random_loops.h"

namespace mechanism_sim {
namespace {

using test_util::Builder;
using test_util::isTranslation;
using test_util::uniform;

struct Case {
  const char* name;
  Builder (*build)(double, double);
};
const Case kCases[] = {{"four-bar", test_util::fourBar}, {"rssr", test_util::rssr}};

// H, G, nu and Phi at q (rates q_dot for nu's kinematics)
struct Dense {
  Eigen::MatrixXd H, G;
  Eigen::VectorXd nu, Phi;
};
Dense denseAt(const TreeModel& model, const System& sys, LoopClosures& cl, TreeWorkspace& ws, const Eigen::VectorXd& q) {
  Dense d;
  forwardKinematics(model, q, Eigen::VectorXd::Zero(model.nv), ws);
  cl.evaluate(model, sys, ws, q);
  AlignedVector<Matrix6d> Ic;
  d.H.setZero(model.nv, model.nv);  // (the CRBA writes the entries of one branch only)
  jointSpaceInertia(model, ws, Ic, d.H);
  d.G = cl.G.topRows(cl.m);
  d.nu = cl.nu.head(cl.m);
  d.Phi = cl.Phi.head(cl.m);
  return d;
}

// -H^-1 G^T (G H^-1 G^T)^+ r
Eigen::VectorXd massNearestCorrection(const Dense& d, const Eigen::VectorXd& r) {
  const Eigen::MatrixXd HinvGt = d.H.ldlt().solve(d.G.transpose());
  const Eigen::MatrixXd A = d.G * HinvGt;
  return -HinvGt * A.completeOrthogonalDecomposition().solve(r);
}

Eigen::VectorXd randomRates(const TreeModel& model, double L, std::mt19937& rng) {
  Eigen::VectorXd qd(model.nv);
  for (const TreeLink& Lk : model.links)
    for (int k = 0; k < Lk.nv; ++k) qd(Lk.iv + k) = uniform(rng, -2, 2) * (isTranslation(Lk, k) ? L : 1.0);
  return qd;
}

TEST(ClosureProjection, RatesGoToTheMassNearestRatesOnTheClosuresInOneCorrection) {
  for (const Case& c : kCases)
    for (const double L : {1.0, 1e-3}) {
      SCOPED_TRACE(std::string(c.name) + " L " + std::to_string(L));
      Builder b = c.build(L, 1.0);
      System& sys = *b.sys;
      sys.finalize();
      TreeModel model(sys);
      TreeWorkspace ws(model);
      LoopClosures cl(model, sys);
      std::mt19937 rng(11);
      const Eigen::VectorXd q = model.neutralPositions(sys);
      const Dense d = denseAt(model, sys, cl, ws, q);
      ASSERT_GT(cl.m, 0);
      Eigen::VectorXd qd = randomRates(model, L, rng);
      const Eigen::VectorXd expected = qd + massNearestCorrection(d, d.G * qd - d.nu);
      const ClosureProjectionReport r = projectClosureVelocities(model, sys, cl, q, qd, ws);
      EXPECT_TRUE(r.converged);
      EXPECT_LE(r.iterations, 2);  // one correction, and at most one of round-off
      const double V = expected.cwiseAbs().maxCoeff();
      EXPECT_LE((qd - expected).cwiseAbs().maxCoeff(), 1e-12 * V);
      EXPECT_LE((d.G * qd - d.nu).cwiseAbs().maxCoeff(), 1e-12 * (d.G.cwiseAbs() * qd.cwiseAbs()).maxCoeff());
      // rates on the closures already: nothing moves, no solve
      const Eigen::VectorXd on = qd;
      const ClosureProjectionReport again = projectClosureVelocities(model, sys, cl, q, qd, ws);
      EXPECT_EQ(again.iterations, 0);
      EXPECT_EQ(qd, on);
    }
}

TEST(ClosureProjection, PositionsTakeMassWeightedLeastNormNewtonStepsOntoTheClosures) {
  for (const Case& c : kCases)
    for (const double L : {1.0, 1e-3}) {
      SCOPED_TRACE(std::string(c.name) + " L " + std::to_string(L));
      Builder b = c.build(L, 1.0);
      System& sys = *b.sys;
      sys.finalize();
      TreeModel model(sys);
      TreeWorkspace ws(model);
      LoopClosures cl(model, sys);
      std::mt19937 rng(12);
      const Eigen::VectorXd closed = model.neutralPositions(sys);
      // off the closures by a small random turn and slide of every coordinate
      Eigen::VectorXd q = closed;
      retract(model, q, 0.02 * randomRates(model, L, rng));
      const Dense d0 = denseAt(model, sys, cl, ws, q);
      ASSERT_GT(d0.Phi.cwiseAbs().maxCoeff(), 1e-4 * L);
      // one step: q (+) dq with the dense dq
      Eigen::VectorXd expected = q;
      retract(model, expected, massNearestCorrection(d0, d0.Phi));
      Eigen::VectorXd one = q;
      const ClosureProjectionReport first = projectClosurePositions(model, sys, cl, one, ws, 1e-13, 1);
      EXPECT_EQ(first.iterations, 1);
      EXPECT_LE((one - expected).cwiseAbs().maxCoeff(), 1e-12);
      // to the end: on the closures, in Newton's few steps
      const ClosureProjectionReport all = projectClosurePositions(model, sys, cl, q, ws);
      EXPECT_TRUE(all.converged);
      EXPECT_LE(all.iterations, 6);  // Newton's quadratic convergence
      const Dense d = denseAt(model, sys, cl, ws, q);
      EXPECT_LE(d.Phi.cwiseAbs().maxCoeff(), 1e-13 * L);
    }
}

TEST(ClosureProjection, RetractMovesPhiByGdvToFirstOrder) {
  for (const Case& c : kCases) {
    SCOPED_TRACE(c.name);
    Builder b = c.build(1.0, 1.0);
    System& sys = *b.sys;
    sys.finalize();
    TreeModel model(sys);
    TreeWorkspace ws(model);
    LoopClosures cl(model, sys);
    std::mt19937 rng(13);
    Eigen::VectorXd q = model.neutralPositions(sys);
    retract(model, q, 0.3 * randomRates(model, 1.0, rng));  // away from the built pose
    const Dense d = denseAt(model, sys, cl, ws, q);
    const Eigen::VectorXd dv = randomRates(model, 1.0, rng);
    const double s = 1e-6;
    Eigen::VectorXd plus = q, minus = q;
    retract(model, plus, s * dv);
    retract(model, minus, -s * dv);
    const Eigen::VectorXd fd = (denseAt(model, sys, cl, ws, plus).Phi - denseAt(model, sys, cl, ws, minus).Phi) / (2 * s);
    EXPECT_LE((fd - d.G * dv).cwiseAbs().maxCoeff(), 1e-8 * (d.G.cwiseAbs() * dv.cwiseAbs()).maxCoeff());
  }
}

}  // namespace
}  // namespace mechanism_sim
