#include "core/assembly/tree_assembly.h"

#include <algorithm>
#include <cmath>
#include <random>

#include <Eigen/Cholesky>

#include "core/absolute/projection.h"
#include "core/absolute/stepper.h"
#include "core/numerics.h"

namespace mechanism_sim {
namespace {

// Assembly's iteration caps and thresholds (numerics.h says why each has its value).
using namespace numerics::assembly;

// Assembly on the spanning tree (Simbody's Assembler, Chrono's assembly analysis:
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
    for (const TreeLink& Lk : model.links)
      for (int k = 0; k < Lk.nv; ++k)
        if (Lk.jmodel->lengths >> k & 1u) vunit_[Lk.iv + k] = L;  // (a translation)
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
      const Row row = jointRow(sys_, ev, s_, t.joint, t.k);
      return row.J.segment<3>(0).cwiseAbs().maxCoeff() > 0 || row.J.segment<3>(6).cwiseAbs().maxCoeff() > 0 ? L : 1.0;
    };
    for (int k = 0; k < nt; ++k) runit_[sys.m + k] = coordinateUnit(targets[k]);
    targeted_.assign(sys.limits.size(), 0);
    limit_q_.assign(sys.limits.size(), -1);
    limit_v_.assign(sys.limits.size(), -1);
    for (size_t k = 0; k < sys.limits.size(); ++k) {
      const int link = model.joint_link[sys.limits[k].joint];
      if (sys.limits[k].single() && link >= 0 && model.links[link].nq == model.links[link].nv &&
          sys.limits[k].k < model.links[link].nq)
        limit_q_[k] = model.links[link].iq + sys.limits[k].k, limit_v_[k] = model.links[link].iv + sys.limits[k].k;
      runit_[r_limit_ + k] = coordinateUnit({sys.limits[k].joint, sys.limits[k].k, 0.0});
      for (const auto& t : targets)
        if (sys.limits[k].single() && t.joint == sys.limits[k].joint && t.k == sys.limits[k].k) targeted_[k] = 1;
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
      for (int k = 0; k < Lk.nv; ++k)
        if ((Lk.jmodel->free_turns >> k & 1u) && limit_of[Lk.iv + k] < 0) turns[Lk.iv + k] = 1;
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
    for (const TreeLink& L : model_.links) {
      if (L.joint < 0) {
        q.segment<7>(L.iq) = s_.x.segment<7>(BodyCoordinates::x(L.body - 1));
        continue;
      }
      const Joint& J = *L.ptr;
      J.treePositions(ev.kin[J.bodyI()], ev.kin[J.bodyJ()], s_.tracked[J.id()], q.data() + L.iq);
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
      R[sys_.m + k] = jointRow(sys_, ev, s_, targets_[k].joint, targets_[k].k).Phi - targets_[k].value;
    int r = sys_.m + static_cast<int>(targets_.size());
    for (const auto& mr : mirror_) {
      const JointGeometry g = axes(mr.joint);
      R.segment<3>(r) = mr.twist ? Vector3d(g.bx_j.a - g.bx_i.a) : Vector3d(g.bz_j.a - g.bz_i.a);
      r += 3;
    }
    for (const LimitSpec& Lm : sys_.limits) R[r++] = limitValue(sys_, ev, s_, Lm);
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
    std::vector<Row> trows, lrows;  // (lrows: each limit's terms' rows in turn)
    for (const auto& t : targets_) trows.push_back(jointRow(sys_, ev, s_, t.joint, t.k));
    for (const LimitSpec& Lm : sys_.limits)
      for (const LimitTerm& t : Lm.terms) lrows.push_back(jointRow(sys_, ev, s_, t.joint, t.k));
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
      size_t i = 0;
      for (size_t k = 0; k < sys_.limits.size(); ++k) {
        G(r_limit_ + k, c) = 0.0;
        for (const LimitTerm& t : sys_.limits[k].terms) G(r_limit_ + k, c) += t.c * rowDot(sys_, t.joint, lrows[i++], u_.data());
      }
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

}  // namespace

double assembleOnTree(const System& sys, State& s, Stepper& st, const std::vector<CoordinateTarget>& targets,
                      const TreeModel& model) {
  return TreeAssembly(sys, s, st, targets, model).run();
}

}  // namespace mechanism_sim
