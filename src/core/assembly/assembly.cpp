// Assembly (a function of System, State, a Stepper's evaluation record and solver): bring rough
// positions onto the constraints, check that every free motion moves mass, find the
// dependent equations, and project the velocities.
#include <algorithm>
#include <cmath>
#include <memory>
#include <sstream>
#include <tuple>

#include <Eigen/Cholesky>

#include "core/assembly/assembly.h"
#include "core/assembly/mass_check.h"
#include "core/assembly/tree_assembly.h"
#include "core/joint_space/tree.h"
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

// Whether the independent equations alone close where all of them leave a gap at the
// file's precision: the dependent rows found (State::dropped, as the stepper finds them),
// the rows kept are solved by minimum-norm Gauss-Newton steps in the absolute coordinates.
// They close when a few steps, none larger than the gap itself allows (a hundredth of the
// length scale), bring them to the position tolerance; the dropped rows then carry the
// whole disagreement, as they do while the mechanism runs. s is left evaluated.
bool closeIndependent(const System& sys, State& s, Stepper& st) {
  st.analyzeDependencies(sys, s);
  Evaluation& ev = st.evaluation();
  for (int it = 0; it <= kIndependentSteps; ++it) {
    if (positionResidual(sys, ev) <= sys.options.position_tol) return true;
    if (it == kIndependentSteps) break;
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
    if (!dq.allFinite() || dq.cwiseAbs().maxCoeff() > kIndependentStepSize * sys.length_scale) break;
    displace(sys, s.x, dq.data());
    st.load(sys, s.x.data(), s.u.data());
    st.trackAngles(sys, s);
    st.evaluate(sys, s);
  }
  return false;
}

// A coordinate no target named that the loops' closing took outside its limits: the bound
// to hold it on (assemble).
struct OutsideLimit {
  CoordinateTarget bound;
  std::string what;  // the coordinate and its limits
};

void checkTargets(const System& sys, const std::vector<CoordinateTarget>& positions,
                  const std::vector<CoordinateTarget>& velocities) {
  auto check = [&](const CoordinateTarget& t, const char* what) {
    if (t.joint < 0 || t.joint >= sys.numJoints() || t.k < 0 || t.k >= sys.joints[t.joint]->dof())
      throw ModelError(std::string("assembly: ") + what + " target names no joint coordinate");
    if (!std::isfinite(t.value))
      throw ModelError("joint '" + sys.joints[t.joint]->name() + "': initial " + what + " not finite");
  };
  for (const auto& t : positions) {
    check(t, "position");
    if (!sys.joints[t.joint]->holonomicCoordinates())
      throw ModelError("joint '" + sys.joints[t.joint]->name() + "': no position coordinate to set");
  }
  for (const auto& t : velocities) check(t, "velocity");
}

bool targets(const std::vector<CoordinateTarget>& positions, const LimitSpec& L) {
  if (!L.single()) return true;  // (a sum: no one coordinate to hold on a bound, its start is the targets')
  for (const auto& p : positions)
    if (p.joint == L.joint && p.k == L.k) return true;
  return false;
}

// The positions: Levenberg-Marquardt on [Phi; q_k - target] in absolute coordinates, each
// equation weighted by its row weight and the damping scaled by the bodies' masses
// (scale-free), after the tree's continuation (assembleOnTree) where the pose is far from
// closing. close() leaves s on the constraints or throws ModelError naming what stays open.
class PositionClosing {
 public:
  PositionClosing(const System& sys, State& s, Stepper& st, const std::vector<CoordinateTarget>& positions)
      : sys_(sys), s_(s), st_(st), ev_(st.evaluation()), positions_(positions), cut_(sys.numConstraints(), 0) {}

  // Returns the position residual reported (the dependent rows' disagreement included) and
  // the absolute iterations taken.
  std::pair<double, int> close() {
    const double tol = sys_.options.position_tol;
    worst_ = residual(&cost_);
    // A pose that closes to the file's precision already (a spherical mechanism whose axes,
    // written to six digits, miss their common point by a little): its independent
    // equations are closed where it stands, rather than chasing the dependent ones'
    // disagreement along motions that barely change it (the least squares would move every
    // joint by radians).
    const bool mirror = anyMirrored(), outside = outsideLimits();
    if (worst_ > tol && mayDisagree() && !mirror && !outside) closeIndependentOnes();
    if (worst_ > tol || mirror || outside) onTree();
    const int iterations = absoluteIterations();
    // Dependent equations that disagree at the file's precision: the least-squares pose is
    // kept, its residual reported (AssemblyReport::position_residual past the position
    // tolerance); the stepper holds the independent equations (the dependent ones dropped).
    if (worst_ > std::max(tol, kAssemblyFailureResidual) && mayDisagree()) closeIndependentOnes();
    if (worst_ > std::max(tol, kAssemblyFailureResidual)) refuseUnclosed();
    return {std::max(worst_, disagreement_), iterations};
  }

