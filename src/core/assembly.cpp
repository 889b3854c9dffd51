// Assembly (a function of System, State, a Stepper's evaluation record and solver): bring rough
// positions onto the constraints, check that every free motion moves mass, find the
// dependent equations, and project the velocities.
#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <random>
#include <sstream>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include "core/joint_space/tree.h"
#include "core/assembly.h"
#include "core/absolute/projection.h"
#include "core/absolute/stepper.h"
#include "core/numerics.h"
#include "core/linalg/sparse_ldlt.h"

namespace mechanism_sim {
namespace {


// Assembly's iteration caps and thresholds (numerics.h says why each has its value).
using namespace numerics::assembly;

// The constrained mass matrix H cannot be factored at the assembled pose although every
// motion moves mass (checkMassRank passed): its condition is past double precision.
constexpr const char* kSingularAtAssembly =
    "assembly: the constrained mass matrix is numerically singular at the initial pose; the "
    "model's lengths differ too much for double precision (a centre of mass far from the "
    "joints of its link?)";

// The moving bodies that the motions moving no mass move. Such a motion v has each body's
// part v_b in the null space of the body's mass block diag(m I, Jp) (all of it for a body
// with neither mass nor inertia, the rotations of a point mass), and meets Phi_q v = 0 with
// every other body still: the null space of W^1/2 Phi_q N, N the bases of those null
// spaces, gives every such motion and every body it moves (dense, on the bodies with a
// singular mass block only, and only when assembly refuses the model).
std::vector<int> bodiesMovingNoMass(const System& sys, const Evaluation& ev) {
  std::vector<Eigen::MatrixXd> basis(sys.nb + 1);  // N_b, 6 x k_b (k_b = 0: the body's motions all move mass)
  std::vector<int> column(sys.nb + 1, 0);
  int k = 0;
  for (int b = 1; b <= sys.nb; ++b) {
    const Body& B = sys.bodies[b];
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(B.Jp);
    std::vector<Eigen::Matrix<double, 6, 1>> free;
    if (!(B.m > 1e-12 * sys.mass_scale))
      for (int i = 0; i < 3; ++i) free.push_back(Eigen::Matrix<double, 6, 1>::Unit(i));
    for (int i = 0; i < 3; ++i)
      if (!(eig.eigenvalues()(i) > 1e-12 * sys.inertia_scale)) {
        Eigen::Matrix<double, 6, 1> v = Eigen::Matrix<double, 6, 1>::Zero();
        v.tail<3>() = eig.eigenvectors().col(i);
        free.push_back(v);
      }
    basis[b].resize(6, static_cast<int>(free.size()));
    for (size_t i = 0; i < free.size(); ++i) basis[b].col(static_cast<int>(i)) = free[i];
    column[b] = k;
    k += static_cast<int>(free.size());
  }
  std::vector<int> moved;
  if (k == 0) return moved;
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(sys.m, k);
  for (int ci = 0; ci < sys.numConstraints(); ++ci) {
    const ConstraintLayout& L = sys.layout[ci];
    for (size_t slot = 0; slot < L.bodies.size(); ++slot) {
      const int b = L.bodies[slot] + 1;
      if (b < 1 || basis[b].cols() == 0) continue;
      for (int r = 0; r < L.size; ++r)
        A.row(L.row + r).segment(column[b], basis[b].cols()) +=
            std::sqrt(ev.W(L.row + r)) * ev.J[ci].row(r).segment<6>(6 * static_cast<int>(slot)) * basis[b];
    }
  }
  const Eigen::MatrixXd AtA = A.transpose() * A;
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(AtA);
  const double largest = std::max(eig.eigenvalues().cwiseAbs().maxCoeff(), 1e-300);
  std::vector<char> moves(sys.nb + 1, 0);
  for (int i = 0; i < k; ++i) {
    if (eig.eigenvalues()(i) > 1e-10 * largest && largest > 1e-300) continue;
    const Eigen::VectorXd z = eig.eigenvectors().col(i);
    for (int b = 1; b <= sys.nb; ++b)
      if (basis[b].cols() > 0 && z.segment(column[b], basis[b].cols()).norm() > 1e-6) moves[b] = 1;
  }
  for (int b = 1; b <= sys.nb; ++b)
    if (moves[b]) moved.push_back(b);
  return moved;
}

// M + Phi_q^T W Phi_q (W: row weights, so the matrix is well conditioned) must be positive
// definite: every motion the joints allow moves some mass. Otherwise the message names
// every body that a motion moving no mass moves (bodiesMovingNoMass), or, should that find
// none (a matrix singular by its condition alone), the bodies of the zero pivots.
void checkMassRank(const System& sys, Evaluation& ev, PenaltyForm& H) {
  rowWeights(sys, ev, sys.all_constraints);
  H.assemble(sys, ev, 1.0, 1.0, 0.0);
  if (H.factorize(1e-10, true) == 0) return;
  std::vector<int> moved = bodiesMovingNoMass(sys, ev);
  if (moved.empty())
    for (int b = 1; b <= sys.nb; ++b) {
      bool zero = false;
      for (int r = 0; r < 6; ++r) zero = zero || H.zeroPivot(b - 1, r);
      if (zero) moved.push_back(b);
    }
  std::ostringstream os;
  os << "bodies that can move without moving any mass:";
  for (const int b : moved) os << " '" << sys.bodies[b].name << "'";
  os << " (give them mass and inertia, or joints that fix every direction they can move in)";
  throw ModelError(os.str());
}

Row coordinateRow(const System& sys, const State& s, const Evaluation& ev, const CoordinateTarget& t) {
  Row rows[kMaxJointDofs];
  jointRows(sys, ev, s, t.joint, rows);
  return rows[t.k];
}

// What a coordinate row's rate is judged against beside its target: the row's columns
// times the mechanism's motion scale V (motionScale, max over bodies of
// max(|v|, |w| L); all at rest, the gravity's velocity scale), for linear and V / L for
// angular velocities. A
// target of 0 is met when the rate is 0 to the rounding of the motion: judged against
// |rate| alone a zero target met to round-off would be a residual of 1, and against the
// row's own products J_i u_i or its bodies' own speeds it fails where the bodies barely
// turn about the joint's axis or its body rests on the ground beside a moving one.
double rateScale(const System& sys, const CoordinateTarget& t, const Row& row, double V) {
  const double L = sys.length_scale;
  const int bs[2] = {sys.joints[t.joint]->bodyI(), sys.joints[t.joint]->bodyJ()};
  double scale = 0;
  for (int s = 0; s < 2; ++s)
    if (bs[s] != System::kGround)
      scale += row.J.segment<3>(6 * s).cwiseAbs().sum() * V + row.J.segment<3>(6 * s + 3).cwiseAbs().sum() * V / L;
  return scale;
}

// Whether a joint's dot-product equations hold it at the mirror pose: axes held parallel
// opposed (bz_i . bz_j < 0, in cz), or a twist lock turned by pi (bx_i . bx_j < 0, in cx).
bool mirrored(const Evaluation& ev, const Joint& jt, double* cz, double* cx) {
  const JointGeometry g = jt.geometry(ev.kin[jt.bodyI()], ev.kin[jt.bodyJ()], kBxI | kBzI | kBxJ | kBzJ);
  const bool parallel = jt.holdsAxesParallel(), twist = parallel && jt.locksTwist();
  *cz = g.bz_i.a.dot(g.bz_j.a), *cx = g.bx_i.a.dot(g.bx_j.a);
  return (parallel && *cz < 0) || (twist && *cx < 0);
}

// ---- Assembly on the spanning tree (Simbody's Assembler, Chrono's assembly analysis:
// damped least squares with continuation). The unknowns are the tree's joint coordinates
// q, so the tree's joints hold exactly at every iterate (the bodies stay jointed and only
// the loops' cut joints, couplers, drives and the targets have residuals); the pose is
// written back to the absolute state through the forward kinematics. The residual R(q) is
// each equation over its unit (metres over the length scale for a row with translational
// terms, radians otherwise: scale-free), each target q_k - value likewise, and, per cut
// joint that holds axes parallel (or locks the twist), bz_j - bz_i (bx_j - bx_i): zero
// only at the pose the joint defines, where the dot-product equations also hold at the
// mirror pose; and per limited coordinate its excess over the limits (gap(): bounds
// relaxed at the start and tightened along the path). The gap closes by homotopy,
// R(q) = (1 - s) R(q0) with s from 0 to 1 in steps that double while the path is followed
// and halve when it is not: an Euler predictor along the path's tangent, then
// Levenberg-Marquardt (Marquardt's scaling, steps capped at half a radian or half a length)
// as corrector, on the path when no motion removes more of the residual than the tolerance
// (dependent rows need not shrink in proportion); so the pose moves continuously from the
// file's onto the nearest branch. Then the least-squares minimum at s = 1.

class TreeAssembly {
 public:
  TreeAssembly(const System& sys, State& s, Stepper& st, const std::vector<CoordinateTarget>& targets,
               const TreeModel& model)
      : sys_(sys), s_(s), st_(st), targets_(targets), model_(model), ws_(model) {
    for (int j : model.cut_joints) {
      const Joint& jt = *sys.joints[j];
      if (jt.holdsAxesParallel()) mirror_.push_back({j, false});
      if (jt.holdsAxesParallel() && jt.locksTwist()) mirror_.push_back({j, true});
    }
    r_limit_ = sys.m + static_cast<int>(targets.size()) + 3 * static_cast<int>(mirror_.size());
    nr_ = r_limit_ + static_cast<int>(sys.limits.size());
    const double L = sys.length_scale;
    vunit_.setOnes(model.nv);
    for (const TreeLink& Lk : model.links) {
      if (Lk.kind == TreeJointKind::kPrismatic) vunit_[Lk.iv] = L;
      if (Lk.kind == TreeJointKind::kCylindrical) vunit_[Lk.iv + 1] = L;
      if (Lk.kind == TreeJointKind::kPlanar) vunit_[Lk.iv] = vunit_[Lk.iv + 1] = L;
      if (Lk.kind == TreeJointKind::kFree) vunit_.segment<3>(Lk.iv).setConstant(L);
    }
    q_ = jointState();
    place(q_);
    // The rows' units at the start: L for a row with translational terms, else 1.
    const Evaluation& ev = st.evaluation();
    runit_.setOnes(nr_);
    for (int ci = 0; ci < sys.numConstraints(); ++ci) {
      const ConstraintLayout& Ly = sys.layout[ci];
      forEachBlock(sys, ev, ci, [&](int, int, const auto& Jb) {
        for (int e = 0; e < Ly.size; ++e)
          if (Jb.row(e).template head<3>().cwiseAbs().maxCoeff() > 0) runit_[Ly.row + e] = L;
      });
    }
    // The axes' difference weighs twice: with the dot-product equations' sin^2 of the angle
    // between the axes beside it, 4 |bz_j - bz_i|^2 still falls all the way from pi to 0
    // (at equal weights the sum is flat to fourth order at pi, the mirror pose).
    const int nt = static_cast<int>(targets.size());
    runit_.segment(sys.m + nt, r_limit_ - sys.m - nt).setConstant(0.5);
    auto coordinateUnit = [&](const CoordinateTarget& t) {
      const Row row = coordinateRow(sys, s, ev, t);
      return row.J.segment<3>(0).cwiseAbs().maxCoeff() > 0 || row.J.segment<3>(6).cwiseAbs().maxCoeff() > 0 ? L : 1.0;
    };
    for (int k = 0; k < nt; ++k) runit_[sys.m + k] = coordinateUnit(targets[k]);
    targeted_.assign(sys.limits.size(), 0);
    limit_q_.assign(sys.limits.size(), -1);
    limit_v_.assign(sys.limits.size(), -1);
    for (size_t k = 0; k < sys.limits.size(); ++k) {
      const int link = model.joint_link[sys.limits[k].joint];
      if (link >= 0 && model.links[link].nq == model.links[link].nv && sys.limits[k].k < model.links[link].nq)
        limit_q_[k] = model.links[link].iq + sys.limits[k].k, limit_v_[k] = model.links[link].iv + sys.limits[k].k;
      runit_[r_limit_ + k] = coordinateUnit({sys.limits[k].joint, sys.limits[k].k, 0.0});
      for (const auto& t : targets)
        if (t.joint == sys.limits[k].joint && t.k == sys.limits[k].k) targeted_[k] = 1;
    }
  }

