// Evaluation records and the free functions over them (evaluation.h).
#include "core/absolute/evaluation.h"

#include <algorithm>
#include <cmath>

namespace mechanism_sim {
namespace {

// The size of the terms of the rows of Jb, a body's six columns of a Jacobian, in a
// position residual: |J_r| (|r|max + L) + |J_theta| per row, r the body's position and L
// the system's length scale (rowScale and positionResidual both take it from here).
template <class Rows>
inline Eigen::Matrix<double, Rows::RowsAtCompileTime, 1> termScale(const Rows& Jb, const Eigen::Vector3d& r,
                                                                   double length) {
  return Jb.template leftCols<3>().cwiseAbs().rowwise().sum() * (r.cwiseAbs().maxCoeff() + length) +
         Jb.template rightCols<3>().cwiseAbs().rowwise().sum();
}

// j M~^-1 j^T for each row j of Jb, a body's six columns of a Jacobian, with M~^-1 = Mi
// block diagonal (1/m, J'^-1): |j_r|^2 / m + j_theta J'^-1 j_theta^T (rowWeights and
// rowWeight both take it from here).
template <class Rows>
inline Eigen::Matrix<double, Rows::RowsAtCompileTime, 1> inverseMassTerms(const Rows& Jb, const Mat6& Mi) {
  return Jb.template leftCols<3>().rowwise().squaredNorm() * Mi(0, 0) +
         (Jb.template rightCols<3>() * Mi.template bottomRightCorner<3, 3>())
             .cwiseProduct(Jb.template rightCols<3>())
             .rowwise()
             .sum();
}

// A row's weight 1 / (j M~^-1 j^T), or 0 for a row that moves no mass.
inline double weightOf(double s) { return (s > 0 && std::isfinite(s)) ? 1.0 / s : 0.0; }


}  // namespace

Evaluation::Evaluation(const System& sys) {
  kin.assign(sys.bodies.size(), BodyKin());
  for (const auto& c : sys.constraints) J.push_back(Jacobian::Zero(6, 6 * static_cast<int>(c->bodies().size())));
  Phi = Eigen::VectorXd::Zero(sys.m), nu = Phi, gamma = Phi, W = Phi;
  Q = Eigen::VectorXd::Zero(sys.n);
  dropped.assign(sys.m, 0);
  dropped_scale.assign(sys.m, 0.0);
  stamp.x = Eigen::VectorXd::Zero(BodyCoordinates::positions(sys));
  stamp.u = Eigen::VectorXd::Zero(sys.n);
  stamp.limit_side.assign(sys.limits.size(), 0);
  stamp.drive.assign(sys.drives.size(), DriveRamp());
  rotor_rows.assign(2 * sys.rotors.size(), Row());
}

void loadKinematics(const System& sys, const double* x, const double* u, std::vector<BodyKin>& kin) {
  kin.resize(sys.bodies.size());
  kin[0] = BodyKin();
  for (int b = 1; b <= sys.nb; ++b) {
    const double* xb = x + BodyCoordinates::x(b - 1);
    const double* ub = u + BodyCoordinates::u(b - 1);
    BodyKin& k = kin[b];
    k.r = Vector3d(xb[0], xb[1], xb[2]);
    k.A_Oi = Quaterniond(xb[3], xb[4], xb[5], xb[6]).normalized().toRotationMatrix();
    k.v = Vector3d(ub[0], ub[1], ub[2]);
    k.w = Vector3d(ub[3], ub[4], ub[5]);
  }
}

void loadKinematics(const System& sys, const double* x, const double* u, Evaluation& ev) {
  loadKinematics(sys, x, u, ev.kin);
  ev.stamp.x = Eigen::Map<const Eigen::VectorXd>(x, BodyCoordinates::positions(sys));
  ev.stamp.u = Eigen::Map<const Eigen::VectorXd>(u, sys.n);
  ev.stamp.level = EvaluationStamp::kLoaded;
}

void evaluateConstraints(const System& sys, const State& st, Evaluation& ev, bool rates) {
  EvalContext ctx = st.context();
  ctx.rates = rates;
  const BodyKin* ptrs[kMaxConstraintBodies];
  for (int ci = 0; ci < sys.numConstraints(); ++ci) {
    const Constraint& c = *sys.constraints[ci];
    const ConstraintLayout& L = sys.layout[ci];
    gather(ev, c, ptrs);
    c.evaluate(ptrs, ctx, ev.Phi.segment(L.row, L.size), ev.J[ci].topRows(L.size), ev.gamma.segment(L.row, L.size));
  }
  for (int ci : sys.rheonomic) sys.constraints[ci]->velocityTerm(ctx, ev.nu.data() + sys.layout[ci].row);
  // Dependent equations (assembly found them) are implied by the others near the
  // constraint manifold; off it they are nearly dependent and make the KKT system
  // ill-posed, so they leave the solve (their Phi is still reported).
  // The size of a dropped row's terms is kept (droppedResidual).
  ev.dropped = st.dropped;
  if (!ev.dropped.empty())
    for (int ci = 0; ci < sys.numConstraints(); ++ci) {
      const ConstraintLayout& L = sys.layout[ci];
      for (int e = 0; e < L.size; ++e)
        if (ev.dropped[L.row + e]) {
          double scale = 0;
          for (size_t k = 0; k < L.bodies.size(); ++k)
            scale += termScale(ev.J[ci].block<1, 6>(e, 6 * k), ev.kin[L.bodies[k] + 1].r, sys.length_scale)(0);
          ev.dropped_scale[L.row + e] = scale;
          ev.J[ci].row(e).setZero(), ev.gamma[L.row + e] = 0.0, ev.nu[L.row + e] = 0.0;
        }
    }
  if (!sys.rotors.empty()) {
    ev.rotor_rows.resize(2 * sys.rotors.size());
    Row rows[kMaxJointDofs];
    for (size_t r = 0; r < sys.rotors.size(); ++r)
      for (size_t c = 0; c < sys.rotors[r].coords.size(); ++c) {
        jointRows(sys, ev, st, sys.rotors[r].coords[c].first, rows);
        ev.rotor_rows[2 * r + c] = rows[sys.rotors[r].coords[c].second];
      }
  }
  if (!rates) ev.gamma.setZero();  // (the joints' is not meaningful, the other constraints' not asked for)
  ev.stamp.limit_side = st.limit_side;
  ev.stamp.t = st.t;
  ev.stamp.drive = st.drive;
  ev.stamp.rates = rates;
  ev.stamp.level = EvaluationStamp::kEvaluated;
}

void evaluateAt(const System& sys, const State& s, Evaluation& ev, bool rates) {
  loadKinematics(sys, s.x.data(), s.u.data(), ev);
  evaluateConstraints(sys, s, ev, rates);
}

void jointRows(const System& sys, const Evaluation& ev, const State& s, int j, Row* rows) {
  const Joint& jt = *sys.joints[j];
  jt.coordinates(ev.kin[jt.bodyI()], ev.kin[jt.bodyJ()], s.tracked[jt.id()], rows);
}

Row jointRow(const System& sys, const Evaluation& ev, const State& s, int j, int k) {
  Row rows[kMaxJointDofs];
  jointRows(sys, ev, s, j, rows);
  return rows[k];
}

double limitValue(const System& sys, const Evaluation& ev, const State& s, const LimitSpec& L) {
  if (L.terms.empty()) return jointRow(sys, ev, s, L.joint, L.k).Phi;
  double q = 0.0;
  for (const LimitTerm& t : L.terms) q += t.c * jointRow(sys, ev, s, t.joint, t.k).Phi;
  return q;
}

void coulombFriction(const std::array<double, 3>& f, bool planar, const double rate[3], const double gPg[3][3],
                     std::array<double, 3>& out) {
  out = {0.0, 0.0, 0.0};
  double needed[3] = {0, 0, 0};
  const bool disc = planar && f[0] > 0.0 && f[1] > 0.0;
  if (disc) {  // the two in-plane translations together: a 2x2 effective inertia
    const double det = gPg[0][0] * gPg[1][1] - gPg[0][1] * gPg[1][0];
    if (det > 0) {
      needed[0] = (gPg[1][1] * rate[0] - gPg[0][1] * rate[1]) / det;
      needed[1] = (-gPg[1][0] * rate[0] + gPg[0][0] * rate[1]) / det;
      // clamp to the ellipse (needed_0 / f_0)^2 + (needed_1 / f_1)^2 <= 1, radially
      const double r = std::hypot(needed[0] / f[0], needed[1] / f[1]);
      const double scale = r > 1.0 ? 1.0 / r : 1.0;
      out[0] = -scale * needed[0];
      out[1] = -scale * needed[1];
    }
  }
  for (int k = disc ? 2 : 0; k < 3; ++k) {
    if (f[k] <= 0.0) continue;
    if (!(gPg[k][k] > 0)) {  // no free motion along it (a drive holds it): it slides as moved, against f
      out[k] = rate[k] > 0 ? -f[k] : rate[k] < 0 ? f[k] : 0.0;
      continue;
    }
    needed[k] = rate[k] / gPg[k][k];
    out[k] = -std::max(-f[k], std::min(f[k], needed[k]));
  }
}

void appliedForces(const System& sys, const State& s, const Inputs& in,
                   const std::vector<std::array<double, 3>>& damping,
                   const std::vector<std::array<double, 3>>& friction, Evaluation& ev) {
  Eigen::VectorXd& Q = ev.Q;
  for (int b = 1; b <= sys.nb; ++b) {
    const Body& B = sys.bodies[b];
    const BodyKin& k = ev.kin[b];
    const int at = BodyCoordinates::u(b - 1);
    Q.segment<3>(at) = B.m * sys.gravity + in.force[b];
    Q.segment<3>(at + 3) = in.torque[b] - k.w.cross(B.Jp * k.w);  // Euler, in omega'
  }
  auto addForceAt = [&](int b, const Vector3d& sp, const Vector3d& f) {
    if (b == System::kGround) return;
    const int at = BodyCoordinates::u(b - 1);
    Q.segment<3>(at) += f;
    Q.segment<3>(at + 3) += sp.cross(ev.kin[b].A_Oi.transpose() * f);
  };
  for (size_t i = 0; i < sys.springs.size(); ++i) {
    const SpringDamper& sd = sys.springs[i];
    const Vector3d f = sd.forceOnI(ev.kin[sd.body_i], ev.kin[sd.body_j], in.spring_actuation[i], sys.length_scale);
    addForceAt(sd.body_i, sd.sp_i, f);
    addForceAt(sd.body_j, sd.sp_j, -f);
  }
  Row rows[kMaxJointDofs];
  for (int j = 0; j < sys.numJoints(); ++j) {
    const auto& tau = in.effort[j];
    const auto& c = damping[j];
    const auto& fr = friction[j];
    const int dof = sys.joints[j]->dof();
    bool any = false;
    for (int k = 0; k < dof; ++k) any = any || tau[k] != 0.0 || c[k] != 0.0 || fr[k] != 0.0;
    if (!any) continue;
    jointRows(sys, ev, s, j, rows);
    for (int k = 0; k < dof; ++k)
      scatterRow(sys, j, rows[k], appliedEffort(tau[k], c[k], rows[k].Phi_dot, fr[k]), Q.data());
  }
  // Coulomb friction on sums of coordinates: its effort F as c_i F along each q_i
  for (size_t r = 0; r < sys.sum_friction.size() && r < s.sum_friction.size(); ++r) {
    if (s.sum_friction[r] == 0.0) continue;
    for (const LimitTerm& t : sys.sum_friction[r].terms)
      scatterRow(sys, t.joint, jointRow(sys, ev, s, t.joint, t.k), t.c * s.sum_friction[r], Q.data());
  }
  // the rotors' -G^T B (G a - gamma): its G^T B gamma part (addRotorMass has the other);
  // the motors' coupled damping
  for (size_t r = 0; r < sys.rotors.size(); ++r) {
    const RotorInertia& R = sys.rotors[r];
    const int n = static_cast<int>(R.coords.size());
    Eigen::Vector2d g = Eigen::Vector2d::Zero();
    for (int c = 0; c < n; ++c) g[c] = ev.rotor_rows[2 * r + c].gamma;
    Eigen::Vector2d f = R.B * g;
    if (R.damping_coupling != 0.0) {  // the motors' coupled damping, -D_01 q_dot of the other coordinate
      f[0] -= R.damping_coupling * ev.rotor_rows[2 * r + 1].Phi_dot;
      f[1] -= R.damping_coupling * ev.rotor_rows[2 * r].Phi_dot;
    }
    for (int c = 0; c < n; ++c) scatterRow(sys, R.coords[c].first, ev.rotor_rows[2 * r + c], f[c], Q.data());
  }
}

void addRotorMass(const System& sys, const Evaluation& ev, const double* v, double* out) {
  for (size_t r = 0; r < sys.rotors.size(); ++r) {
    const RotorInertia& R = sys.rotors[r];
    const int n = static_cast<int>(R.coords.size());
    Eigen::Vector2d y = Eigen::Vector2d::Zero();
    for (int c = 0; c < n; ++c) y[c] = rowDot(sys, R.coords[c].first, ev.rotor_rows[2 * r + c], v);
    const Eigen::Vector2d f = R.B * y;
    for (int c = 0; c < n; ++c) scatterRow(sys, R.coords[c].first, ev.rotor_rows[2 * r + c], f[c], out);
  }
}

// ---- the walk over the constraint blocks (no allocation). J[c] holds 6 rows (those past
// the constraint's size are zero), so every body block is a fixed-size 6x6.

void mulJ(const System& sys, const Evaluation& ev, const std::vector<int>& cs, const double* v, double* out) {
  for (int ci : cs) {
    Vec6 y = Vec6::Zero();
    forEachBlock(sys, ev, ci, [&](int, int b, const auto& Jb) {
      y.noalias() += Jb * Eigen::Map<const Vec6>(v + BodyCoordinates::u(b));
    });
    const ConstraintLayout& L = sys.layout[ci];
    for (int e = 0; e < L.size; ++e) out[L.row + e] = y[e];
  }
}

void addJt(const System& sys, const Evaluation& ev, const std::vector<int>& cs, const double* y, double* out) {
  for (int ci : cs) {
    const ConstraintLayout& L = sys.layout[ci];
    const Vec6 yc = padded(y + L.row, L.size);
    forEachBlock(sys, ev, ci, [&](int, int b, const auto& Jb) {
      Eigen::Map<Vec6>(out + BodyCoordinates::u(b)).noalias() += Jb.transpose() * yc;
    });
  }
}

void mulM(const System& sys, const double* v, double* out) {
  for (int b = 1; b <= sys.nb; ++b) {
    const Body& B = sys.bodies[b];
    Eigen::Map<Vec6> o(out + BodyCoordinates::u(b - 1));
    Eigen::Map<const Vec6> vb(v + BodyCoordinates::u(b - 1));
    o.head<3>() = B.m * vb.head<3>();
    o.tail<3>() = B.Jp * vb.tail<3>();
  }
}

void scatterRow(const System& sys, int joint, const Row& row, double x, double* out) {
  const int bs[2] = {sys.joints[joint]->bodyI(), sys.joints[joint]->bodyJ()};
  for (int s = 0; s < 2; ++s)
    if (bs[s] != System::kGround)
      Eigen::Map<Vec6>(out + BodyCoordinates::u(bs[s] - 1)) += row.J.segment<6>(6 * s).transpose() * x;
}

double rowDot(const System& sys, int joint, const Row& row, const double* v) {
  const int bs[2] = {sys.joints[joint]->bodyI(), sys.joints[joint]->bodyJ()};
  double d = 0;
  for (int s = 0; s < 2; ++s)
    if (bs[s] != System::kGround) d += row.J.segment<6>(6 * s).dot(Eigen::Map<const Vec6>(v + BodyCoordinates::u(bs[s] - 1)));
  return d;
}

void rowWeights(const System& sys, Evaluation& ev, const std::vector<int>& cs) {
  for (int ci : cs) {
    Vec6 sum = Vec6::Zero();  // diag(J M~^-1 J^T)
    forEachBlock(sys, ev, ci, [&](int, int b, const auto& Jb) { sum += inverseMassTerms(Jb, sys.Minv[b]); });
    const ConstraintLayout& L = sys.layout[ci];
    for (int e = 0; e < L.size; ++e) ev.W[L.row + e] = weightOf(sum[e]);
  }
}

double rowWeight(const System& sys, int constraint, const Eigen::Ref<const Eigen::MatrixXd>& row) {
  const ConstraintLayout& L = sys.layout[constraint];
  double s = 0;
  for (size_t k = 0; k < L.bodies.size(); ++k)
    if (L.bodies[k] >= 0) s += inverseMassTerms(row.block<1, 6>(0, 6 * k), sys.Minv[L.bodies[k]])(0);
  return weightOf(s);
}

// max_e |Phi_e| / (size of its terms): each row's terms are its Jacobian entries times the
// coordinates they multiply (|J_r| |r| for positions, |J_theta| for rotations).
double rowScale(const System& sys, const Evaluation& ev, const Constraint& c,
                const Eigen::Ref<const Eigen::MatrixXd>& J, int e) {
  double scale = 0;
  for (size_t k = 0; k < c.bodies().size(); ++k)
    scale += termScale(J.block<1, 6>(e, 6 * k), ev.kin[c.bodies()[k]].r, sys.length_scale)(0);
  return scale;
}

double motionScale(const System& sys, const Eigen::VectorXd& u) {
  double V = 0;
  for (int b = 0; b < sys.nb; ++b)
    V = std::max({V, u.segment<3>(BodyCoordinates::u(b)).cwiseAbs().maxCoeff(),
                  u.segment<3>(BodyCoordinates::u(b) + 3).cwiseAbs().maxCoeff() * sys.length_scale});
  return V;
}

void bodyScales(const System& sys, const Eigen::VectorXd& u, double floor, std::vector<std::array<double, 2>>& out) {
  const double L = sys.length_scale;
  for (int b = 0; b < sys.nb; ++b) {
    const double v0 = u.segment<3>(BodyCoordinates::u(b)).cwiseAbs().maxCoeff();
    const double w0 = u.segment<3>(BodyCoordinates::u(b) + 3).cwiseAbs().maxCoeff();
    out[b] = {std::max({v0, w0 * L, floor}), std::max({w0, v0 / L, floor / L})};
  }
}

double positionViolation(const Evaluation& ev) { return ev.Phi.size() ? ev.Phi.cwiseAbs().maxCoeff() : 0.0; }

double velocityViolation(const System& sys, const Evaluation& ev, const Eigen::VectorXd& u) {
  Eigen::VectorXd r(sys.m);
  mulJ(sys, ev, sys.all_constraints, u.data(), r.data());
  r -= ev.nu;
  return r.size() ? r.cwiseAbs().maxCoeff() : 0.0;
}

double positionResidual(const System& sys, const Evaluation& ev) {
  // per constraint, all rows at once: row e's scale is rowScale(c, J, e)
  double worst = 0;
  for (int ci = 0; ci < sys.numConstraints(); ++ci) {
    const ConstraintLayout& L = sys.layout[ci];
    const Jacobian& J = ev.J[ci];
    Vec6 scale = Vec6::Zero();
    for (size_t k = 0; k < L.bodies.size(); ++k)  // (kin[0] is the ground's: r = 0)
      scale += termScale(J.middleCols<6>(6 * k), ev.kin[L.bodies[k] + 1].r, sys.length_scale);
    for (int e = 0; e < L.size; ++e)
      if (ev.dropped.empty() || !ev.dropped[L.row + e]) worst = std::max(worst, relative(ev.Phi[L.row + e], scale[e]));
  }
  return worst;
}

double droppedResidual(const System& sys, const Evaluation& ev) {
  double worst = 0;
  for (int e = 0; e < sys.m_eq; ++e)
    if (ev.dropped[e]) worst = std::max(worst, relative(ev.Phi[e], ev.dropped_scale[e]));
  return worst;
}

// max_e |(Phi_q v)_e| / (size of its terms): |J_r| |v|_max + |J_theta| |w'|_max per body.
double velocityResidual(const System& sys, const Evaluation& ev, const Eigen::VectorXd& u,
                        std::vector<std::array<double, 2>>& scales) {
  const double floor = kFloor * std::max(motionScale(sys, u), sys.velocity_scale);
  bodyScales(sys, u, floor, scales);
  return velocityResidualAtScales(sys, ev, u, scales);
}

double velocityResidualAtScales(const System& sys, const Evaluation& ev, const Eigen::VectorXd& u,
                                const std::vector<std::array<double, 2>>& scales) {
  double worst = 0;
  for (int ci = 0; ci < sys.numConstraints(); ++ci) {
    const ConstraintLayout& L = sys.layout[ci];
    Vec6 value = -padded(ev.nu.data() + L.row, L.size);
    Vec6 scale = value.cwiseAbs();
    forEachBlock(sys, ev, ci, [&](int, int b, const auto& Jb) {
      const std::array<double, 2>& bs = scales[b];
      value.noalias() += Jb * u.segment<6>(BodyCoordinates::u(b));
      scale += Jb.template leftCols<3>().cwiseAbs().rowwise().sum() * bs[0] +
               Jb.template rightCols<3>().cwiseAbs().rowwise().sum() * bs[1];
    });
    for (int e = 0; e < L.size; ++e)
      if (ev.dropped.empty() || !ev.dropped[L.row + e]) worst = std::max(worst, relative(value[e], scale[e]));
  }
  return worst;
}

void displace(const System& sys, Eigen::VectorXd& x, const double* dq) {
  for (int b = 0; b < sys.nb; ++b) {
    double* xb = x.data() + BodyCoordinates::x(b);
    const double* d = dq + BodyCoordinates::u(b);
    xb[0] += d[0], xb[1] += d[1], xb[2] += d[2];
    Quaterniond p(xb[3], xb[4], xb[5], xb[6]);
    p = (p * expRotation(Vector3d(d[3], d[4], d[5]))).normalized();
    xb[3] = p.w(), xb[4] = p.x(), xb[5] = p.y(), xb[6] = p.z();
  }
}

void positionRates(const System& sys, const double* x, const double* u, double* xdot) {
  for (int b = 0; b < sys.nb; ++b) {
    const double* p = x + BodyCoordinates::x(b) + 3;
    const double* ub = u + BodyCoordinates::u(b);
    const double* w = ub + 3;
    double* xd = xdot + BodyCoordinates::x(b);
    xd[0] = ub[0], xd[1] = ub[1], xd[2] = ub[2];
    xd[3] = 0.5 * (-p[1] * w[0] - p[2] * w[1] - p[3] * w[2]);
    xd[4] = 0.5 * (p[0] * w[0] + p[2] * w[2] - p[3] * w[1]);
    xd[5] = 0.5 * (p[0] * w[1] + p[3] * w[0] - p[1] * w[2]);
    xd[6] = 0.5 * (p[0] * w[2] + p[1] * w[1] - p[2] * w[0]);
  }
}

}  // namespace mechanism_sim
