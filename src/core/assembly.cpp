// Assembly (a function of System, State and a Stepper's building blocks): bring rough
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

std::string fmt(double x) {
  std::ostringstream os;
  os.precision(3);
  os << x;
  return os.str();
}

// The constrained mass matrix H cannot be factored at the assembled pose although every
// motion moves mass (checkMassRank passed): its condition is past double precision.
constexpr const char* kSingularAtAssembly =
    "assembly: the constrained mass matrix is numerically singular at the initial pose; the "
    "model's lengths differ too much for double precision (a centre of mass far from the "
    "joints of its link?)";

// Rank of Phi_q by LDL^T of the Gram matrix of its normalized rows, in constraint order,
// skipping zero pivots: row e is dependent when less than 1e-9 of its squared norm lies
// outside the span of the rows before it.
//
// The test is made on Phi_q in coordinates of the joints' own geometry, which leaves its
// rank as it is: a body's position is taken at the centroid c of its joints' points (body
// frame) rather than at its centre of mass, delta r = delta r_c + A tilde(c) delta theta'
// (so J_theta gains J_r A tilde(c)), and rotations are measured by the displacement they
// make at l, the largest distance of a joint point from its body's centroid
// (delta theta' = delta phi / l, one l for all bodies, so that rows between two bodies'
// rotations keep their balance). Rows taken at the centre of mass carry the lever arm from
// it: a rod whose centre of mass lay 425 km from its joints 0.35 m apart made a
// slider-crank's loop look dependent at 1e-9 and lose all five equations of its wrist pin
// (the fuzzer's find), and a double pendulum whose second link's centre of mass lay 100 km
// off lost two of its joint's five. In the joints' geometry the loop keeps the three
// dependent equations of a planar loop and the pendulum none, in metres or in millimetres
// alike.
DependencyReport analyzeDependencies(const System& sys, const Stepper& st, std::vector<char>* dropped) {
  const int m = sys.m_eq;
  std::vector<std::vector<std::pair<int, int>>> at_body(sys.bodies.size());  // (constraint, slot)
  int nc = 0;
  for (int ci = 0; ci < sys.numConstraints(); ++ci) {
    if (sys.layout[ci].row >= m) break;
    nc = ci + 1;
    const auto& bs = sys.constraints[ci]->bodies();
    for (size_t k = 0; k < bs.size(); ++k)
      if (bs[k] != System::kGround) at_body[bs[k]].push_back({ci, static_cast<int>(k)});
  }
  // each body's joint points: their centroid c; l: the largest distance of a joint point
  // from the centroid of its body's (the mechanism's size without its centres of mass)
  std::vector<Vector3d> centroid(sys.bodies.size(), Vector3d::Zero());
  double size = 0;
  {
    std::vector<std::vector<Vector3d>> points(sys.bodies.size());
    for (const Joint* j : sys.joints) {
      if (j->bodyI() != System::kGround) points[j->bodyI()].push_back(j->frameI().sp_B);
      if (j->bodyJ() != System::kGround) points[j->bodyJ()].push_back(j->frameJ().sp_B);
    }
    for (size_t b = 1; b < points.size(); ++b) {
      for (const Vector3d& p : points[b]) centroid[b] += p / static_cast<double>(points[b].size());
      for (const Vector3d& p : points[b]) size = std::max(size, (p - centroid[b]).norm());
    }
    if (!(size > 0)) size = sys.length_scale;  // every body has one joint
  }
  std::vector<Eigen::MatrixXd> Jn(nc);
  for (int ci = 0; ci < nc; ++ci) {
    Jn[ci] = st.jacobian(ci);
    const auto& bs = sys.constraints[ci]->bodies();
    for (size_t k = 0; k < bs.size(); ++k) {
      if (bs[k] == System::kGround) continue;
      auto Jb = Jn[ci].middleCols<6>(6 * k);
      const Matrix3d shift = st.kin()[bs[k]].A_Oi * tilde(centroid[bs[k]]);
      Jb.rightCols<3>() = (Jb.rightCols<3>() + Jb.leftCols<3>() * shift) / size;
    }
    for (int e = 0; e < Jn[ci].rows(); ++e) {
      const double norm = Jn[ci].row(e).norm();
      if (norm > 0) Jn[ci].row(e) /= norm;
    }
  }
  std::map<std::pair<int, int>, Eigen::MatrixXd> blocks;  // (c1, c2) -> Jn1 Jn2^T
  for (size_t b = 1; b < at_body.size(); ++b)
    for (const auto& a : at_body[b])
      for (const auto& c : at_body[b]) {
        const Eigen::MatrixXd prod = Jn[a.first].middleCols<6>(6 * a.second) *
                                     Jn[c.first].middleCols<6>(6 * c.second).transpose();
        auto it = blocks.find({a.first, c.first});
        if (it == blocks.end()) blocks.emplace(std::make_pair(a.first, c.first), prod);
        else it->second += prod;
      }
  std::vector<std::vector<std::pair<int, double>>> cols(m);
  for (const auto& entry : blocks) {
    const int r0 = sys.layout[entry.first.first].row, c0 = sys.layout[entry.first.second].row;
    for (int i = 0; i < entry.second.rows(); ++i)
      for (int j = 0; j < entry.second.cols(); ++j) cols[c0 + j].push_back({r0 + i, entry.second(i, j)});
  }
  std::vector<int> Gp(m + 1, 0), Gi;
  std::vector<double> Gx;
  for (int j = 0; j < m; ++j) {
    std::sort(cols[j].begin(), cols[j].end());
    for (const auto& e : cols[j]) Gi.push_back(e.first), Gx.push_back(e.second);
    Gp[j + 1] = static_cast<int>(Gi.size());
  }
  SparseLDLT gram;
  gram.analyze(m, Gp, Gi, {});
  gram.factorize(Gx.data(), 1e-9, true);
  DependencyReport report;
  report.equations = m;
  for (int ci = 0; ci < nc; ++ci) {
    int count = 0;
    for (int e = 0; e < sys.layout[ci].size; ++e) {
      const int row = sys.layout[ci].row + e;
      count += gram.zeroPivot(row);
      (*dropped)[row] = gram.zeroPivot(row) ? 1 : 0;
    }
    if (count) report.by_constraint.push_back({sys.constraints[ci]->name(), count});
    report.dependent += count;
  }
  return report;
}