  // Closes the loops from the current pose; s is left at the last pose reached (the tree's
  // joints exact). Returns max |R| there. Where the path from the file's pose ends in a
  // least-squares minimum that does not close (bounds held, a leg folded the other way),
  // it starts again from the closest pose so far with the coordinates that only the
  // unclosed loops move drawn anew (limited ones within their limits, revolute ones a
  // turn around the file's), as one restarts an inverse-kinematics solve from random
  // guesses, loop by loop; a fixed seed, so a file assembles the same way every time.
  double run() {
    const Eigen::VectorXd q_file = q_;
    const std::vector<Tracked> tracked_file = s_.tracked;
    double best = follow();
    if (best <= kDescriptionPrecision) return best;
    // Per q_dot coordinate: its limit (-1: none), whether it is an unlimited revolute angle,
    // its link (for a link whose q and q_dot coordinates are the same: no quaternion).
    std::vector<int> limit_of(model_.nv, -1);
    std::vector<char> turns(model_.nv, 0);
    std::vector<const TreeLink*> link_of(model_.nv, nullptr);
    for (const TreeLink& Lk : model_.links)
      if (Lk.joint >= 0 && Lk.nq == Lk.nv)
        for (int c = 0; c < Lk.nv; ++c) link_of[Lk.iv + c] = &Lk;
    for (int k = 0; k < static_cast<int>(limit_v_.size()); ++k)
      if (limit_v_[k] >= 0 && !targeted_[k]) limit_of[limit_v_[k]] = k;
    for (const TreeLink& Lk : model_.links)
      if (Lk.kind == TreeJointKind::kRevolute && Lk.nq == 1 && limit_of[Lk.iv] < 0) turns[Lk.iv] = 1;
    for (const auto& t : targets_)
      if (model_.joint_link[t.joint] >= 0) turns[model_.links[model_.joint_link[t.joint]].iv] = 0;
    Eigen::VectorXd best_q = q_;
    std::vector<Tracked> best_tracked = s_.tracked;
    std::mt19937_64 draw(kRestartSeed);
    auto uniform = [&]() { return static_cast<double>(draw() >> 11) * 0x1.0p-53; };  // in [0, 1)
    // The coordinates drawn at the best pose: those that move an unclosed equation and no
    // closed one (found again only when a restart improves on the best pose).
    std::vector<int> drawn;
    auto findDrawn = [&]() {
      q_ = best_q;
      s_.tracked = best_tracked;
      const Eigen::VectorXd F = gap(residual(q_), 0.0);
      Eigen::MatrixXd G;
      jacobian(G);
      std::vector<char> row_open(sys_.m, 0);  // (each row of an equation not closed, whole)
      for (int ci = 0; ci < sys_.numConstraints(); ++ci) {
        const ConstraintLayout& Ly = sys_.layout[ci];
        const bool open = Ly.size > 0 && F.segment(Ly.row, Ly.size).cwiseAbs().maxCoeff() > kDescriptionPrecision;
        for (int e = 0; e < Ly.size; ++e) row_open[Ly.row + e] = open;
      }
      drawn.clear();
      for (int c = 0; c < model_.nv; ++c) {
        if ((limit_of[c] < 0 && !turns[c]) || !link_of[c]) continue;
        bool open = false, closed = false;
        for (int r = 0; r < sys_.m; ++r)
          if (G(r, c) != 0) (row_open[r] ? open : closed) = true;
        if (open && !closed) drawn.push_back(c);
      }
    };
    findDrawn();
    for (int restart = 0; restart < kRestarts && best > kDescriptionPrecision && !drawn.empty(); ++restart) {
      q_ = best_q;
      s_.tracked = best_tracked;
      for (const int c : drawn) {
        const TreeLink& Lk = *link_of[c];
        const int i = Lk.iq + (c - Lk.iv);
        double value = q_file[i] + (2 * uniform() - 1) * M_PI;
        if (limit_of[c] >= 0) {
          const LimitSpec& Lm = sys_.limits[limit_of[c]];
          value = Lm.lower + uniform() * (Lm.upper - Lm.lower);
        }
        q_[i] = value;
        const int slot = Lk.ptr->trackedSlot(c - Lk.iv);
        if (slot >= 0) s_.tracked[Lk.ptr->id()][slot] = value;
      }
      const double r = follow();
      if (r < best) {
        best = r, best_q = q_, best_tracked = s_.tracked;
        if (best > kDescriptionPrecision) findDrawn();
      }
    }
    q_ = best_q;
    s_.tracked = best_tracked;
    place(q_);
    return best;
  }