 private:
  // The largest residual (the equations' relative one, each target over its row's scale);
  // *cost: the weighted sum of squares the iteration lowers.
  double residual(double* cost) {
    st_.evaluate(sys_, s_);
    rowWeights(sys_, ev_, sys_.all_constraints);
    const Eigen::VectorXd& W = ev_.W;
    double worst = positionResidual(sys_, ev_), sum = 0;
    for (int e = 0; e < sys_.m; ++e) sum += W[e] * ev_.Phi[e] * ev_.Phi[e];
    for (const auto& t : positions_) {
      const Row row = jointRow(sys_, ev_, s_, t.joint, t.k);
      const double r = row.Phi - t.value;
      Eigen::MatrixXd J = row.J;
      const double scale = rowScale(sys_, ev_, *sys_.joints[t.joint], J, 0) + std::fabs(t.value);
      worst = std::max(worst, scale > 0 ? std::fabs(r) / scale : std::fabs(r));
      const double w = 1.0 / std::max(1e-300, row.J.squaredNorm());
      sum += w * r * r;
    }
    *cost = sum;
    return worst;
  }

  // Whether the pose is within the file's precision of closing, with no target held
  // (closeIndependent holds none): then dependent rows may disagree by the file's rounding.
  bool mayDisagree() const {
    return positions_.empty() && positionViolation(ev_) <= kDescriptionPrecision * sys_.length_scale;
  }

  // (a mirror pose meets the equations: worst_ can be 0 there)
  bool anyMirrored() const {
    double cz, cx;
    for (int j = 0; j < sys_.numJoints(); ++j)
      if (mirrored(ev_, *sys_.joints[j], &cz, &cx)) return true;
    return false;
  }

  // (a coordinate no target names outside its limits: the tree holds it within them)
  bool outsideLimits() const {
    for (const LimitSpec& L : sys_.limits) {
      const double q = limitValue(sys_, ev_, s_, L), slack = limitSlack(sys_, L);
      if (!targets(positions_, L) && (q < L.lower - slack || q > L.upper + slack)) return true;
    }
    return false;
  }

  // Closes the independent equations alone where the dependent ones disagree at the file's
  // precision (closeIndependent); else the pose stays as it was.
  void closeIndependentOnes() {
    State closed = s_;
    if (closeIndependent(sys_, closed, st_)) {
      s_ = closed;
      worst_ = 0;
      disagreement_ = droppedResidual(sys_, ev_);
    } else {
      st_.load(sys_, s_.x.data(), s_.u.data());
      worst_ = residual(&cost_);
    }
  }

  // On the spanning tree: the loops close from however far apart their cut frames start;
  // the absolute iteration then polishes. A System the tree has no model of is assembled
  // by the absolute iteration alone.
  void onTree() {
    std::unique_ptr<TreeModel> model;
    try {
      model = std::make_unique<TreeModel>(sys_);
    } catch (const Error&) {
      return;
    }
    for (int j : model->cut_joints) cut_[sys_.joint_constraint[j]] = 1;
    const std::vector<Tracked> tracked_start = s_.tracked;
    assembleOnTree(sys_, s_, st_, positions_, *model);
    // The angles of the pose reached taken nearest the start's (a turn the path wound up
    // is no motion, and would count against a joint's limits).
    s_.tracked = tracked_start;
    st_.load(sys_, s_.x.data(), s_.u.data());
    st_.trackAngles(sys_, s_);
    on_tree_ = s_;
    tree_ran_ = true;
    worst_ = residual(&cost_);
  }