// M + Phi_q^T W Phi_q (W: row weights, so the matrix is well conditioned) must be positive
// definite: every motion the joints allow moves some mass. A zero pivot names a body that
// can move without moving mass.
void checkMassRank(const System& sys, Stepper& st) {
  st.rowWeights(sys);
  st.assembleH(sys, 1.0, 1.0, 0.0);
  if (st.cholesky().factorize(1e-10, true) == 0) return;
  std::ostringstream os;
  os << "bodies that can move without moving any mass:";
  for (int b = 1; b <= sys.nb; ++b) {
    bool zero = false;
    for (int r = 0; r < 6; ++r) zero = zero || st.cholesky().zeroPivot(b - 1, r);
    if (zero) os << " '" << sys.bodies[b].name << "'";
  }
  os << " (give them mass and inertia, or joints that fix every direction they can move in)";
  throw ModelError(os.str());
}

Row coordinateRow(const System& sys, const State& s, const Stepper& st, const CoordinateTarget& t) {
  const Joint& j = *sys.joints[t.joint];
  Row rows[3];
  j.coordinates(st.kin()[j.bodyI()], st.kin()[j.bodyJ()], s.tracked[j.id()], rows);
  return rows[t.k];
}

// Adds x * row^T into out over the joint's two bodies.
void addRowT(const System& sys, const CoordinateTarget& t, const Row& row, double x, double* out) {
  const int bs[2] = {sys.joints[t.joint]->bodyI(), sys.joints[t.joint]->bodyJ()};
  for (int s = 0; s < 2; ++s)
    if (bs[s] != System::kGround)
      for (int c = 0; c < 6; ++c) out[6 * (bs[s] - 1) + c] += row.J(6 * s + c) * x;
}