 private:
  // run() from q_ alone: the continuation, then the least-squares minimum.
  double follow() {
    Eigen::VectorXd R0 = residual(q_);
    startAt(R0);
    // A cut joint's axes exactly opposed: |bz_j - bz_i| is at its largest, where it has no
    // slope to descend (nor has the mirror pose its equations hold at). The coordinates that
    // turn them are moved a tenth of a radian first.
    const int r_mirror = sys_.m + static_cast<int>(targets_.size());
    Eigen::VectorXd nudge = Eigen::VectorXd::Zero(model_.nv);
    Eigen::MatrixXd G;
    for (size_t k = 0; k < mirror_.size(); ++k) {
      const int r = r_mirror + 3 * static_cast<int>(k);
      if (R0.segment<3>(r).norm() * runit_[r] < 2 - kOpposed) continue;  // (|bz_j - bz_i|)
      if (G.size() == 0) jacobian(G);
      for (int c = 0; c < model_.nv; ++c)
        if (G.block(r, c, 3, 1).cwiseAbs().maxCoeff() > 0) nudge[c] = kNudge * vunit_[c];
    }
    if (!nudge.isZero()) {
      q_ = moved(q_, nudge);
      R0 = residual(q_);
      startAt(R0);
    }
    double reached = 0, step = 0.25;
    while (reached < 1 && step >= kMinContinuationStep) {
      const double s_try = std::min(1.0, reached + step);
      const Eigen::VectorXd q_saved = q_;
      const std::vector<Tracked> tracked_saved = s_.tracked;
      q_ = projected(moved(q_saved, (s_try - reached) * tangent(1 - reached)), 1 - s_try);  // (the predictor)
      const bool ok = correct(1 - s_try, kCorrectorIterations, kFollowTolerance);
      if (ok) {
        reached = s_try;
        step = std::min(1.0, 2 * step);
      } else {
        q_ = q_saved;
        s_.tracked = tracked_saved;
        step /= 2;
      }
    }
    correct(0.0, kFinalIterations, 0.0);  // (to round-off: until no step lowers |R|)
    place(q_);
    return gap(residual(q_), 0.0).cwiseAbs().maxCoeff();
  }

  // The joint coordinates of the absolute state (as JointStepper::settle reads them).
  Eigen::VectorXd jointState() {
    st_.load(sys_, s_.x.data(), s_.u.data());
    const Evaluation& ev = st_.evaluation();
    Eigen::VectorXd q = model_.neutralPositions(sys_);
    Row rows[kMaxJointDofs];
    for (const TreeLink& L : model_.links) {
      if (L.joint < 0) {
        q.segment<7>(L.iq) = s_.x.segment<7>(BodyCoordinates::x(L.body - 1));
        continue;
      }
      const Joint& J = *L.ptr;
      if (L.kind == TreeJointKind::kSpherical) {
        const Matrix3d Ri = ev.kin[J.bodyI()].A_Oi * J.frameI().Rp, Rj = ev.kin[J.bodyJ()].A_Oi * J.frameJ().Rp;
        const Quaterniond p(Ri.transpose() * Rj);
        q.segment<4>(L.iq) << p.w(), p.x(), p.y(), p.z();
      } else {
        J.coordinates(ev.kin[J.bodyI()], ev.kin[J.bodyJ()], s_.tracked[J.id()], rows);
        for (int k = 0; k < J.dof(); ++k) q[L.iq + k] = rows[k].Phi;
      }
    }
    normalizeQuaternions(model_, q);
    return q;
  }

