// The two implementations of the solver interface (solver.h) check each other, in the
// Pinocchio habit of one algorithm checking another: on random trees of every joint type,
// with drives, active limits and applied efforts, the tree KKT form and the penalty form
// give the same accelerations and multipliers, and both solve the KKT system itself
//   M a + Phi_q^T lambda = Q,   Phi_q a = gamma
// (the known answer both are measured against).
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "bodies.h"
#include "mechanism_sim/core/mechanism.h"
#include "core/absolute/solver.h"

namespace mechanism_sim {
namespace {

using test_util::frame;

struct RandomTree {
  Mechanism m;
  std::mt19937 rng;
  double uniform(double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(rng); }
  Matrix3d rotation() {
    return Quaterniond(uniform(-1, 1), uniform(-1, 1), uniform(-1, 1), uniform(-1, 1)).normalized().toRotationMatrix();
  }

  // n bodies, each jointed to an earlier one (or the ground) at a point between them; the
  // joint frames coincide in space, so the initial pose is assembled (q = 0). Lengths in
  // units of `scale` metres.
  RandomTree(unsigned seed, int n, double scale) : rng(seed) {
    const char* types[] = {"revolute", "prismatic", "cylindrical", "screw", "universal", "spherical", "planar"};
    std::vector<Vector3d> r(1, Vector3d::Zero());
    std::vector<Matrix3d> A(1, Matrix3d::Identity());
    for (int b = 1; b <= n; ++b) {
      const int parent = std::uniform_int_distribution<int>(0, b - 1)(rng);
      const Vector3d P = r[parent] + scale * Vector3d(uniform(-1, 1), uniform(-1, 1), uniform(-1, 1));
      const Vector3d rb = P + scale * Vector3d(uniform(-1, 1), uniform(-1, 1), uniform(-1, 1));
      const Matrix3d Ab = rotation(), R = rotation();
      const double mass = uniform(0.5, 3.0);
      const Vector3d I = mass * scale * scale * Vector3d(uniform(0.1, 0.2), uniform(0.1, 0.2), uniform(0.1, 0.2));
      Body body = test_util::body("b" + std::to_string(b), mass, I, rb);
      body.p = Quaterniond(Ab);
      body.v = scale * Vector3d(uniform(-1, 1), uniform(-1, 1), uniform(-1, 1));
      body.w = Vector3d(uniform(-1, 1), uniform(-1, 1), uniform(-1, 1));
      m.addBody(body);
      r.push_back(rb), A.push_back(Ab);
      const std::string type = types[std::uniform_int_distribution<int>(0, 6)(rng)];
      JointParams params;
      params.alpha = 0.1 * scale;
      m.addJoint(makeJoint(type, "j" + std::to_string(b), parent, frame(A[parent].transpose() * (P - r[parent]), A[parent].transpose() * R),
                           b, frame(Ab.transpose() * (P - rb), Ab.transpose() * R), params));
    }
    m.setGravity(Vector3d(0, 0, -9.81));
    // a drive and limits on a few holonomic coordinates
    bool driven = false;
    for (int j = 0; j < n; ++j) {
      const Joint& jt = m.joint(j);
      if (!jt.holonomicCoordinates() || jt.dof() == 0) continue;
      if (!driven) m.addDrive(j, 0, DriveProfile::velocity(0.3 * (jt.type() == "prismatic" ? scale : 1.0))), driven = true;
      else if (j % 2 == 0) m.setJointLimits(j, jt.dof() - 1, -1.0, 1.0);
    }
    m.build();
    m.assemble();
  }
};

struct Solved {
  Eigen::VectorXd a, lambda;
};

// Accelerations and multipliers of state s by one implementation, checked against the KKT
// system itself (relative residuals returned in residual).
Solved solveWith(ConstraintSolver& solver, const System& sys, const State& s, const Inputs& in, double* residual) {
  Evaluation ev(sys);
  evaluateAt(sys, s, ev);
  appliedForces(sys, s, in, sys.damping, s.friction, ev);
  solver.factor(sys, ev, "test", s.t);
  Solved out{Eigen::VectorXd::Zero(sys.n), Eigen::VectorXd::Zero(sys.m)};
  EXPECT_TRUE(solver.solve(sys, ev, out.a, out.lambda, ConstraintSolver::HState::kCurrent, s.t));
  // Normwise backward error: r1 = Q - M a - J^T lambda against the largest of |Q|, |M a|,
  // |J^T lambda| (torques over the length scale L: scale-free), r2 = gamma - J a against the
  // largest of |gamma| + |J_r| |a_r| + |J_theta| |a_theta| L over the rows.
  Eigen::VectorXd Ma(sys.n), Jtl = Eigen::VectorXd::Zero(sys.n), Ja(sys.m);
  mulM(sys, out.a.data(), Ma.data());
  addJt(sys, ev, sys.all_constraints, out.lambda.data(), Jtl.data());
  mulJ(sys, ev, sys.all_constraints, out.a.data(), Ja.data());
  const double L = sys.length_scale;
  auto forceNorm = [&](const Eigen::VectorXd& f) {
    double n = 0;
    for (int i = 0; i < sys.n; i += 6)
      n = std::max({n, f.segment<3>(i).cwiseAbs().maxCoeff(), f.segment<3>(i + 3).cwiseAbs().maxCoeff() / L});
    return n;
  };
  const double f_scale = std::max({forceNorm(ev.Q), forceNorm(Ma), forceNorm(Jtl)});
  double a_scale = 0;
  for (int c = 0; c < sys.numConstraints(); ++c)
    for (int e = 0; e < sys.layout[c].size; ++e) {
      double terms = std::fabs(ev.gamma[sys.layout[c].row + e]);
      forEachBlock(sys, ev, c, [&](int, int b, const auto& Jb) {
        terms += Jb.row(e).template head<3>().cwiseAbs().sum() * out.a.segment<3>(6 * b).cwiseAbs().maxCoeff() +
                 Jb.row(e).template tail<3>().cwiseAbs().sum() * out.a.segment<3>(6 * b + 3).cwiseAbs().maxCoeff() * L;
      });
      a_scale = std::max(a_scale, terms);
    }
  *residual = std::max(forceNorm(ev.Q - Ma - Jtl) / f_scale, sys.m ? (ev.gamma - Ja).cwiseAbs().maxCoeff() / a_scale : 0.0);
  return out;
}

double relativeDifference(const Eigen::VectorXd& x, const Eigen::VectorXd& y) {
  const double scale = std::max(x.cwiseAbs().maxCoeff(), y.cwiseAbs().maxCoeff());
  return scale > 0 ? (x - y).cwiseAbs().maxCoeff() / scale : 0.0;
}

void compareForms(double scale, const char* label) {
  double worst_a = 0, worst_l = 0, worst_res = 0;
  int active = 0;
  for (unsigned seed = 1; seed <= 24; ++seed) {
    RandomTree t(seed, 2 + static_cast<int>(seed % 11), scale);
    const System& sys = t.m.system();
    ASSERT_TRUE(kktTopology(sys).tree) << "seed " << seed << ": a random tree is not solved as a tree";
    State s = t.m.state();
    // the limits active, half on each side: their rows join the joints' blocks
    for (size_t l = 0; l < s.limit_side.size(); ++l) s.limit_side[l] = (l % 2) ? 1 : -1, ++active;
    Inputs in = zeroInputs(sys);
    std::mt19937 rng(seed);
    for (auto& e : in.effort)
      for (double& x : e) x = scale * std::uniform_real_distribution<double>(-2, 2)(rng);
    SolverStats stats;
    TreeKktSolver tree(sys, kktTopology(sys), stats);
    PenaltySolver penalty(sys, stats);
    double res_tree = 0, res_pen = 0;
    const Solved a = solveWith(tree, sys, s, in, &res_tree);
    const Solved b = solveWith(penalty, sys, s, in, &res_pen);
    worst_a = std::max(worst_a, relativeDifference(a.a, b.a));
    worst_l = std::max(worst_l, relativeDifference(a.lambda, b.lambda));
    worst_res = std::max({worst_res, res_tree, res_pen});
    EXPECT_LT(relativeDifference(a.a, b.a), 1e-10) << label << " seed " << seed;
    EXPECT_LT(relativeDifference(a.lambda, b.lambda), 1e-10) << label << " seed " << seed;
    EXPECT_LT(res_tree, 1e-12) << label << " seed " << seed;
    EXPECT_LT(res_pen, 1e-12) << label << " seed " << seed;
  }
  EXPECT_GT(active, 0) << "no limit was active: the merged rows went untested";
  std::printf("[%s] 24 random trees (%d active limits): accelerations differ by %.2e, multipliers by %.2e "
              "(relative); KKT residual at most %.2e\n",
              label, active, worst_a, worst_l, worst_res);
}

TEST(SolverForms, TreeKktAndPenaltyAgreeOnRandomTrees) { compareForms(1.0, "m"); }
TEST(SolverForms, TreeKktAndPenaltyAgreeOnRandomTreesInMillimetres) { compareForms(1e-3, "mm"); }

// Chosen once per mechanism: a tree gets the tree KKT form, a loop the penalty form.
TEST(SolverForms, TheFormIsChosenByTheTopology) {
  RandomTree t(7, 5, 1.0);
  SolverStats stats;
  EXPECT_STREQ(makeSolver(t.m.system(), stats)->name(), "tree KKT");
  Mechanism loop;  // a rod hinged to the ground at both ends: a closed chain
  const int b = loop.addBody(test_util::body("rod", 1.0, Vector3d(0.1, 0.1, 0.01), Vector3d(0, 0, 0)));
  loop.addJoint(makeJoint("revolute", "a", Mechanism::kGround, frame(Vector3d(-0.5, 0, 0)), b, frame(Vector3d(-0.5, 0, 0))));
  loop.addJoint(makeJoint("revolute", "b", Mechanism::kGround, frame(Vector3d(0.5, 0, 0)), b, frame(Vector3d(0.5, 0, 0))));
  loop.build();
  EXPECT_FALSE(kktTopology(loop.system()).tree);
  EXPECT_STREQ(makeSolver(loop.system(), stats)->name(), "penalty");
}

}  // namespace
}  // namespace mechanism_sim
