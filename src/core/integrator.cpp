// Mechanism: forces, accelerations, time stepping and projection onto the constraints.
#include <algorithm>
#include <cmath>
#include <sstream>

#include "mechanism_sim/core/couplers.h"
#include "mechanism_sim/core/mechanism.h"

namespace mechanism_sim {

void Mechanism::evaluateConstraints() {
  for (size_t ci = 0; ci < constraints_.size(); ++ci) {
    ConstraintData& cd = cdata_[ci];
    constraints_[ci]->evaluate(cd.kin.data(), Phi_.segment(cd.row, cd.size), cd.J,
                               gamma_.segment(cd.row, cd.size));
  }
}

// Q per body: [f (global, at the centre of mass); n' (body components)].
void Mechanism::computeForces() {
  for (int b = 1; b < numBodies(); ++b) {
    const Body& B = bodies_[b];
    const BodyKin& k = kin_[b];
    auto f = Q_.segment<3>(6 * (b - 1));
    auto n = Q_.segment<3>(6 * (b - 1) + 3);
    f = B.m * gravity_ + body_force_[b];
    n = body_torque_[b] - k.w.cross(B.Jp * k.w);  // Euler's equations in omega'
  }
  auto addForceAt = [&](int b, const Vector3d& sp, const Vector3d& f) {
    if (b == kGround) return;
    Q_.segment<3>(6 * (b - 1)) += f;
    Q_.segment<3>(6 * (b - 1) + 3) += sp.cross(kin_[b].A_Oi.transpose() * f);
  };
  for (const SpringDamper& s : springs_) {
    const Gap g = gap(kin_[s.body_i], s.sp_i, kin_[s.body_j], s.sp_j);
    const double L = g.d.norm();
    if (L < 1e-12) continue;  // direction undefined; no force
    const Vector3d e = g.d / L;
    const double F = s.k * (L - s.L0) + s.c * e.dot(g.d_dot) + s.f_act;
    addForceAt(s.body_i, s.sp_i, F * e);
    addForceAt(s.body_j, s.sp_j, -F * e);
  }
  for (int j = 0; j < numJoints(); ++j) {
    const auto& tau = joint_effort_[j];
    const auto& c = joint_damping_[j];
    const int dof = joints_[j]->dof();
    bool any = false;
    const auto& fr = friction_effort_[j];
    for (int k = 0; k < dof; ++k) any = any || tau[k] != 0.0 || c[k] != 0.0 || fr[k] != 0.0;
    if (!any) continue;
    std::array<Row, 3> rows;
    jointRows(j, rows);
    const int bs[2] = {joints_[j]->bodyI(), joints_[j]->bodyJ()};
    for (int k = 0; k < dof; ++k) {
      const double effort = tau[k] - c[k] * rows[k].Phi_dot + fr[k];  // along q_k
      for (int s = 0; s < 2; ++s)
        if (bs[s] != kGround)
          Q_.segment<6>(6 * (bs[s] - 1)) += rows[k].J.segment<6>(6 * s).transpose() * effort;
    }
  }
}

// Augmented Lagrangian iteration for M a + Phi_q^T lambda = Q, Phi_q a = gamma with H
// factored, warm-started from the last multipliers. Stops when
// max |Phi_q a - gamma| <= 1e-11 (1 + max |gamma|); at a singular configuration the
// inconsistent part of gamma cannot vanish and the count bounds it.
void Mechanism::solveAccelerations() {
  const double tol = 1e-11 * (1.0 + maxAbs(gamma_, m_));
  for (int it = 0; it < 20; ++it) {
    acc_ = Q_;
    for (int e = 0; e < m_; ++e) work_m_[e] = alpha_ * gamma_[e] - lambda_[e];
    addJtx(work_m_.data(), acc_.data());
    ldlt_.solve(acc_.data());
    mulJ(acc_.data(), work_m_.data());
    double res = 0;
    for (int e = 0; e < m_; ++e) {
      const double r = work_m_[e] - gamma_[e];
      lambda_[e] += alpha_ * r;
      res = std::max(res, std::fabs(r));
    }
    if (res <= tol) break;
  }
}

// (x, u) -> (x_dot, u_dot): r_dot = v, p_dot = p (x) (0, w) / 2, u_dot = a.
void Mechanism::rates(const double* x, const double* u, double* xdot, double* udot) {
  loadKinematics(x, u);
  evaluateConstraints();
  computeForces();
  assembleH(alpha_, 0.0, true);
  factorH("stage");
  solveAccelerations();
  positionRates(x, u, xdot);
  std::copy(acc_.data(), acc_.data() + n_, udot);
}

void Mechanism::positionRates(const double* x, const double* u, double* xdot) const {
  for (int b = 0; b < numBodies() - 1; ++b) {
    const double* p = x + 7 * b + 3;
    const double* w = u + 6 * b + 3;
    double* xd = xdot + 7 * b;
    xd[0] = u[6 * b], xd[1] = u[6 * b + 1], xd[2] = u[6 * b + 2];
    xd[3] = 0.5 * (-p[1] * w[0] - p[2] * w[1] - p[3] * w[2]);
    xd[4] = 0.5 * (p[0] * w[0] + p[2] * w[2] - p[3] * w[1]);
    xd[5] = 0.5 * (p[0] * w[1] + p[3] * w[0] - p[1] * w[2]);
    xd[6] = 0.5 * (p[0] * w[2] + p[1] * w[1] - p[2] * w[0]);
  }
}

void Mechanism::step(double h) {
  if (!built_) throw std::logic_error("Mechanism::step before build() and assemble()");
  if (!(h > 0) || !std::isfinite(h)) throw std::invalid_argument("step must be positive");
  x0_ = x_;
  u0_ = u_;
  // Stage 1 at the accepted state, whose accelerations finishStep() left in acc_.
  if (!acc_valid_) finishStep(false);
  positionRates(x0_.data(), u0_.data(), kx_[0].data());
  ku_[0] = acc_;
  auto stage = [&](int s, double c, int from) {
    xs_ = x0_ + (c * h) * kx_[from];
    us_ = u0_ + (c * h) * ku_[from];
    rates(xs_.data(), us_.data(), kx_[s].data(), ku_[s].data());
  };
  if (options_.method == "rk2") {  // Heun
    stage(1, 1.0, 0);
    x_ = x0_ + (0.5 * h) * (kx_[0] + kx_[1]);
    u_ = u0_ + (0.5 * h) * (ku_[0] + ku_[1]);
  } else {  // classical RK4
    stage(1, 0.5, 0);
    stage(2, 0.5, 1);
    stage(3, 1.0, 2);
    x_ = x0_ + (h / 6.0) * (kx_[0] + 2.0 * kx_[1] + 2.0 * kx_[2] + kx_[3]);
    u_ = u0_ + (h / 6.0) * (ku_[0] + 2.0 * ku_[1] + 2.0 * ku_[2] + ku_[3]);
  }
  t_ += h;
  ++steps_;
  last_h_ = h;
  finishStep(true);
}

// Brings the new state onto the constraints and prepares the next step.
void Mechanism::finishStep(bool project) {
  for (int b = 0; b < numBodies() - 1; ++b) x_.segment<4>(7 * b + 3).normalize();
  loadKinematics(x_.data(), u_.data());
  const bool limits_changed = updateLimits();
  if (project) projectPositions(limits_changed);
  for (size_t ci = 0; ci < constraints_.size(); ++ci) constraints_[ci]->accept(cdata_[ci].kin.data());
  evaluateConstraints();
  assembleH(alpha_, 0.0, true);
  factorH("projection");
  if (project) projectVelocities();
  for (auto& fe : friction_effort_) fe = {0.0, 0.0, 0.0};  // first solve without friction
  bool friction_done = false;
  for (int pass = 0; pass < 4; ++pass) {
    evaluateConstraints();
    computeForces();
    solveAccelerations();
    // Release limits that would have to pull (lambda of the wrong sign), then re-solve.
    bool released = false;
    for (size_t l = 0; l < limits_.size(); ++l) {
      LimitData& L = limits_[l];
      if (!L.active) continue;
      const double lam = lambda_[cdata_[limit_constraint_[l]].row];
      if ((L.active < 0 && lam > 0) || (L.active > 0 && lam < 0)) {
        setLimitSide(l, 0);
        released = true;
      }
    }
    if (released) {
      evaluateConstraints();
      assembleH(alpha_, 0.0, true);
      factorH("limit release");
      continue;
    }
    if (!friction_done) {  // friction from the friction-free accelerations, then re-solve
      friction_done = true;
      if (updateFriction()) continue;
    }
    break;
  }
  // Rows of released limits stay zero; the accelerations above are those of the next stage 1.
  acc_valid_ = true;
}

// Friction for the coming step, from the accepted state with H factored there and the
// friction-free accelerations in acc_. The effective inertia along coordinate k is
// I = 1 / (G H^{-1} G^T) (H^{-1} is the constrained inverse mass up to 1/alpha); the
// effort that leaves q_dot = 0 after one step h is I (q_dot / h + q_ddot_free), and
// friction supplies it up to f. Returns whether any friction acts.
bool Mechanism::updateFriction() {
  bool acting = false;
  for (int j = 0; j < numJoints(); ++j) {
    const auto& f = joint_friction_[j];
    auto& out = friction_effort_[j];
    const int dof = joints_[j]->dof();
    bool any = false;
    for (int k = 0; k < dof; ++k) any = any || f[k] > 0.0;
    if (!any) continue;
    std::array<Row, 3> rows;
    jointRows(j, rows);
    const int bs[2] = {joints_[j]->bodyI(), joints_[j]->bodyJ()};
    for (int k = 0; k < dof; ++k) {
      out[k] = 0.0;
      if (f[k] <= 0.0) continue;
      work_n_.setZero();
      double qddot = 0;
      for (int s = 0; s < 2; ++s)
        if (bs[s] != kGround) {
          work_n_.segment<6>(6 * (bs[s] - 1)) = rows[k].J.segment<6>(6 * s).transpose();
          qddot += rows[k].J.segment<6>(6 * s).dot(acc_.segment<6>(6 * (bs[s] - 1)));
        }
      ldlt_.solve(work_n_.data());
      double gHg = 0;
      for (int s = 0; s < 2; ++s)
        if (bs[s] != kGround) gHg += rows[k].J.segment<6>(6 * s).dot(work_n_.segment<6>(6 * (bs[s] - 1)));
      if (!(gHg > 0)) continue;
      const double needed = (rows[k].Phi_dot / last_h_ + qddot) / gHg;
      out[k] = -std::max(-f[k], std::min(f[k], needed));
      acting = acting || out[k] != 0.0;
    }
  }
  return acting;
}

// Activates a limit whose coordinate has passed its bound; returns whether any did.
bool Mechanism::updateLimits() {
  bool changed = false;
  for (size_t l = 0; l < limits_.size(); ++l) {
    LimitData& L = limits_[l];
    if (L.active) continue;
    const double q = jointPosition(L.joint, L.k);
    const int side = q < L.lower ? -1 : q > L.upper ? 1 : 0;
    if (!side) continue;
    setLimitSide(l, side);
    changed = true;
  }
  return changed;
}

// r += dr, p <- p (x) exp(dtheta'/2): a displacement in variation coordinates.
void Mechanism::applyDisplacement(const double* dq) {
  for (int b = 0; b < numBodies() - 1; ++b) {
    double* xb = x_.data() + 7 * b;
    const double* d = dq + 6 * b;
    xb[0] += d[0], xb[1] += d[1], xb[2] += d[2];
    Quaterniond p(xb[3], xb[4], xb[5], xb[6]);
    p = (p * expRotation(Vector3d(d[3], d[4], d[5]))).normalized();
    xb[3] = p.w(), xb[4] = p.x(), xb[5] = p.y(), xb[6] = p.z();
  }
  loadKinematics(x_.data(), u_.data());
}

// Mass-orthogonal projection of positions: Newton steps
//   dq = -(M + alpha Phi_q^T Phi_q)^{-1} alpha Phi_q^T Phi,
// the least-squares step for dependent equations too. The factorization of the last stage
// serves the first iterations (simplified Newton) unless the set of rows changed (a limit
// became active); it is renewed when progress is slow. A projection that cannot reach
// 1e-6 means the step left the constraint manifold: an error, not a result.
void Mechanism::projectPositions(bool refactor) {
  double previous = 0, err = 0;
  for (int it = 0; it < 40; ++it) {
    evaluateConstraints();
    err = maxAbs(Phi_, m_);
    if (err <= options_.position_tol) return;
    if ((it == 0 && refactor) || (it > 0 && err > 0.1 * previous)) {
      assembleH(alpha_, 0.0, true);
      factorH("position projection");
    }
    previous = err;
    work_n_.setZero();
    for (int e = 0; e < m_; ++e) work_m_[e] = -alpha_ * Phi_[e];
    addJtx(work_m_.data(), work_n_.data());
    ldlt_.solve(work_n_.data());
    applyDisplacement(work_n_.data());
  }
  evaluateConstraints();
  err = maxAbs(Phi_, m_);
  if (err > 1e-6) {
    int worst = 0;
    double worst_err = -1.0;
    for (size_t ci = 0; ci < cdata_.size(); ++ci) {
      const double e = maxAbs(Phi_.segment(cdata_[ci].row, cdata_[ci].size), cdata_[ci].size);
      if (e > worst_err) worst_err = e, worst = static_cast<int>(ci);
    }
    std::ostringstream os;
    os << "at t = " << t_ << " s: the step left the constraints (residual " << err << " at '"
       << constraints_[worst]->name() << "'); try a smaller step";
    throw std::runtime_error(os.str());
  }
}

// Mass-orthogonal projection of velocities onto Phi_q v = 0 (augmented Lagrangian):
//   (M + alpha Phi_q^T Phi_q) v_{k+1} = M v* - Phi_q^T mu_k,  mu_{k+1} = mu_k + alpha Phi_q v_{k+1}.
void Mechanism::projectVelocities() {
  mulM(u_.data(), work_n2_.data());
  work_m2_.setZero();
  for (int it = 0; it < 30; ++it) {
    mulJ(u_.data(), work_m_.data());
    if (maxAbs(work_m_, m_) <= options_.velocity_tol) break;
    u_ = work_n2_;
    for (int e = 0; e < m_; ++e) work_m_[e] = -work_m2_[e];
    addJtx(work_m_.data(), u_.data());
    ldlt_.solve(u_.data());
    mulJ(u_.data(), work_m_.data());
    for (int e = 0; e < m_; ++e) work_m2_[e] += alpha_ * work_m_[e];
  }
  loadKinematics(x_.data(), u_.data());
}

}  // namespace mechanism_sim