  // The absolute state of q (velocities kept), loaded and evaluated, the angles tracked.
  void place(const Eigen::VectorXd& q) {
    forwardKinematics(model_, q, Eigen::VectorXd::Zero(model_.nv), ws_);
    absoluteState(model_, ws_, x_, u_);
    s_.x = x_;
    st_.load(sys_, s_.x.data(), s_.u.data());
    st_.trackAngles(sys_, s_);
    st_.evaluate(sys_, s_);
  }

  Eigen::VectorXd residual(const Eigen::VectorXd& q) {
    place(q);
    const Evaluation& ev = st_.evaluation();
    Eigen::VectorXd R(nr_);
    R.head(sys_.m) = ev.Phi;
    for (size_t k = 0; k < targets_.size(); ++k)
      R[sys_.m + k] = coordinateRow(sys_, s_, ev, targets_[k]).Phi - targets_[k].value;
    int r = sys_.m + static_cast<int>(targets_.size());
    for (const auto& mr : mirror_) {
      const JointGeometry g = axes(mr.joint);
      R.segment<3>(r) = mr.twist ? Vector3d(g.bx_j.a - g.bx_i.a) : Vector3d(g.bz_j.a - g.bz_i.a);
      r += 3;
    }
    for (const LimitSpec& Lm : sys_.limits) R[r++] = coordinateRow(sys_, s_, ev, {Lm.joint, Lm.k, 0.0}).Phi;
    return R.cwiseQuotient(runit_);
  }

  JointGeometry axes(int j) const {
    const Joint& jt = *sys_.joints[j];
    const Evaluation& ev = st_.evaluation();
    return jt.geometry(ev.kin[jt.bodyI()], ev.kin[jt.bodyJ()], kBxI | kBzI | kBxJ | kBzJ);
  }

  // dR/dq at the placed pose (columns per q_dot coordinate): the bodies' velocities for
  // each unit joint rate through the equations' Jacobian.
  void jacobian(Eigen::MatrixXd& G) {
    const Evaluation& ev = st_.evaluation();
    G.setZero(nr_, model_.nv);
    std::vector<Row> trows, lrows;
    for (const auto& t : targets_) trows.push_back(coordinateRow(sys_, s_, ev, t));
    for (const LimitSpec& Lm : sys_.limits) lrows.push_back(coordinateRow(sys_, s_, ev, {Lm.joint, Lm.k, 0.0}));
    std::vector<JointGeometry> geo;
    for (const auto& mr : mirror_) geo.push_back(axes(mr.joint));
    Eigen::VectorXd e = Eigen::VectorXd::Zero(model_.nv), out(sys_.m);
    for (int c = 0; c < model_.nv; ++c) {
      e.setZero();
      e[c] = 1;
      forwardKinematics(model_, q_, e, ws_);
      absoluteState(model_, ws_, x_, u_);
      mulJ(sys_, ev, sys_.all_constraints, u_.data(), out.data());
      G.col(c).head(sys_.m) = out;
      for (size_t k = 0; k < targets_.size(); ++k) G(sys_.m + k, c) = rowDot(sys_, targets_[k].joint, trows[k], u_.data());
      int r = sys_.m + static_cast<int>(targets_.size());
      for (size_t k = 0; k < mirror_.size(); ++k, r += 3) {
        const Joint& jt = *sys_.joints[mirror_[k].joint];
        const FixedVector& ai = mirror_[k].twist ? geo[k].bx_i : geo[k].bz_i;
        const FixedVector& aj = mirror_[k].twist ? geo[k].bx_j : geo[k].bz_j;
        Vector3d d = Vector3d::Zero();
        if (jt.bodyJ() != System::kGround) d += aj.a_th * u_.segment<3>(BodyCoordinates::u(jt.bodyJ() - 1) + 3);
        if (jt.bodyI() != System::kGround) d -= ai.a_th * u_.segment<3>(BodyCoordinates::u(jt.bodyI() - 1) + 3);
        G.col(c).segment<3>(r) = d;
      }
      for (size_t k = 0; k < lrows.size(); ++k) G(r_limit_ + k, c) = rowDot(sys_, sys_.limits[k].joint, lrows[k], u_.data());
    }
    for (int r = 0; r < nr_; ++r) G.row(r) /= runit_[r];
  }

  // The path's tangent dq/ds at q_ (Euler predictor): G dq/ds = -R0, least squares. It
  // carries the pose along its branch across a point where another branch crosses it (a
  // parallelogram passing flat: the corrector alone could leave onto the other).
  Eigen::VectorXd tangent(double relax) {
    const Eigen::VectorXd F = gap(residual(q_), relax);
    Eigen::MatrixXd G;
    jacobian(G);
    // A limit on its relaxed bound moves with it (d bound / ds = -e0); the others are free.
    Eigen::VectorXd R0 = R0_;
    for (int k = 0; k < static_cast<int>(sys_.limits.size()); ++k) {
      const int r = r_limit_ + k;
      const bool on = e0_[k] != 0 && std::fabs(F[r]) <= kFollowTolerance;
      const bool beyond = F[r] != 0;  // (past the bound: held there, as the corrector does)
      if (!on && !beyond) G.row(r).setZero();
      R0[r] = on ? e0_[k] / runit_[r] : 0.0;
    }
    Eigen::MatrixXd A = G.transpose() * G;
    const double dmax = std::max(A.diagonal().maxCoeff(), 1e-300);
    for (int c = 0; c < model_.nv; ++c) A(c, c) += 1e-12 * std::max(A(c, c), 1e-3 * dmax) + 1e-300;
    Eigen::VectorXd t = A.ldlt().solve(-G.transpose() * R0);
    if (!t.allFinite()) t.setZero();
    return t;
  }

  // q moved by dv (a q_dot-sized displacement), quaternions renormalized.
  Eigen::VectorXd moved(const Eigen::VectorXd& q, const Eigen::VectorXd& dv) const {
    Eigen::VectorXd rate;
    positionRates(model_, q, dv, rate);
    Eigen::VectorXd out = q + rate;
    normalizeQuaternions(model_, out);
    return out;
  }

