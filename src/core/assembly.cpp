// Assembly (a function of System, State, a Stepper's evaluation record and solver): bring rough
// positions onto the constraints, check that every free motion moves mass, find the
// dependent equations, and project the velocities.
#include <algorithm>
#include <cmath>
#include <map>
#include <sstream>

#include "mechanism_sim/core/mechanism.h"
#include "mechanism_sim/core/sparse_ldlt.h"

namespace mechanism_sim {
namespace {


// Assembly's limits: Levenberg-Marquardt iterations on the positions, augmented Lagrangian
// passes on the velocities, and the relative residual above which either fails (ModelError:
// the targets or the closures cannot be met) whatever the tolerances ask.
constexpr int kMaxPositionIterations = 300;
constexpr int kMaxVelocityIterations = 60;
constexpr double kAssemblyFailureResidual = 1e-9;

// The constrained mass matrix H cannot be factored at the assembled pose although every
// motion moves mass (checkMassRank passed): its condition is past double precision.
constexpr const char* kSingularAtAssembly =
    "assembly: the constrained mass matrix is numerically singular at the initial pose; the "
    "model's lengths differ too much for double precision (a centre of mass far from the "
    "joints of its link?)";

// M + Phi_q^T W Phi_q (W: row weights, so the matrix is well conditioned) must be positive
// definite: every motion the joints allow moves some mass. A zero pivot names a body that
// can move without moving mass.
void checkMassRank(const System& sys, Evaluation& ev, PenaltyForm& H) {
  rowWeights(sys, ev, sys.all_constraints);
  H.assemble(sys, ev, 1.0, 1.0, 0.0);
  if (H.factorize(1e-10, true) == 0) return;
  std::ostringstream os;
  os << "bodies that can move without moving any mass:";
  for (int b = 1; b <= sys.nb; ++b) {
    bool zero = false;
    for (int r = 0; r < 6; ++r) zero = zero || H.zeroPivot(b - 1, r);
    if (zero) os << " '" << sys.bodies[b].name << "'";
  }
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
// target of 0 is met when the rate is 0 to the rounding of the motion. (Judged against
// |rate| alone, a zero target met to 1e-17 was a residual of 1; against the row's own
// products J_i u_i or its bodies' own speeds, it still failed where the bodies barely turn
// about the joint's axis or its body rests on the ground beside a moving one.)
double rateScale(const System& sys, const CoordinateTarget& t, const Row& row, double V) {
  const double L = sys.length_scale;
  const int bs[2] = {sys.joints[t.joint]->bodyI(), sys.joints[t.joint]->bodyJ()};
  double scale = 0;
  for (int s = 0; s < 2; ++s)
    if (bs[s] != System::kGround)
      scale += row.J.segment<3>(6 * s).cwiseAbs().sum() * V + row.J.segment<3>(6 * s + 3).cwiseAbs().sum() * V / L;
  return scale;
}

}  // namespace

AssemblyReport assemble(const System& sys, State& s, Stepper& st,
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
  double worst = residual(&cost);
  const double tol = sys.options.position_tol;
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
  report.position_residual = worst;
  if (worst > std::max(tol, kAssemblyFailureResidual)) {
    std::ostringstream os;
    os << "the mechanism does not close (largest residual " << fmt(positionViolation(ev)) << "):";
    for (int ci = 0; ci < sys.numConstraints(); ++ci) {
      const ConstraintLayout& L = sys.layout[ci];
      const double r = L.size ? ev.Phi.segment(L.row, L.size).cwiseAbs().maxCoeff() : 0.0;
      if (r > 1e-8 * sys.length_scale) os << " '" << sys.constraints[ci]->name() << "' (" << fmt(r) << ")";
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
    const JointGeometry g = jt.geometry(ev.kin[jt.bodyI()], ev.kin[jt.bodyJ()], kBxI | kBzI | kBxJ | kBzJ);
    const bool parallel = jt.holdsAxesParallel();
    const bool twist = parallel && jt.locksTwist();
    const double cz = g.bz_i.a.dot(g.bz_j.a), cx = g.bx_i.a.dot(g.bx_j.a);
    if ((parallel && cz < 0) || (twist && cx < 0)) {
      std::ostringstream os;
      os << "joint '" << jt.name() << "': assembly closed it mirrored (" << (parallel && cz < 0 ? "axes opposed, bz_i . bz_j = " + fmt(cz) : "turned by pi, bx_i . bx_j = " + fmt(cx))
         << "); start its bodies nearer the pose the joint defines";
      throw ModelError(os.str());
    }
  }
  // An initial position outside a joint's limits is an error, never a jump.
  for (const LimitSpec& L : sys.limits) {
    const CoordinateTarget t{L.joint, L.k, 0.0};
    const double q = coordinateRow(sys, s, ev, t).Phi;
    const double slack = 1e-9 * (std::fabs(L.lower) + std::fabs(L.upper) + sys.length_scale);
    if (q < L.lower - slack || q > L.upper + slack) {
      std::ostringstream os;
      os << "joint '" << sys.joints[L.joint]->name() << "': initial position " << fmt(q)
         << " is outside its limits [" << fmt(L.lower) << ", " << fmt(L.upper) << "]";
      throw ModelError(os.str());
    }
  }
  checkMassRank(sys, ev, H);
  const DependencyReport dependencies = st.analyzeDependencies(sys, s);
  if (deps) *deps = dependencies;

  // ---- velocities: mass-orthogonal projection onto Phi_q v = 0 and G_k v = target by the
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
  if (vres > kAssemblyFailureResidual) {
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

}  // namespace mechanism_sim