  // Levenberg-Marquardt in absolute coordinates from s_; returns the iterations taken.
  int absoluteIterations() {
    PenaltyForm& H = st_.solver().penalty();
    const double tol = sys_.options.position_tol;
    double mu = 1e-6;
    Eigen::VectorXd dq(sys_.n), saved_x, y(sys_.m);
    std::vector<Tracked> saved_tracked;
    int iterations = 0;
    for (int it = 0; it < kMaxPositionIterations && worst_ > tol; ++it) {
      iterations = it + 1;
      rowWeights(sys_, ev_, sys_.all_constraints);
      H.assemble(sys_, ev_, 1.0, 0.0, mu);
      dq.setZero();
      for (int e = 0; e < sys_.m; ++e) y[e] = -ev_.W[e] * ev_.Phi[e];
      addJt(sys_, ev_, sys_.all_constraints, y.data(), dq.data());
      for (const CoordinateTarget& t : positions_) {
        const Row row = jointRow(sys_, ev_, s_, t.joint, t.k);
        // (the target row weighted like a constraint row of the joint's bodies)
        const double w = 1.0 / std::max(1e-300, row.J.squaredNorm());
        Eigen::MatrixXd R = row.J;
        H.addRows(sys_, sys_.joints[t.joint]->id(), R, w);
        scatterRow(sys_, t.joint, row, -w * (row.Phi - t.value), dq.data());
      }
      if (H.factorize(1e-15, true) != 0) {
        mu *= 10;
        continue;
      }
      H.solve(dq.data());
      saved_x = s_.x;
      saved_tracked = s_.tracked;
      displace(sys_, s_.x, dq.data());
      st_.load(sys_, s_.x.data(), s_.u.data());
      st_.trackAngles(sys_, s_);
      double trial_cost = 0;
      const double trial_worst = residual(&trial_cost);
      if (trial_cost < cost_) {
        cost_ = trial_cost;
        worst_ = trial_worst;
        mu = std::max(mu / 3.0, 1e-14);
      } else {
        s_.x = saved_x;
        s_.tracked = saved_tracked;
        st_.load(sys_, s_.x.data(), s_.u.data());
        worst_ = residual(&cost_);
        mu *= 4.0;
        if (mu > 1e12) break;
      }
    }
    return iterations;
  }

  // Throws the ModelError that names each equation, drive and target left open, at the
  // tree's closest pose where the tree ran (its joints exact: the residual is the loops'
  // own gap).
  [[noreturn]] void refuseUnclosed() {
    if (tree_ran_) {
      s_ = on_tree_;
      st_.load(sys_, s_.x.data(), s_.u.data());
      st_.evaluate(sys_, s_);
    }
    std::ostringstream os;
    os << "the mechanism does not close (largest residual " << fmt(positionViolation(ev_)) << "):";
    for (int ci = 0; ci < sys_.numConstraints(); ++ci) {
      const ConstraintLayout& L = sys_.layout[ci];
      const double r = L.size ? ev_.Phi.segment(L.row, L.size).cwiseAbs().maxCoeff() : 0.0;
      if (r > 1e-8 * sys_.length_scale)
        os << (cut_[ci] ? " the loop closed by '" : " '") << sys_.constraints[ci]->name() << "' (" << fmt(r) << ")";
    }
    for (const DriveSpec& D : sys_.drives) {
      const double r = std::fabs(ev_.Phi[sys_.layout[D.constraint].row]);
      if (r > 1e-8 * sys_.length_scale)
        os << "; the drive of '" << sys_.joints[D.joint]->name() << "' asks for a position the mechanism cannot reach (off by " << fmt(r) << ")";
    }
    for (const auto& t : positions_) {
      const double r = jointRow(sys_, ev_, s_, t.joint, t.k).Phi - t.value;
      if (std::fabs(r) > 1e-8 * (1 + std::fabs(t.value)))
        os << " initial position of '" << sys_.joints[t.joint]->name() << "' (off by " << fmt(r) << ")";
    }
    throw ModelError(os.str());
  }

  const System& sys_;
  State& s_;
  Stepper& st_;
  Evaluation& ev_;
  const std::vector<CoordinateTarget>& positions_;
  double cost_ = 0, worst_ = 0;
  double disagreement_ = 0;  // the dependent rows' residual where they disagree at the file's precision
  std::vector<char> cut_;  // per constraint: a joint that closes a loop
  State on_tree_;
  bool tree_ran_ = false;
};