  // Levenberg-Marquardt on R(q) = target from q_; returns whether |R - target| <= tol was
  // reached (q_ the best pose found either way; s_.tracked with it).
  bool correct(double relax, int iterations, double tol) {
    Eigen::VectorXd F = gap(residual(q_), relax);
    double cost = F.squaredNorm(), mu = 1e-3;
    Eigen::MatrixXd G, A;
    for (int it = 0; it < iterations; ++it) {
      if (F.cwiseAbs().maxCoeff() <= tol) return true;
      place(q_);
      jacobian(G);
      for (int r = r_limit_; r < nr_; ++r)
        if (F[r] == 0) G.row(r).setZero();  // (a limit not reached: no residual, no slope)
      // A coordinate on its bound that descent would push past it is held there (its
      // column dropped): the active set of the bound-constrained problem.
      Eigen::VectorXd g = -G.transpose() * F;
      for (int k = 0; k < e0_.size(); ++k) {
        const int c = limit_v_[k], i = limit_q_[k];
        if (c < 0 || targeted_[k]) continue;
        const auto [lo, hi] = bounds(k, relax);
        if ((q_[i] <= lo && g[c] < 0) || (q_[i] >= hi && g[c] > 0)) G.col(c).setZero(), g[c] = 0;
      }
      A.noalias() = G.transpose() * G;
      const Eigen::VectorXd d = A.diagonal();
      const double dmax = std::max(d.maxCoeff(), 1e-300);
      // On the path when no motion removes more of F than tol: F less its least-squares
      // part G dv (dv the Gauss-Newton step) is what dependent rows leave. Their residuals
      // cannot all shrink as (1 - s) R0 (a loop's redundant equations, nonzero where the file
      // misplaces it), so the path is the least-squares one.
      Eigen::MatrixXd A0 = A;
      for (int c = 0; c < model_.nv; ++c) A0(c, c) += 1e-12 * std::max(d[c], 1e-3 * dmax) + 1e-300;
      const Eigen::VectorXd removable = G * A0.ldlt().solve(g);
      if (removable.allFinite() && removable.cwiseAbs().maxCoeff() <= tol) {
        place(q_);
        return true;
      }
      const std::vector<Tracked> tracked = s_.tracked;
      bool accepted = false;
      for (int tries = 0; tries < 30 && !accepted; ++tries) {
        Eigen::MatrixXd Am = A;
        for (int c = 0; c < model_.nv; ++c) Am(c, c) += mu * std::max(d[c], 1e-12 * dmax) + 1e-300;
        Eigen::VectorXd dv = Am.ldlt().solve(g);
        const double big = dv.cwiseQuotient(vunit_).cwiseAbs().maxCoeff();
        if (!(big < HUGE_VAL)) { mu *= 10; continue; }
        if (big > kMaxStep) dv *= kMaxStep / big;
        const Eigen::VectorXd q_try = projected(moved(q_, dv), relax);
        const Eigen::VectorXd F_try = gap(residual(q_try), relax);
        const double c_try = F_try.squaredNorm();
        if (c_try < cost) {
          q_ = q_try, F = F_try, cost = c_try;
          mu = std::max(mu / 3, 1e-12);
          accepted = true;
        } else {
          s_.tracked = tracked;
          mu *= 4;
        }
      }
      if (!accepted) break;  // a minimum of |R - target|
    }
    place(q_);
    return F.cwiseAbs().maxCoeff() <= tol;
  }

  // The start's residual R0 and, per limit, how far its coordinate starts past the limit
  // (e0: below the lower bound < 0, above the upper > 0).
  void startAt(const Eigen::VectorXd& R0) {
    R0_ = R0;
    e0_.setZero(static_cast<int>(sys_.limits.size()));
    for (int k = 0; k < e0_.size(); ++k) {
      const LimitSpec& Lm = sys_.limits[k];
      const double q = R0[r_limit_ + k] * runit_[r_limit_ + k];
      e0_[k] = targeted_[k] ? 0.0 : q < Lm.lower ? q - Lm.lower : q > Lm.upper ? q - Lm.upper : 0.0;
    }
  }

  // Limit k's bounds at relax = 1 - s: the limits widened by relax e0 (gap(), below).
  std::pair<double, double> bounds(int k, double relax) const {
    const LimitSpec& Lm = sys_.limits[k];
    return {Lm.lower + std::min(0.0, relax * e0_[k]), Lm.upper + std::max(0.0, relax * e0_[k])};
  }

  // q with each limited coordinate of its own clamped to its bounds: the iterates stay
  // within them (bound-constrained least squares, as Drake's inverse kinematics keeps
  // SNOPT's iterates within the joints' limits), so the loops close on the branch the
  // limits admit rather than on one the least squares reaches by leaving them.
  Eigen::VectorXd projected(Eigen::VectorXd q, double relax) const {
    for (int k = 0; k < e0_.size(); ++k) {
      if (limit_q_[k] < 0 || targeted_[k]) continue;
      const auto [lo, hi] = bounds(k, relax);
      q[limit_q_[k]] = std::min(hi, std::max(lo, q[limit_q_[k]]));
    }
    return q;
  }

  // The corrector's residual F at relax = 1 - s: R - relax R0 for the equations, the targets
  // and the axes, and for each limit its coordinate's excess over the bounds relaxed by
  // relax e0 (0 within them): a coordinate that starts past a limit is brought within it
  // along the path, one within it stays there (an inequality, as Drake's inverse kinematics
  // holds joint limits as bounds).
  Eigen::VectorXd gap(const Eigen::VectorXd& R, double relax) const {
    Eigen::VectorXd F = R - relax * R0_;
    for (int k = 0; k < e0_.size(); ++k) {
      const double u = runit_[r_limit_ + k], q = R[r_limit_ + k] * u;
      if (targeted_[k]) {  // (a target's own coordinate: the target holds it; a target past its limit is refused after)
        F[r_limit_ + k] = 0;
        continue;
      }
      const auto [lo, hi] = bounds(k, relax);
      F[r_limit_ + k] = (q < lo ? q - lo : q > hi ? q - hi : 0.0) / u;
    }
    return F;
  }