double rowDot(const System& sys, const CoordinateTarget& t, const Row& row, const Eigen::VectorXd& u) {
  const int bs[2] = {sys.joints[t.joint]->bodyI(), sys.joints[t.joint]->bodyJ()};
  double v = 0;
  for (int s = 0; s < 2; ++s)
    if (bs[s] != System::kGround) v += row.J.segment<6>(6 * s).dot(u.segment<6>(6 * (bs[s] - 1)));
  return v;
}

// What a coordinate row's rate is judged against beside its target: the row's columns
// times the mechanism's motion scale V (Stepper::motionScale, max over bodies of
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
    const Eigen::VectorXd& W = st.rowWeights(sys);
    double worst = st.positionResidual(sys), sum = 0;
    for (int e = 0; e < sys.m; ++e) sum += W[e] * st.Phi()[e] * st.Phi()[e];
    for (const auto& t : positions) {
      const Row row = coordinateRow(sys, s, st, t);
      const double r = row.Phi - t.value;
      Eigen::MatrixXd J = row.J;
      const double scale = st.rowScale(*sys.joints[t.joint], J, 0) + std::fabs(t.value);
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
  for (int it = 0; it < 300 && worst > tol; ++it) {
    report.iterations = it + 1;
    const Eigen::VectorXd W = st.rowWeights(sys);
    st.assembleH(sys, 1.0, 0.0, mu);
    dq.setZero();
    Eigen::VectorXd y(sys.m);
    for (int e = 0; e < sys.m; ++e) y[e] = -W[e] * st.Phi()[e];
    st.addJt(sys, y.data(), dq.data());
    for (int k = 0; k < nt; ++k) {
      const CoordinateTarget& t = positions[k];
      const Row row = coordinateRow(sys, s, st, t);
      const double w = 1.0 / std::max(1e-300, row.J.squaredNorm());
      // weight the target row like a constraint row of the joint's bodies
      Eigen::MatrixXd R = row.J;
      st.addRowsToH(sys, sys.joints[t.joint]->id(), R, w * 1.0);
      addRowT(sys, t, row, -w * (row.Phi - t.value), dq.data());
    }
    if (st.cholesky().factorize(1e-15, true) != 0) {
      mu *= 10;
      continue;
    }
    st.cholesky().solve(dq.data());
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
  if (worst > std::max(tol, 1e-9)) {
    std::ostringstream os;
    os << "the mechanism does not close (largest residual " << fmt(st.positionViolation()) << "):";
    for (int ci = 0; ci < sys.numConstraints(); ++ci) {
      const ConstraintLayout& L = sys.layout[ci];
      const double r = L.size ? st.Phi().segment(L.row, L.size).cwiseAbs().maxCoeff() : 0.0;
      if (r > 1e-8 * sys.length_scale) os << " '" << sys.constraints[ci]->name() << "' (" << fmt(r) << ")";
    }
    for (const DriveSpec& D : sys.drives) {
      const ConstraintLayout& L = sys.layout[D.constraint];
      const double r = std::fabs(st.Phi()[L.row]);
      if (r > 1e-8 * sys.length_scale)
        os << "; the drive of '" << sys.joints[D.joint]->name() << "' asks for a position the mechanism cannot reach (off by " << fmt(r) << ")";
    }
    for (const auto& t : positions) {
      const double r = coordinateRow(sys, s, st, t).Phi - t.value;
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
    const unsigned uses = jt.equationAxes();
    const JointGeometry g = jt.geometry(st.kin()[jt.bodyI()], st.kin()[jt.bodyJ()], kBxI | kBzI | kBxJ | kBzJ);
    const bool parallel = (uses & kBzJ) && (uses & kByI);
    const bool twist = parallel && (uses & kBxJ);
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
    const double q = coordinateRow(sys, s, st, t).Phi;
    const double slack = 1e-9 * (std::fabs(L.lower) + std::fabs(L.upper) + sys.length_scale);
    if (q < L.lower - slack || q > L.upper + slack) {
      std::ostringstream os;
      os << "joint '" << sys.joints[L.joint]->name() << "': initial position " << fmt(q)
         << " is outside its limits [" << fmt(L.lower) << ", " << fmt(L.upper) << "]";
      throw ModelError(os.str());
    }
  }
  checkMassRank(sys, st);
  std::fill(s.dropped.begin(), s.dropped.end(), 0);
  st.evaluate(sys, s);
  const DependencyReport dependencies = analyzeDependencies(sys, st, &s.dropped);
  if (deps) *deps = dependencies;
  st.evaluate(sys, s);

  // ---- velocities: mass-orthogonal projection onto Phi_q v = 0 and G_k v = target by the
  // augmented Lagrangian, starting from the bodies' own velocities.
  try {
    st.factorHere(sys, s.t);
  } catch (const ModelError&) {
    throw;
  } catch (const std::runtime_error&) {
    throw ModelError(kSingularAtAssembly);
  }
  const Eigen::VectorXd W = st.rowWeights(sys);
  constexpr double kKappa = Stepper::kKappa;
  std::vector<Row> rows;
  std::vector<double> wt;
  for (const auto& t : velocities) {
    rows.push_back(coordinateRow(sys, s, st, t));
    wt.push_back(kKappa * st.rowWeight(sys, sys.joints[t.joint]->id(), Eigen::MatrixXd(rows.back().J)));
  }
  if (!velocities.empty()) {
    st.assembleH(sys, kKappa, 1.0, 0.0);
    for (size_t k = 0; k < velocities.size(); ++k) {
      Eigen::MatrixXd R = rows[k].J;
      st.addRowsToH(sys, sys.joints[velocities[k].joint]->id(), R, wt[k]);
    }
    if (st.cholesky().factorize(0.0, false) != 0) throw ModelError(kSingularAtAssembly);
  }
  Eigen::VectorXd Mu(sys.n), mu_c = Eigen::VectorXd::Zero(sys.m), Ju(sys.m), y(sys.m);
  std::vector<double> mu_t(velocities.size(), 0.0);
  st.mulM(sys, s.u.data(), Mu.data());
  double vres = 0;
  auto velocityError = [&]() {
    double worst_v = st.velocityResidual(sys, s.u);
    const double moving = st.motionScale(sys, s.u), V = moving == 0 ? sys.velocity_scale : moving;
    for (size_t k = 0; k < velocities.size(); ++k) {
      const double r = rowDot(sys, velocities[k], rows[k], s.u) - velocities[k].value;
      const double scale = std::fabs(velocities[k].value) + rateScale(sys, velocities[k], rows[k], V);
      worst_v = std::max(worst_v, scale > 0 ? std::fabs(r) / scale : std::fabs(r));
    }
    return worst_v;
  };
  for (int it = 0; it < 60; ++it) {
    vres = velocityError();
    if (vres <= sys.options.velocity_tol) break;
    s.u = Mu;
    // Phi_q v = nu: the drives' rates (zero for scleronomic equations)
    for (int e = 0; e < sys.m; ++e) y[e] = kKappa * W[e] * st.nu()[e] - mu_c[e];
    st.addJt(sys, y.data(), s.u.data());
    for (size_t k = 0; k < velocities.size(); ++k)
      addRowT(sys, velocities[k], rows[k], wt[k] * velocities[k].value - mu_t[k], s.u.data());
    st.cholesky().solve(s.u.data());
    st.mulJ(sys, s.u.data(), Ju.data());
    for (int e = 0; e < sys.m; ++e) mu_c[e] += kKappa * W[e] * (Ju[e] - st.nu()[e]);
    for (size_t k = 0; k < velocities.size(); ++k)
      mu_t[k] += wt[k] * (rowDot(sys, velocities[k], rows[k], s.u) - velocities[k].value);
  }
  report.velocity_residual = vres;
  if (vres > 1e-9) {
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