// Dot-product equations also admit the mirror pose: axes held parallel can close opposed
// (bz_j = -bz_i), a twist lock can close turned by pi. Only the pose the joint was defined
// in is accepted.
void refuseMirrored(const System& sys, const Evaluation& ev) {
  for (int j = 0; j < sys.numJoints(); ++j) {
    const Joint& jt = *sys.joints[j];
    double cz = 0, cx = 0;
    if (!mirrored(ev, jt, &cz, &cx)) continue;
    std::ostringstream os;
    os << "joint '" << jt.name() << "': assembly closed it mirrored ("
       << (jt.holdsAxesParallel() && cz < 0 ? "axes opposed, bz_i . bz_j = " + fmt(cz) : "turned by pi, bx_i . bx_j = " + fmt(cx))
       << "); start its bodies nearer the pose the joint defines";
    throw ModelError(os.str());
  }
}

// An initial position outside a joint's limits is an error, never a jump: a target's
// first. A coordinate no target named, which the closing of the loops took outside its
// limits, is thrown as OutsideLimit: assemble holds it on its nearest bound and assembles
// again.
void checkLimits(const System& sys, const State& s, const Evaluation& ev, const std::vector<CoordinateTarget>& positions) {
  for (const bool targeted : {true, false})
    for (const LimitSpec& L : sys.limits) {
      if (targets(positions, L) != targeted) continue;
      const double q = limitValue(sys, ev, s, L);
      const double slack = limitSlack(sys, L);
      if (q >= L.lower - slack && q <= L.upper + slack) continue;
      std::ostringstream os;
      if (L.single())
        os << "joint '" << sys.joints[L.joint]->name() << "': initial position " << fmt(q)
           << " is outside its limits [" << fmt(L.lower) << ", " << fmt(L.upper) << "]";
      else
        os << limitSubject(sys, L) << ": the initial positions give sum_i c_i q_i = " << fmt(q)
           << ", outside its backlash [" << fmt(L.lower) << ", " << fmt(L.upper) << "]";
      if (!targeted) throw OutsideLimit{CoordinateTarget{L.joint, L.k, q < L.lower ? L.lower : L.upper}, os.str()};
      throw ModelError(os.str());
    }
}

// The velocities: mass-orthogonal projection onto Phi_q v = nu and q_x,k v = target by the
// augmented Lagrangian, starting from the bodies' own velocities. Returns the largest
// relative residual; throws ModelError where it stays above `failure` (the targets cannot
// be met).
double projectVelocities(const System& sys, State& s, Stepper& st, const std::vector<CoordinateTarget>& velocities,
                         double failure) {
  Evaluation& ev = st.evaluation();
  PenaltyForm& H = st.solver().penalty();
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
    rows.push_back(jointRow(sys, ev, s, t.joint, t.k));
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
  if (vres > failure) {
    std::ostringstream os;
    os << "initial velocities cannot be met (largest relative residual " << fmt(vres) << ")";
    for (const auto& t : velocities) os << " '" << sys.joints[t.joint]->name() << "'";
    os << ": they contradict the joints, or the model's lengths differ too much for double "
          "precision (a centre of mass far from the joints of its link?)";
    throw ModelError(os.str());
  }
  return vres;
}

AssemblyReport assembleOnce(const System& sys, State& s, Stepper& st,
                            const std::vector<CoordinateTarget>& positions,
                            const std::vector<CoordinateTarget>& velocities, DependencyReport* deps) {
  checkTargets(sys, positions, velocities);
  st.load(sys, s.x.data(), s.u.data());
  std::fill(s.dropped.begin(), s.dropped.end(), 0);
  // Tracked angles from the starting pose, then the targets' own (so that a target of
  // 5 rad means 5 rad, not 5 - 2 pi).
  st.trackAngles(sys, s);
  for (const auto& t : positions) {
    const int slot = sys.joints[t.joint]->trackedSlot(t.k);
    if (slot >= 0) s.tracked[sys.joints[t.joint]->id()][slot] = t.value;
  }
  AssemblyReport report;
  std::tie(report.position_residual, report.iterations) = PositionClosing(sys, s, st, positions).close();
  Evaluation& ev = st.evaluation();
  refuseMirrored(sys, ev);
  checkLimits(sys, s, ev, positions);
  checkMassRank(sys, ev, st.solver().penalty());
  const DependencyReport dependencies = st.analyzeDependencies(sys, s);
  if (deps) *deps = dependencies;
  // (rows that a file's rounding leaves nearly but not exactly dependent converge as slowly
  // as they are near: where the positions were accepted at the file's precision, the
  // velocities are held to it, as the steps are)
  const double failure =
      report.position_residual > kAssemblyFailureResidual ? kDescriptionPrecision : kAssemblyFailureResidual;
  report.velocity_residual = projectVelocities(sys, s, st, velocities, failure);
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