  struct MirrorRow {
    int joint;
    bool twist;
  };
  const System& sys_;
  State& s_;
  Stepper& st_;
  const std::vector<CoordinateTarget>& targets_;
  const TreeModel& model_;
  TreeWorkspace ws_;
  std::vector<MirrorRow> mirror_;
  int nr_ = 0, r_limit_ = 0;  // rows: all, the first limit's
  Eigen::VectorXd vunit_, runit_, q_, x_, u_, R0_, e0_;
  std::vector<char> targeted_;  // per limit: its coordinate is a target's
  std::vector<int> limit_q_, limit_v_;  // per limit: its coordinate's index in q, q_dot (-1: none of its own)
};


// Whether the independent equations alone close where all of them leave a gap at the
// file's precision: the dependent rows found (State::dropped, as the stepper finds them),
// the rows kept are solved by minimum-norm Gauss-Newton steps in the absolute coordinates.
// They close when a few steps, none larger than the gap itself allows (a hundredth of the
// length scale), bring them to the position tolerance; the dropped rows then carry the
// whole disagreement, as they do while the mechanism runs. s is left evaluated.
bool closeIndependent(const System& sys, State& s, Stepper& st) {
  constexpr int kSteps = 8;
  st.analyzeDependencies(sys, s);
  Evaluation& ev = st.evaluation();
  for (int it = 0; it <= kSteps; ++it) {
    if (positionResidual(sys, ev) <= sys.options.position_tol) return true;
    if (it == kSteps) break;
    std::vector<int> rows;
    for (int e = 0; e < sys.m; ++e)
      if (!s.dropped[e]) rows.push_back(e);
    Eigen::MatrixXd J = Eigen::MatrixXd::Zero(static_cast<int>(rows.size()), sys.n);
    Eigen::VectorXd r(static_cast<int>(rows.size()));
    std::vector<int> at(sys.m, -1);
    for (size_t i = 0; i < rows.size(); ++i) at[rows[i]] = static_cast<int>(i), r[static_cast<int>(i)] = -ev.Phi[rows[i]];
    for (int ci = 0; ci < sys.numConstraints(); ++ci) {
      const ConstraintLayout& L = sys.layout[ci];
      forEachBlock(sys, ev, ci, [&](int, int b, const auto& Jb) {
        for (int e = 0; e < L.size; ++e)
          if (at[L.row + e] >= 0) J.row(at[L.row + e]).segment<6>(BodyCoordinates::u(b)) += Jb.row(e);
      });
    }
    const Eigen::VectorXd dq = J.completeOrthogonalDecomposition().solve(r);
    if (!dq.allFinite() || dq.cwiseAbs().maxCoeff() > 1e-2 * sys.length_scale) break;  // (not a rounding: a far pose)
    displace(sys, s.x, dq.data());
    st.load(sys, s.x.data(), s.u.data());
    st.trackAngles(sys, s);
    st.evaluate(sys, s);
  }
  return false;
}

// assembleOnce found a coordinate no target named outside its limits: the bound to set it on.
struct OutsideLimit {
  CoordinateTarget bound;
  std::string what;  // the coordinate and its limits
};

AssemblyReport assembleOnce(const System& sys, State& s, Stepper& st,
                            const std::vector<CoordinateTarget>& positions,
                            const std::vector<CoordinateTarget>& velocities, DependencyReport* deps) {
  auto checkTarget = [&](const CoordinateTarget& t, const char* what) {
    if (t.joint < 0 || t.joint >= sys.numJoints() || t.k < 0 || t.k >= sys.joints[t.joint]->dof())
      throw ModelError(std::string("assembly: ") + what + " target names no joint coordinate");
    if (!std::isfinite(t.value))
      throw ModelError("joint '" + sys.joints[t.joint]->name() + "': initial " + what + " not finite");
  };
  Evaluation& ev = st.evaluation();
  PenaltyForm& H = st.solver().penalty();
  st.load(sys, s.x.data(), s.u.data());
  std::fill(s.dropped.begin(), s.dropped.end(), 0);
  for (const auto& t : positions) {
    checkTarget(t, "position");
    if (!sys.joints[t.joint]->holonomicCoordinates())
      throw ModelError("joint '" + sys.joints[t.joint]->name() + "': no position coordinate to set");
  }
  for (const auto& t : velocities) checkTarget(t, "velocity");
  // Tracked angles from the starting pose, then the targets' own (so that a target of
  // 5 rad means 5 rad, not 5 - 2 pi).
  st.trackAngles(sys, s);
  for (const auto& t : positions) {
    const int slot = sys.joints[t.joint]->trackedSlot(t.k);
    if (slot >= 0) s.tracked[sys.joints[t.joint]->id()][slot] = t.value;
  }

  // ---- positions: Levenberg-Marquardt on [Phi; q_k - target], each equation weighted by
  // its row weight and the damping scaled by the bodies' masses (scale-free).
  const int nt = static_cast<int>(positions.size());
  auto residual = [&](double* cost) {
    st.evaluate(sys, s);
    rowWeights(sys, ev, sys.all_constraints);
    const Eigen::VectorXd& W = ev.W;
    double worst = positionResidual(sys, ev), sum = 0;
    for (int e = 0; e < sys.m; ++e) sum += W[e] * ev.Phi[e] * ev.Phi[e];
    for (const auto& t : positions) {
      const Row row = coordinateRow(sys, s, ev, t);
      const double r = row.Phi - t.value;
      Eigen::MatrixXd J = row.J;
      const double scale = rowScale(sys, ev, *sys.joints[t.joint], J, 0) + std::fabs(t.value);
      worst = std::max(worst, scale > 0 ? std::fabs(r) / scale : std::fabs(r));
      const double w = 1.0 / std::max(1e-300, row.J.squaredNorm());
      sum += w * r * r;
    }
    *cost = sum;
    return worst;
  };
  AssemblyReport report;
  double cost = 0, mu = 1e-6;
  double disagreement = 0;  // the dependent rows' residual where they disagree at the file's precision
  double worst = residual(&cost);
  const double tol = sys.options.position_tol;
  // Closes the independent equations alone where the dependent ones disagree at the file's
  // precision (closeIndependent); else the pose stays as it was.
  auto closeIndependentOnes = [&]() {
    State closed = s;
    if (closeIndependent(sys, closed, st)) {
      s = closed;
      worst = 0;
      disagreement = droppedResidual(sys, ev);
    } else {
      st.load(sys, s.x.data(), s.u.data());
      worst = residual(&cost);
    }
  };
  // On the spanning tree first (TreeAssembly): the loops close from however far apart
  // their cut frames start; the absolute iteration below then polishes. A System the tree
  // has no model of is assembled by the absolute iteration alone.
  State on_tree;
  bool tree_ran = false;
  std::vector<char> cut(sys.numConstraints(), 0);  // the constraints of joints that close loops
  bool any_mirrored = false;  // (a mirror pose meets the equations: worst can be 0 there)
  for (int j = 0; j < sys.numJoints() && !any_mirrored; ++j) {
    double cz, cx;
    any_mirrored = mirrored(ev, *sys.joints[j], &cz, &cx);
  }
  // (a coordinate no target names outside its limits: the tree holds it within them)
  bool outside_limits = false;
  for (const LimitSpec& L : sys.limits) {
    bool targeted = false;
    for (const auto& p : positions) targeted = targeted || (p.joint == L.joint && p.k == L.k);
    const double q = coordinateRow(sys, s, ev, CoordinateTarget{L.joint, L.k, 0.0}).Phi;
    const double slack = limitSlack(sys, L);
    outside_limits = outside_limits || (!targeted && (q < L.lower - slack || q > L.upper + slack));
  }
  // A pose that closes to the file's precision already (a spherical mechanism whose axes,
  // written to six digits, miss their common point by a little): its independent equations
  // are closed where it stands, rather than chasing the dependent ones' disagreement along
  // motions that barely change it (the least squares would move every joint by radians).
  const bool may_disagree = positions.empty();  // (closeIndependent holds no target)
  if (worst > tol && may_disagree && !any_mirrored && !outside_limits &&
      positionViolation(ev) <= kDescriptionPrecision * sys.length_scale) {
    closeIndependentOnes();
  }
  if (worst > tol || any_mirrored || outside_limits) {
    std::unique_ptr<TreeModel> model;
    try {
      model = std::make_unique<TreeModel>(sys);
    } catch (const Error&) {
    }
    if (model) {
      for (int j : model->cut_joints) cut[sys.joint_constraint[j]] = 1;
      const std::vector<Tracked> tracked_start = s.tracked;
      TreeAssembly(sys, s, st, positions, *model).run();
      // The angles of the pose reached taken nearest the start's (a turn the path wound up
      // is no motion, and would count against a joint's limits).
      s.tracked = tracked_start;
      st.load(sys, s.x.data(), s.u.data());
      st.trackAngles(sys, s);
      on_tree = s;
      tree_ran = true;
      worst = residual(&cost);
    }
  }
  Eigen::VectorXd dq(sys.n), saved_x;
  std::vector<Tracked> saved_tracked;
  for (int it = 0; it < kMaxPositionIterations && worst > tol; ++it) {
    report.iterations = it + 1;
    rowWeights(sys, ev, sys.all_constraints);
    const Eigen::VectorXd W = ev.W;
    H.assemble(sys, ev, 1.0, 0.0, mu);
    dq.setZero();
    Eigen::VectorXd y(sys.m);
    for (int e = 0; e < sys.m; ++e) y[e] = -W[e] * ev.Phi[e];
    addJt(sys, ev, sys.all_constraints, y.data(), dq.data());
    for (int k = 0; k < nt; ++k) {
      const CoordinateTarget& t = positions[k];
      const Row row = coordinateRow(sys, s, ev, t);
      const double w = 1.0 / std::max(1e-300, row.J.squaredNorm());
      // weight the target row like a constraint row of the joint's bodies
      Eigen::MatrixXd R = row.J;
      H.addRows(sys, sys.joints[t.joint]->id(), R, w * 1.0);
      scatterRow(sys, t.joint, row, -w * (row.Phi - t.value), dq.data());
    }
    if (H.factorize(1e-15, true) != 0) {
      mu *= 10;
      continue;
    }
    H.solve(dq.data());
    saved_x = s.x;
    saved_tracked = s.tracked;
    displace(sys, s.x, dq.data());
    st.load(sys, s.x.data(), s.u.data());
    st.trackAngles(sys, s);
    double trial_cost = 0;
    const double trial_worst = residual(&trial_cost);
    if (trial_cost < cost) {
      cost = trial_cost;
      worst = trial_worst;
      mu = std::max(mu / 3.0, 1e-14);
    } else {
      s.x = saved_x;
      s.tracked = saved_tracked;
      st.load(sys, s.x.data(), s.u.data());
      worst = residual(&cost);
      mu *= 4.0;
      if (mu > 1e12) break;
    }
  }
  // Dependent equations that disagree at the file's precision (a spherical mechanism whose
  // axes, written to six digits, miss their common point by a little): the least-squares
  // pose is kept, its residual reported (AssemblyReport::position_residual past the
  // position tolerance); the stepper holds the independent equations (the dependent ones
  // dropped).
  if (worst > std::max(tol, kAssemblyFailureResidual) && may_disagree &&
      positionViolation(ev) <= kDescriptionPrecision * sys.length_scale) {
    closeIndependentOnes();
  }
  report.position_residual = std::max(worst, disagreement);
  if (worst > std::max(tol, kAssemblyFailureResidual)) {
    // (the tree's closest pose, its joints exact: the residual is the loops' own gap)
    if (tree_ran) {
      s = on_tree;
      st.load(sys, s.x.data(), s.u.data());
      st.evaluate(sys, s);
    }
    std::ostringstream os;
    os << "the mechanism does not close (largest residual " << fmt(positionViolation(ev)) << "):";
    for (int ci = 0; ci < sys.numConstraints(); ++ci) {
      const ConstraintLayout& L = sys.layout[ci];
      const double r = L.size ? ev.Phi.segment(L.row, L.size).cwiseAbs().maxCoeff() : 0.0;
      if (r > 1e-8 * sys.length_scale)
        os << (cut[ci] ? " the loop closed by '" : " '") << sys.constraints[ci]->name() << "' (" << fmt(r) << ")";
    }
    for (const DriveSpec& D : sys.drives) {
      const ConstraintLayout& L = sys.layout[D.constraint];
      const double r = std::fabs(ev.Phi[L.row]);
      if (r > 1e-8 * sys.length_scale)
        os << "; the drive of '" << sys.joints[D.joint]->name() << "' asks for a position the mechanism cannot reach (off by " << fmt(r) << ")";
    }
    for (const auto& t : positions) {
      const double r = coordinateRow(sys, s, ev, t).Phi - t.value;
      if (std::fabs(r) > 1e-8 * (1 + std::fabs(t.value)))
        os << " initial position of '" << sys.joints[t.joint]->name() << "' (off by " << fmt(r) << ")";
    }
    throw ModelError(os.str());
  }

  // Dot-product equations also admit the mirror pose: axes held parallel can close
  // opposed (bz_j = -bz_i), a twist lock can close turned by pi. Only the pose the joint was
  // defined in is accepted.
  for (int j = 0; j < sys.numJoints(); ++j) {
    const Joint& jt = *sys.joints[j];
    double cz = 0, cx = 0;
    const bool parallel = jt.holdsAxesParallel();
    if (mirrored(ev, jt, &cz, &cx)) {
      std::ostringstream os;
      os << "joint '" << jt.name() << "': assembly closed it mirrored (" << (parallel && cz < 0 ? "axes opposed, bz_i . bz_j = " + fmt(cz) : "turned by pi, bx_i . bx_j = " + fmt(cx))
         << "); start its bodies nearer the pose the joint defines";
      throw ModelError(os.str());
    }
  }
  // An initial position outside a joint's limits is an error, never a jump: a target's
  // first. A coordinate no target named, which the closing of the loops took outside its
  // limits, is set on its nearest bound and the assembly done again (assemble, below).
  auto targeted = [&](const LimitSpec& L) {
    for (const auto& p : positions)
      if (p.joint == L.joint && p.k == L.k) return true;
    return false;
  };
  for (const bool targets : {true, false})
    for (const LimitSpec& L : sys.limits) {
      if (targeted(L) != targets) continue;
      const CoordinateTarget t{L.joint, L.k, 0.0};
      const double q = coordinateRow(sys, s, ev, t).Phi;
      const double slack = limitSlack(sys, L);
      if (q >= L.lower - slack && q <= L.upper + slack) continue;
      std::ostringstream os;
      os << "joint '" << sys.joints[L.joint]->name() << "': initial position " << fmt(q)
         << " is outside its limits [" << fmt(L.lower) << ", " << fmt(L.upper) << "]";
      if (!targets) throw OutsideLimit{CoordinateTarget{L.joint, L.k, q < L.lower ? L.lower : L.upper}, os.str()};
      throw ModelError(os.str());
    }
  checkMassRank(sys, ev, H);
  const DependencyReport dependencies = st.analyzeDependencies(sys, s);
  if (deps) *deps = dependencies;

  // ---- velocities: mass-orthogonal projection onto Phi_q v = 0 and q_x,k v = target by the
  // augmented Lagrangian, starting from the bodies' own velocities.
  try {
    st.solver().factorPenalty(sys, ev, "assembly", s.t);
  } catch (const SimulationError&) {  // factor(): singular; at assembly that is the model's fault
    throw ModelError(kSingularAtAssembly);
  }
  rowWeights(sys, ev, sys.all_constraints);
  const Eigen::VectorXd W = ev.W;
  constexpr double kKappa = ConstraintSolver::kKappa;
  std::vector<Row> rows;
  std::vector<double> wt;
  for (const auto& t : velocities) {
    rows.push_back(coordinateRow(sys, s, ev, t));
    wt.push_back(kKappa * rowWeight(sys, sys.joints[t.joint]->id(), Eigen::MatrixXd(rows.back().J)));
  }
  if (!velocities.empty()) {
    H.assemble(sys, ev, kKappa, 1.0, 0.0);
    for (size_t k = 0; k < velocities.size(); ++k) {
      Eigen::MatrixXd R = rows[k].J;
      H.addRows(sys, sys.joints[velocities[k].joint]->id(), R, wt[k]);
    }
    if (H.factorize(0.0, false) != 0) throw ModelError(kSingularAtAssembly);
  }
  Eigen::VectorXd Mu(sys.n), mu_c = Eigen::VectorXd::Zero(sys.m), Ju(sys.m), y(sys.m);
  std::vector<double> mu_t(velocities.size(), 0.0);
  mulM(sys, s.u.data(), Mu.data());
  addRotorMass(sys, ev, s.u.data(), Mu.data());
  std::vector<std::array<double, 2>> scales(sys.nb);
  double vres = 0;
  auto velocityError = [&]() {
    double worst_v = velocityResidual(sys, ev, s.u, scales);
    const double moving = motionScale(sys, s.u), V = moving == 0 ? sys.velocity_scale : moving;
    for (size_t k = 0; k < velocities.size(); ++k) {
      const double r = rowDot(sys, velocities[k].joint, rows[k], s.u.data()) - velocities[k].value;
      const double scale = std::fabs(velocities[k].value) + rateScale(sys, velocities[k], rows[k], V);
      worst_v = std::max(worst_v, scale > 0 ? std::fabs(r) / scale : std::fabs(r));
    }
    return worst_v;
  };
  for (int it = 0; it < kMaxVelocityIterations; ++it) {
    vres = velocityError();
    if (vres <= sys.options.velocity_tol) break;
    s.u = Mu;
    // Phi_q v = nu: the drives' rates (zero for scleronomic equations)
    for (int e = 0; e < sys.m; ++e) y[e] = kKappa * W[e] * ev.nu[e] - mu_c[e];
    addJt(sys, ev, sys.all_constraints, y.data(), s.u.data());
    for (size_t k = 0; k < velocities.size(); ++k)
      scatterRow(sys, velocities[k].joint, rows[k], wt[k] * velocities[k].value - mu_t[k], s.u.data());
    H.solve(s.u.data());
    mulJ(sys, ev, sys.all_constraints, s.u.data(), Ju.data());
    for (int e = 0; e < sys.m; ++e) mu_c[e] += kKappa * W[e] * (Ju[e] - ev.nu[e]);
    for (size_t k = 0; k < velocities.size(); ++k)
      mu_t[k] += wt[k] * (rowDot(sys, velocities[k].joint, rows[k], s.u.data()) - velocities[k].value);
  }
  report.velocity_residual = vres;
  // (rows that a file's rounding leaves nearly but not exactly dependent converge as slowly as
  // they are near: where the positions were accepted at the file's precision, the velocities
  // are held to it, as the steps are)
  if (vres > (report.position_residual > kAssemblyFailureResidual ? kDescriptionPrecision : kAssemblyFailureResidual)) {
    std::ostringstream os;
    os << "initial velocities cannot be met (largest relative residual " << fmt(vres) << ")";
    for (const auto& t : velocities) os << " '" << sys.joints[t.joint]->name() << "'";
    os << ": they contradict the joints, or the model's lengths differ too much for double "
          "precision (a centre of mass far from the joints of its link?)";
    throw ModelError(os.str());
  }
  st.load(sys, s.x.data(), s.u.data());
  return report;
}

}  // namespace

// The assembly within the joints' limits: each coordinate the loops' closing takes outside
// its limits is held on its nearest bound and the whole assembly starts again from the
// given state; at most once per limit, as each round adds one target.
AssemblyReport assemble(const System& sys, State& s, Stepper& st,
                        const std::vector<CoordinateTarget>& positions,
                        const std::vector<CoordinateTarget>& velocities, DependencyReport* deps) {
  const State start = s;
  std::vector<CoordinateTarget> targets = positions;
  for (;;) {
    try {
      return assembleOnce(sys, s, st, targets, velocities, deps);
    } catch (const OutsideLimit& out) {
      s = start;
      targets.push_back(out.bound);
      try {
        return assembleOnce(sys, s, st, targets, velocities, deps);
      } catch (const OutsideLimit&) {  // another coordinate: the next round sets it too
        s = start;
      } catch (const ModelError& e) {
        throw ModelError(out.what + " where the loops close, and held on its bound they do not (" + e.what() + ")");
      }
    }
  }
}

}  // namespace mechanism_sim
