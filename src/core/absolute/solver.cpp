// The two implementations of the solver interface (solver.h) and what they share: the
// refinement on the exact KKT residual, its residual scales, the least-norm multipliers.
#include "core/absolute/solver.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "mechanism_sim/core/model/inertia.h"

namespace mechanism_sim {
namespace {

constexpr double kKappa = ConstraintSolver::kKappa;  // (numerics.h says why 1e7)
using numerics::absolute::kMaxSolvePasses;

// max of |r1| s1 and |r2| s2 (either may be empty: a mechanism without constraints).
inline double scaledMax(const Eigen::VectorXd& r1, const Eigen::VectorXd& s1, const Eigen::VectorXd& r2,
                        const Eigen::VectorXd& s2) {
  double m = 0;  // a zero residual counts as met even where its scale is zero (1/0 = inf)
  for (int i = 0; i < r1.size(); ++i)
    if (r1[i] != 0.0) m = std::max(m, std::fabs(r1[i]) * s1[i]);
  for (int i = 0; i < r2.size(); ++i)
    if (r2[i] != 0.0) m = std::max(m, std::fabs(r2[i]) * s2[i]);
  return m;
}

// T += Jb^T W Jb on the lower triangle only (T a diagonal block of H: the factorization
// reads nothing above it), WJ = W Jb: entry (r, c), r >= c, gains the dot product of
// columns r of Jb and c of WJ. 126 multiply-adds where the full product takes 216.
inline void lowerPenalty(BlockCholesky::Block& T, const Eigen::Ref<const Mat6>& Jb, const Mat6& WJ) {
  forEachColumn6([&](auto column) {
    constexpr int c = decltype(column)::value;
    T.col(c).template tail<6 - c>().noalias() += Jb.template rightCols<6 - c>().transpose() * WJ.col(c);
  });
}

}  // namespace

std::string SolverStats::describe() const {
  std::ostringstream os;
  os.precision(2);
  if (shortfalls() == 0) {
    os << "every iteration met its tolerance (" << solves << " solves, " << position_projections
       << " position and " << velocity_projections << " velocity projections)";
    if (halved_steps) os << "; " << halved_steps << " steps were taken as two halves";
    return os.str();
  }
  os << "iterations short of tolerance:";
  if (solve_shortfalls) os << " " << solve_shortfalls << " of " << solves << " solves (worst relative residual " << worst_solve << ")";
  if (position_shortfalls)
    os << " " << position_shortfalls << " of " << position_projections << " position projections (worst " << worst_position << ")";
  if (velocity_shortfalls)
    os << " " << velocity_shortfalls << " of " << velocity_projections << " velocity projections (worst " << worst_velocity << ")";
  if (halved_steps) os << "; " << halved_steps << " steps were taken as two halves";
  return os.str();
}

// ---- the penalty form

void addPenalty(const System& sys, const Evaluation& ev, int ci, double kappa, BlockCholesky& target,
                const int* address, const char* transposed) {
  const Jacobian& J = ev.J[ci];
  const ConstraintLayout& L = sys.layout[ci];
  const int k = static_cast<int>(L.bodies.size());
  const Vec6 w = kappa * padded(ev.W.data() + L.row, L.size);
  for (int k1 = 0; k1 < k; ++k1) {
    if (L.bodies[k1] < 0) continue;
    const Mat6 WJ = w.asDiagonal() * J.middleCols<6>(6 * k1);
    if (address[k1 * k + k1] >= 0) lowerPenalty(target.block(address[k1 * k + k1]), J.middleCols<6>(6 * k1), WJ);
    for (int k2 = k1 + 1; k2 < k; ++k2) {
      const int a = address[k1 * k + k2];
      if (a < 0) continue;
      if (transposed[k1 * k + k2]) target.block(a).noalias() += J.middleCols<6>(6 * k2).transpose() * WJ;
      else target.block(a).noalias() += WJ.transpose() * J.middleCols<6>(6 * k2);
    }
  }
}

PenaltyForm::PenaltyForm(const System& sys) {
  std::vector<std::pair<int, int>> edges;  // the body graph of H = M + Phi_q^T W Phi_q
  for (const auto& c : sys.constraints)
    for (int b1 : c->bodies())
      for (int b2 : c->bodies())
        if (b1 > 0 && b2 > 0 && b1 < b2) edges.push_back({b1 - 1, b2 - 1});
  addRotorEdges(sys, edges);
  chol_.analyze(sys.nb, edges);
  address_.assign(sys.numConstraints(), {});
  transposed_.assign(sys.numConstraints(), {});
  for (int ci = 0; ci < sys.numConstraints(); ++ci) {
    const ConstraintLayout& L = sys.layout[ci];
    const int k = static_cast<int>(L.bodies.size());
    address_[ci].assign(k * k, -1);
    transposed_[ci].assign(k * k, 0);
    for (int k1 = 0; k1 < k; ++k1)
      for (int k2 = k1; k2 < k; ++k2) {
        const int b1 = L.bodies[k1], b2 = L.bodies[k2];
        if (b1 < 0 || b2 < 0) continue;
        bool t = false;
        address_[ci][k1 * k + k2] = chol_.address(b1, b2, &t);
        transposed_[ci][k1 * k + k2] = t;
      }
  }
}

// H = mass M + shift M~ + kappa sum_c J_c^T W_c J_c, block by block into the factor's
// storage (M~: the stand-in masses of System::Minv, used as Levenberg-Marquardt damping).
void PenaltyForm::assemble(const System& sys, const Evaluation& ev, double kappa, double mass, double shift) {
  chol_.setZero();
  for (int b = 1; b <= sys.nb; ++b) {
    bool t = false;
    auto& D = chol_.block(chol_.address(b - 1, b - 1, &t));
    const Body& B = sys.bodies[b];
    D.topLeftCorner<3, 3>().diagonal().array() += mass * B.m;
    D.bottomRightCorner<3, 3>() += mass * B.Jp;
    if (shift != 0.0) D.diagonal() += shift * sys.Minv[b - 1].diagonal().cwiseInverse();
  }
  for (int ci = 0; ci < sys.numConstraints(); ++ci)
    addPenalty(sys, ev, ci, kappa, chol_, address_[ci].data(), transposed_[ci].data());
  if (mass != 0.0) addRotorBlocks(sys, ev, mass, chol_);
}

// H(b1, b2) += mass G_b1 B G_b2^T per rotor inertia, G_b the 6 x n columns of its
// coordinates' rows on body b (System::rotors; the pairs are in block_edges).
void addRotorBlocks(const System& sys, const Evaluation& ev, double mass, BlockCholesky& H) {
  for (size_t r = 0; r < sys.rotors.size(); ++r) {
    const RotorInertia& R = sys.rotors[r];
    const int n = static_cast<int>(R.coords.size());
    int bodies[4], count = 0;
    Eigen::Matrix<double, 6, 2> G[4];
    for (int c = 0; c < n; ++c) {
      const Joint& J = *sys.joints[R.coords[c].first];
      const int bs[2] = {J.bodyI(), J.bodyJ()};
      for (int s = 0; s < 2; ++s) {
        if (bs[s] == System::kGround) continue;
        int at = 0;
        while (at < count && bodies[at] != bs[s] - 1) ++at;
        if (at == count) bodies[count] = bs[s] - 1, G[count].setZero(), ++count;
        G[at].col(c) += ev.rotor_rows[2 * r + c].J.segment<6>(6 * s).transpose();
      }
    }
    const Eigen::Matrix2d B = mass * R.B;
    for (int i = 0; i < count; ++i)
      for (int j = i; j < count; ++j) {
        bool transposed = false;
        const int a = H.address(bodies[i], bodies[j], &transposed);
        const Mat6 block = G[i] * B * G[j].transpose();
        if (transposed) H.block(a) += block.transpose();
        else H.block(a) += block;
      }
  }
}

void PenaltyForm::factor(const System& sys, Evaluation& ev, const char* where, double t, bool reweight) {
  if (reweight) rowWeights(sys, ev, sys.all_constraints);
  assemble(sys, ev, kKappa, 1.0, 0.0);
  // singular mass blocks: what decides the motions that move no mass (massFloor)
  for (int b = 1; b <= sys.nb; ++b) {
    const Body& B = sys.bodies[b];
    const Vec6 floor = massFloor(B.m, B.Jp, sys.Minv[b - 1].diagonal().cwiseInverse(), sys.mass_scale, sys.inertia_scale);
    bool transposed = false;
    if (!floor.isZero(0.0)) chol_.block(chol_.address(b - 1, b - 1, &transposed)).diagonal() += floor;
  }
  if (chol_.factorize(0.0, false) != 0) {
    std::ostringstream os;
    os << "at t = " << t << " s (" << where << "): the constrained mass matrix is singular; some motion moves no mass";
    throw SimulationError(os.str());
  }
}

// ---- the interface

ConstraintSolver::ConstraintSolver(const System& sys, SolverStats& stats) : stats_(stats), penalty_(sys) {
  auto zeros = [](Eigen::VectorXd& v, int size) { v = Eigen::VectorXd::Zero(size); };
  zeros(r1_, sys.n), zeros(s1_, sys.n), zeros(dn_, sys.n);
  zeros(r2_, sys.m), zeros(s2_, sys.m), zeros(dm_, sys.m), zeros(dl_, sys.m), zeros(zero_rows_, sys.m);
  body_scale_.assign(sys.nb, {0.0, 0.0});
  factored_.x = Eigen::VectorXd::Zero(BodyCoordinates::positions(sys));
  factored_.limit_side.assign(sys.limits.size(), 0);
}

void ConstraintSolver::factor(const System& sys, Evaluation& ev, const char* where, double t, bool reweight) {
  ++stats_.factorizations;
  factored_.x = ev.stamp.x;
  factored_.limit_side = ev.stamp.limit_side;
  factored_.level = EvaluationStamp::kEvaluated;
  factorHere(sys, ev, where, t, reweight);
}

void ConstraintSolver::factorPenalty(const System& sys, Evaluation& ev, const char* where, double t) {
  ++stats_.factorizations;
  factored_.x = ev.stamp.x;
  factored_.limit_side = ev.stamp.limit_side;
  factored_.level = EvaluationStamp::kEvaluated;
  penalty_active_ = true;
  penalty_.factor(sys, ev, where, t, true);
}

void ConstraintSolver::usePenalty(bool describes_evaluation) {
  penalty_active_ = true;
  if (!describes_evaluation) factored_.level = EvaluationStamp::kNone;
}

void ConstraintSolver::preconditionPenalty(const System& sys, const Evaluation& ev, const double* r1,
                                           const double* r2, bool multipliers) {
  if (r1 != dn_.data()) std::copy(r1, r1 + sys.n, dn_.data());
  for (int e = 0; e < sys.m; ++e) dm_[e] = kKappa * ev.W[e] * r2[e];
  addJt(sys, ev, sys.all_constraints, dm_.data(), dn_.data());
  penalty_.solve(dn_.data());
  if (!multipliers) return;
  mulJ(sys, ev, sys.all_constraints, dn_.data(), dm_.data());
  for (int e = 0; e < sys.m; ++e) dl_[e] = kKappa * ev.W[e] * (dm_[e] - r2[e]);
}

void PenaltySolver::factorHere(const System& sys, Evaluation& ev, const char* where, double t, bool reweight) {
  penalty_active_ = true;
  penalty_.factor(sys, ev, where, t, reweight);
}

// ---- the tree KKT form

TreeKktSolver::TreeKktSolver(const System& sys, KktTopology topology, SolverStats& stats)
    : ConstraintSolver(sys, stats), T_(std::move(topology)) {
  kkt_.analyze(T_.nodes, T_.edges, T_.order, T_.signs);
  z_ = Eigen::VectorXd::Zero(6 * T_.nodes);
}

void TreeKktSolver::factorHere(const System& sys, Evaluation& ev, const char* where, double t, bool reweight) {
  if (reweight) rowWeights(sys, ev, T_.penalized);  // the tree's rows have none
  assembleKKT(sys, ev);
  if (kkt_.factorize(0.0, false) == 0) {
    penalty_active_ = false;
    return;
  }
  // a pivot of the tree is not definite (its joint's equations are dependent at this
  // configuration): this factorization takes every equation in penalty form
  penalty_active_ = true;
  penalty_.factor(sys, ev, where, t, true);
}

// The KKT matrix of the tree joints with the other equations in penalty form:
//   bodies: M + kappa sum_p J_p^T W_p J_p;  tree block t, body b: J_tb;  t, t: 0
// (a tree block's rows: its joint's equations, then the drives and limits merged into it;
// -1 on the padding rows past them and on rows that are zero, an inactive limit's or a
// dropped one's: decoupled, dl = -r2, which is 0 in a solve, their gamma being 0).
//
// Every block is written here, none only added to: the blocks the penalized equations add
// to (body pairs) are zeroed first, the others assigned (a tree has no fill), so the
// storage is not swept clean before each factorization.
void TreeKktSolver::assembleKKT(const System& sys, const Evaluation& ev) {
  const KktTopology& T = T_;
  for (int b = 1; b <= sys.nb; ++b) {
    bool t = false;
    auto& D = kkt_.block(kkt_.address(b - 1, b - 1, &t));
    D.setZero();
    D.topLeftCorner<3, 3>().diagonal().array() = sys.bodies[b].m;
    D.bottomRightCorner<3, 3>() = sys.bodies[b].Jp;
  }
  for (int a : T.added) kkt_.block(a).setZero();
  for (int ci : T.penalized) addPenalty(sys, ev, ci, kKappa, kkt_, T.address[ci].data(), T.transposed[ci].data());
  for (int ci = 0; ci < sys.numConstraints(); ++ci) {
    if (T.node[ci] < 0) continue;
    const ConstraintLayout& L = sys.layout[ci];
    const std::vector<KktTopology::NodeRow>& rows = T.node_rows[T.node[ci] - sys.nb];
    const std::vector<int>& address = T.address[ci];
    forEachBlock(sys, ev, ci, [&](int s, int, const auto& Jb) {
      // rows: the joint's equations (zero past its size), then its drives and limits
      BlockCholesky::Block& B = kkt_.block(address[s]);
      if (T.transposed[ci][s]) {
        B = Jb.transpose();
        for (size_t r = L.size; r < rows.size(); ++r)
          B.col(r) = ev.J[rows[r].constraint].row(rows[r].e).template segment<6>(6 * s).transpose();
      } else {
        B = Jb;
        for (size_t r = L.size; r < rows.size(); ++r)
          B.row(r) = ev.J[rows[r].constraint].row(rows[r].e).template segment<6>(6 * s);
      }
    });
    auto& D = kkt_.block(address.back());
    D.setZero();
    const int size = static_cast<int>(rows.size());
    for (int e = size; e < 6; ++e) D(e, e) = -1.0;
    if (!ev.dropped.empty())
      for (int e = 0; e < L.size; ++e)
        if (ev.dropped[L.row + e]) D(e, e) = -1.0;
    for (int e = L.size; e < size; ++e)  // an inactive limit's row is zero
      if (ev.J[rows[e].constraint].row(rows[e].e).squaredNorm() == 0.0) D(e, e) = -1.0;
  }
}

void TreeKktSolver::precondition(const System& sys, const Evaluation& ev, const double* r1, const double* r2,
                                 bool multipliers) {
  if (penalty_active_) {
    preconditionPenalty(sys, ev, r1, r2, multipliers);
    return;
  }
  // the tree blocks' rows exactly, the others (drives and limits that did not fit) weighted
  const KktTopology& T = T_;
  const std::vector<int>& pen = T.penalized;
  for (int ci : pen) {
    const ConstraintLayout& L = sys.layout[ci];
    for (int e = 0; e < L.size; ++e) dm_[L.row + e] = kKappa * ev.W[L.row + e] * r2[L.row + e];
  }
  z_.head(sys.n) = Eigen::Map<const Eigen::VectorXd>(r1, sys.n);  // the bodies' rows of z_
  addJt(sys, ev, pen, dm_.data(), z_.data());
  for (size_t k = 0; k < T.node_rows.size(); ++k) {
    double* zc = z_.data() + 6 * (sys.nb + k);
    const size_t size = T.node_rows[k].size();
    for (size_t r = 0; r < size; ++r) zc[r] = r2[T.node_rows[k][r].row];
    for (size_t r = size; r < 6; ++r) zc[r] = 0.0;
  }
  kkt_.solve(z_.data());
  dn_ = z_.head(sys.n);
  if (multipliers)
    for (size_t k = 0; k < T.node_rows.size(); ++k)
      for (size_t r = 0; r < T.node_rows[k].size(); ++r) dl_[T.node_rows[k][r].row] = z_[6 * (sys.nb + k) + r];
  if (!multipliers) return;
  mulJ(sys, ev, pen, dn_.data(), dm_.data());
  for (int ci : pen) {
    const ConstraintLayout& L = sys.layout[ci];
    for (int e = L.row; e < L.row + L.size; ++e) dl_[e] = kKappa * ev.W[e] * (dm_[e] - r2[e]);
  }
}

std::unique_ptr<ConstraintSolver> makeSolver(const System& sys, SolverStats& stats) {
  KktTopology topology = kktTopology(sys);
  if (topology.tree) return std::make_unique<TreeKktSolver>(sys, std::move(topology), stats);
  return std::make_unique<PenaltySolver>(sys, stats);
}

// ---- refinement on the exact KKT residual

// The residual scales of solve(): the size of the terms each residual was computed from, as
// inverses: per body, the largest force (torque) term of its three components, forces and
// torques measured against each other through the length scale; per equation, |gamma| +
// |J_r| |a_r|max + |J_theta| |a_theta|max. Both have a floor at kFloor of the system's
// largest.
void ConstraintSolver::residualScales(const System& sys, const Evaluation& ev, const Eigen::VectorXd& a,
                                      const Eigen::VectorXd& lambda) {
  const double length = sys.length_scale;
  // accelerations: at least the centripetal scale V^2 / L of the motion
  double V = 0;  // of the loaded state
  for (int b = 1; b <= sys.nb; ++b)
    V = std::max({V, ev.kin[b].v.cwiseAbs().maxCoeff(), ev.kin[b].w.cwiseAbs().maxCoeff() * length});
  mulM(sys, a.data(), s1_.data());
  addRotorMass(sys, ev, a.data(), s1_.data());
  for (int i = 0; i < sys.n; ++i) s1_[i] = std::fabs(ev.Q[i]) + std::fabs(s1_[i]);
  // ... and at least what the loads alone would do (a mechanism at rest against stops has
  // accelerations of round-off size: they are not the scale of its equations)
  double F = 0;  // the largest applied force, torques through the length scale
  for (int i = 0; i < sys.n; i += 6)
    F = std::max({F, ev.Q.segment<3>(i).cwiseAbs().maxCoeff(), ev.Q.segment<3>(i + 3).cwiseAbs().maxCoeff() / length});
  const double a_floor =
      kFloor * std::max({motionScale(sys, a), V * V / length, sys.acceleration_scale, F / sys.mass_scale});
  for (int e = 0; e < sys.m; ++e) s2_[e] = std::fabs(ev.gamma[e]);
  bodyScales(sys, a, a_floor, body_scale_);
  for (int ci = 0; ci < sys.numConstraints(); ++ci) {
    const ConstraintLayout& L = sys.layout[ci];
    const Vec6 lam = padded(lambda.data() + L.row, L.size);
    Vec6 jas = Vec6::Zero();
    forEachBlock(sys, ev, ci, [&](int, int b, const auto& Jb) {
      const std::array<double, 2>& as = body_scale_[b];
      jas += Jb.template leftCols<3>().cwiseAbs().rowwise().sum() * as[0] +
             Jb.template rightCols<3>().cwiseAbs().rowwise().sum() * as[1];
      Eigen::Map<Vec6>(s1_.data() + BodyCoordinates::u(b)) += (Jb.transpose() * lam).cwiseAbs();
    });
    for (int e = 0; e < L.size; ++e) s2_[L.row + e] += jas[e];
  }
  double f_floor = 0;  // the largest force in the system (torques through the length scale)
  for (int i = 0; i < sys.n; i += 6)
    f_floor = std::max({f_floor, s1_[i], s1_[i + 1], s1_[i + 2], (s1_[i + 3] + s1_[i + 4] + s1_[i + 5]) / length});
  f_floor *= kFloor;
  // A mechanism without mass (a kinematic one, doc/method.md "Kinematic models") has forces
  // of round-off size only: they are weighed against the stand-in mass at the floor
  // acceleration, so its solves are judged on the equations Phi_q a = gamma.
  bool massless = sys.nb > 0;
  for (int b = 1; b <= sys.nb && massless; ++b) massless = sys.bodies[b].m == 0.0;
  if (massless) f_floor = std::max(f_floor, sys.mass_scale * a_floor);
  for (int i = 0; i < sys.n; i += 6) {
    const double f = std::max({s1_[i], s1_[i + 1], s1_[i + 2]});
    const double n = std::max({s1_[i + 3], s1_[i + 4], s1_[i + 5]});
    const double fs = std::max({f, n / length, f_floor});
    const double ns = std::max({n, f * length, f_floor * length});
    for (int c = 0; c < 3; ++c) s1_[i + c] = fs > 0 ? 1.0 / fs : HUGE_VAL, s1_[i + 3 + c] = ns > 0 ? 1.0 / ns : HUGE_VAL;
  }
  for (int e = 0; e < sys.m; ++e) s2_[e] = s2_[e] > 0 ? 1.0 / s2_[e] : HUGE_VAL;
}

// Iterative refinement of the KKT system  [M J^T; J 0] [a; lambda] = [Q; gamma]  with the
// regularized matrix [M J^T; J -W^-1] as preconditioner (precondition(); W = 0 on the
// rows of the tree KKT factorization, which holds them exactly):
//   r1 = Q - M a - J^T lambda,  r2 = gamma - J a,
//   H da = r1 + J^T W r2,  dlambda = W (J da - r2)   (H = M + J^T W J).
// With H factored at the current J one pass is the augmented Lagrangian update (Bayo &
// Ledesma 1996) made exact by also correcting r1 (the round-off of H, which grows with
// kappa); on a tree, one pass solves to round-off. It stops when every residual is within
// solve_tol of the size of the terms it was computed from (a componentwise backward
// error: independent of units); the scales are taken from the warm start (or, from a
// cold one, after the first update). A shortfall is counted.
//
// H from nearby positions (HState::kNearby: the last stage's, for the state the step
// reached) still contracts the error, more slowly the further its Jacobian is from this
// one; when a pass gains less than a factor 1 / kNearbyGain, H is factored here and the
// passes go on (rather than stopping short).
bool ConstraintSolver::solve(const System& sys, Evaluation& ev, Eigen::VectorXd& a, Eigen::VectorXd& lam,
                             HState hstate, double t, bool rescale) {
  constexpr double kNearbyGain = numerics::absolute::kNearbyGain;
  const double tol = sys.options.solve_tol;
  double res = 0, previous_res = HUGE_VAL;
  // warm (a, lambda from a nearby solve): their sizes are the solution's to O(h); cold
  // (nothing yet): the scales are taken again after the first update
  const bool cold = (sys.n > 0 && a.cwiseAbs().maxCoeff() == 0.0) || (sys.m > 0 && lam.cwiseAbs().maxCoeff() == 0.0);
  if (rescale || cold) residualScales(sys, ev, a, lam);
  for (int pass = 0;; ++pass) {
    mulM(sys, a.data(), r1_.data());
    addRotorMass(sys, ev, a.data(), r1_.data());
    for (int i = 0; i < sys.n; ++i) r1_[i] = ev.Q[i] - r1_[i];
    for (int ci = 0; ci < sys.numConstraints(); ++ci) {
      const ConstraintLayout& L = sys.layout[ci];
      const Vec6 l = padded(lam.data() + L.row, L.size);
      Vec6 ja = Vec6::Zero();
      forEachBlock(sys, ev, ci, [&](int, int b, const auto& Jb) {
        const int col = BodyCoordinates::u(b);
        ja.noalias() += Jb * Eigen::Map<const Vec6>(a.data() + col);
        Eigen::Map<Vec6>(r1_.data() + col).noalias() -= Jb.transpose() * l;
      });
      for (int e = 0; e < L.size; ++e) r2_[L.row + e] = ev.gamma[L.row + e] - ja[e];
    }
    res = scaledMax(r1_, s1_, r2_, s2_);
    if (cold && pass == 1) {
      residualScales(sys, ev, a, lam);
      res = scaledMax(r1_, s1_, r2_, s2_);
    }
    if (res <= tol) {
      ++stats_.solves;
      return true;
    }
    if (hstate == HState::kNearby && pass >= 1 && res > kNearbyGain * previous_res) {
      factor(sys, ev, "stage", t, false);
      hstate = HState::kCurrent;
    } else if (pass == kMaxSolvePasses || (pass >= 2 && res > 0.5 * previous_res)) {
      // No progress: what is left is inconsistent (equations that are dependent at this
      // very configuration, e.g. a parallelogram passing flat). Further passes would only
      // push the iterate along the nearly dependent direction: keep the better of the last
      // two iterates (the last pass is undone when it made things worse), count it.
      if (res > previous_res) {
        a -= dn_;
        lam -= dl_;
        res = previous_res;
      }
      break;
    }
    previous_res = res;
    if (hstate == HState::kNone) factor(sys, ev, "stage 1", t), hstate = HState::kCurrent;
    ++stats_.solve_passes;
    precondition(sys, ev, r1_.data(), r2_.data(), true);
    a += dn_;
    lam += dl_;
  }
  ++stats_.solves;
  ++stats_.solve_shortfalls;
  stats_.worst_solve = std::max(stats_.worst_solve, res);
  return false;
}

// Least-norm multipliers (solver.h). With every row in J (the dependent ones too) and H =
// M + kappa J^T W J factored, the iteration
//   r = g - J^T lambda,  lambda += kappa W J H^-1 r,   from lambda = 0,   g = Q - M a,
// keeps lambda in the range of W J, where the solution of J^T lambda = g with the least
// sum lambda_e^2 / W_e lies; in W-scaled coordinates it contracts the error by about
// 1 / (kappa sigma) per pass on that range (sigma as in solve()) and leaves the null space
// of J^T (the dependencies) alone, so it converges to the least-norm solution.
double minimumNormMultipliers(const System& sys, const State& s, const Inputs& in, Evaluation& ev,
                              ConstraintSolver& solver, SolverStats& stats, Eigen::VectorXd& lambda) {
  State all = s;
  std::fill(all.dropped.begin(), all.dropped.end(), 0);
  evaluateAt(sys, all, ev);
  ++stats.evaluations;
  solver.factorPenalty(sys, ev, "reactions", s.t);  // penalty form: all rows weighted alike
  appliedForces(sys, all, in, sys.damping, all.friction, ev);
  Eigen::VectorXd& dn = solver.dn();
  Eigen::VectorXd dm(sys.m);
  // g = Q - M a: the constraint forces (the limits' part taken out: they keep their own)
  mulM(sys, s.acc.data(), dn.data());
  addRotorMass(sys, ev, s.acc.data(), dn.data());
  Eigen::VectorXd g = ev.Q - dn;
  Eigen::VectorXd limit_lambda = Eigen::VectorXd::Zero(sys.m);
  limit_lambda.tail(sys.m - sys.m_eq) = s.lambda.tail(sys.m - sys.m_eq);
  dn.setZero();
  addJt(sys, ev, sys.all_constraints, limit_lambda.data(), dn.data());
  g -= dn;
  const double length = sys.length_scale;
  double g_scale = 0;  // forces and torques through the length scale
  for (int i = 0; i < sys.n; i += 6)
    g_scale = std::max({g_scale, g.segment<3>(i).cwiseAbs().maxCoeff(), g.segment<3>(i + 3).cwiseAbs().maxCoeff() / length});
  lambda = Eigen::VectorXd::Zero(sys.m);
  double res = 0;
  for (int pass = 0; pass < kMaxSolvePasses + 8; ++pass) {
    dn = g;
    dm = -lambda;
    addJt(sys, ev, sys.all_constraints, dm.data(), dn.data());  // r = g - J^T lambda
    res = 0;
    for (int i = 0; i < sys.n; i += 6)
      res = std::max({res, dn.segment<3>(i).cwiseAbs().maxCoeff(), dn.segment<3>(i + 3).cwiseAbs().maxCoeff() / length});
    res = g_scale > 0 ? res / g_scale : 0.0;
    if (res <= sys.options.solve_tol * 100) break;
    solver.penalty().solve(dn.data());
    mulJ(sys, ev, sys.all_constraints, dn.data(), dm.data());
    for (int e = 0; e < sys.m_eq; ++e) lambda[e] += kKappa * ev.W[e] * dm[e];
  }
  lambda.tail(sys.m - sys.m_eq) = s.lambda.tail(sys.m - sys.m_eq);
  ++stats.solves;
  if (res > sys.options.solve_tol * 100) {
    ++stats.solve_shortfalls;
    stats.worst_solve = std::max(stats.worst_solve, res);
  }
  return res;
}

}  // namespace mechanism_sim
