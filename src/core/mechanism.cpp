// Mechanism: model building, validation, sparse layout and state queries.
// Dynamics and integration: integrator.cpp; assembly and analysis: assembly.cpp.
#include "mechanism_sim/core/mechanism.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <sstream>

#include <Eigen/Eigenvalues>
#include <Eigen/OrderingMethods>
#include <Eigen/SparseCore>

#include "mechanism_sim/core/couplers.h"

namespace mechanism_sim {

Mechanism::Mechanism() {
  Body ground;
  ground.name = "ground";
  bodies_.push_back(ground);
}

int Mechanism::addBody(const Body& body) {
  bodies_.push_back(body);
  built_ = false;
  return numBodies() - 1;
}

int Mechanism::addJoint(std::unique_ptr<Joint> joint) {
  for (int b : joint->bodies())
    if (b < 0 || b >= numBodies())
      throw ModelError("joint '" + joint->name() + "': body index out of range");
  if (joint->bodyI() == joint->bodyJ())
    throw ModelError("joint '" + joint->name() + "': joins body '" +
                     bodies_[joint->bodyI()].name + "' to itself");
  joints_.push_back(joint.get());
  joint_constraint_.push_back(numConstraints());
  joint_damping_.push_back({0, 0, 0});
  joint_friction_.push_back({0, 0, 0});
  friction_effort_.push_back({0, 0, 0});
  joint_effort_.push_back({0, 0, 0});
  constraints_.push_back(std::move(joint));
  built_ = false;
  return numJoints() - 1;
}

int Mechanism::addCoupler(const std::string& name, int joint_a, int k_a, int joint_b, int k_b,
                          double multiplier, double offset) {
  auto check = [&](int j, int k) {
    if (j < 0 || j >= numJoints() || k < 0 || k >= joints_[j]->dof())
      throw ModelError("coupler '" + name + "': no such joint coordinate");
    if (!joints_[j]->holonomicCoordinates())
      throw ModelError("coupler '" + name + "': joint '" + joints_[j]->name() +
                       "' has no position coordinate to couple");
  };
  check(joint_a, k_a);
  check(joint_b, k_b);
  if (joint_a == joint_b) throw ModelError("coupler '" + name + "': couples a joint to itself");
  if (!std::isfinite(multiplier) || !std::isfinite(offset))
    throw ModelError("coupler '" + name + "': multiplier and offset must be finite");
  constraints_.push_back(std::make_unique<CoordinateCoupler>(
      name, *joints_[joint_a], k_a, *joints_[joint_b], k_b, multiplier, offset));
  built_ = false;
  return numConstraints() - 1;
}

int Mechanism::addSpring(const SpringDamper& s) {
  if (s.body_i < 0 || s.body_i >= numBodies() || s.body_j < 0 || s.body_j >= numBodies())
    throw ModelError("spring '" + s.name + "': body index out of range");
  if (!(s.k >= 0) || !(s.c >= 0) || !(s.L0 >= 0) || !std::isfinite(s.k + s.c + s.L0 + s.f_act))
    throw ModelError("spring '" + s.name + "': stiffness, damping and rest length must be "
                     "finite and non-negative");
  springs_.push_back(s);
  return static_cast<int>(springs_.size()) - 1;
}

void Mechanism::setJointDamping(int joint, int k, double c) {
  if (!(c >= 0) || !std::isfinite(c))
    throw ModelError("joint '" + joints_.at(joint)->name() + "': damping must be finite and >= 0");
  joint_damping_.at(joint).at(k) = c;
  acc_valid_ = false;
}

void Mechanism::setJointFriction(int joint, int k, double f) {
  if (!(f >= 0) || !std::isfinite(f))
    throw ModelError("joint '" + joints_.at(joint)->name() + "': friction must be finite and >= 0");
  joint_friction_.at(joint).at(k) = f;
  acc_valid_ = false;
}

void Mechanism::setJointEffort(int joint, int k, double tau) {
  if (joint < 0 || joint >= numJoints() || k < 0 || k >= joints_[joint]->dof())
    throw std::out_of_range("no such joint coordinate");
  if (!std::isfinite(tau)) throw std::invalid_argument("effort must be finite");
  if (joint_effort_[joint][k] != tau) acc_valid_ = false;  // stage 1 must see it
  joint_effort_[joint][k] = tau;
}

void Mechanism::setBodyWrench(int body, const Vector3d& force, const Vector3d& torque_body) {
  body_force_.at(body) = force;
  body_torque_.at(body) = torque_body;
  acc_valid_ = false;
}

void Mechanism::setSpringActuation(int spring, double f_act) {
  springs_.at(spring).f_act = f_act;
  acc_valid_ = false;
}

void Mechanism::setJointLimits(int joint, int k, double lower, double upper) {
  const Joint& j = *joints_.at(joint);
  if (!j.holonomicCoordinates() || k < 0 || k >= j.dof())
    throw ModelError("joint '" + j.name() + "': limits need a position coordinate");
  if (!(lower <= upper) || !std::isfinite(lower) || !std::isfinite(upper))
    throw ModelError("joint '" + j.name() + "': limits need finite lower <= upper");
  limits_.push_back(LimitData{joint, k, lower, upper});
  built_ = false;
}

void Mechanism::setIntegrator(const IntegratorOptions& options) {
  if (options.method != "rk4" && options.method != "rk2")
    throw ModelError("unknown integrator '" + options.method + "' (known: rk4, rk2)");
  if (!(options.position_tol > 0) || !(options.velocity_tol > 0))
    throw ModelError("integrator tolerances must be positive");
  options_ = options;
}

namespace {

void validateBody(const Body& b) {
  const std::string who = "body '" + b.name + "': ";
  if (!std::isfinite(b.m) || b.m < 0) throw ModelError(who + "mass must be finite and >= 0");
  if (!b.Jp.allFinite()) throw ModelError(who + "inertia must be finite");
  const double scale = std::max(1e-300, b.Jp.cwiseAbs().maxCoeff());
  if ((b.Jp - b.Jp.transpose()).cwiseAbs().maxCoeff() > 1e-9 * scale)
    throw ModelError(who + "inertia must be symmetric");
  const Eigen::Vector3d ev = Eigen::SelfAdjointEigenSolver<Matrix3d>(b.Jp).eigenvalues();
  const double tol = 1e-9 * std::max(scale, 1e-12);
  if (ev.minCoeff() < -tol)
    throw ModelError(who + "inertia has a negative principal moment");
  if (ev(2) > ev(0) + ev(1) + tol)
    throw ModelError(who + "inertia violates the triangle inequality (largest principal "
                     "moment exceeds the sum of the other two)");
  if (!b.r.allFinite() || !b.p.coeffs().allFinite() || b.p.norm() < 1e-9 || !b.v.allFinite() ||
      !b.w.allFinite())
    throw ModelError(who + "initial state must be finite with a non-zero orientation");
}

}  // namespace

void Mechanism::build() {
  const int nb = numBodies() - 1;
  if (nb < 1) throw ModelError("the mechanism has no moving body");
  for (int b = 1; b <= nb; ++b) validateBody(bodies_[b]);
  if (!gravity_.allFinite()) throw ModelError("gravity must be finite");

  // Limits become constraints after all others, inactive until reached.
  constraints_.erase(std::remove_if(constraints_.begin(), constraints_.end(),
                                    [](const std::unique_ptr<Constraint>& c) {
                                      return dynamic_cast<LimitConstraint*>(c.get()) != nullptr;
                                    }),
                     constraints_.end());
  m_eq_ = 0;
  for (const auto& c : constraints_) m_eq_ += c->size();
  limit_constraint_.clear();
  for (const LimitData& l : limits_) {
    limit_constraint_.push_back(numConstraints());
    constraints_.push_back(std::make_unique<LimitConstraint>(*joints_[l.joint], l.k));
  }

  n_ = 6 * nb;
  body_force_.assign(numBodies(), Vector3d::Zero());
  body_torque_.assign(numBodies(), Vector3d::Zero());
  kin_.assign(numBodies(), BodyKin());

  // Block pattern of H = M + alpha Phi_q^T Phi_q over moving bodies.
  std::vector<std::set<int>> blocks(nb);
  for (int b = 0; b < nb; ++b) blocks[b].insert(b);
  for (const auto& c : constraints_)
    for (int b1 : c->bodies())
      for (int b2 : c->bodies())
        if (b1 > 0 && b2 > 0) blocks[b2 - 1].insert(b1 - 1);
  std::vector<int> start(nb + 1, 0);
  for (int b = 0; b < nb; ++b) start[b + 1] = start[b] + 36 * static_cast<int>(blocks[b].size());
  Hp_.assign(n_ + 1, 0);
  Hi_.clear();
  for (int b2 = 0; b2 < nb; ++b2)
    for (int c = 0; c < 6; ++c) {
      for (int b1 : blocks[b2])
        for (int r = 0; r < 6; ++r) Hi_.push_back(6 * b1 + r);
      Hp_[6 * b2 + c + 1] = static_cast<int>(Hi_.size());
    }
  Hx_.assign(Hi_.size(), 0.0);
  auto address = [&](int b1, int b2, int* base, int* stride) {
    const auto& col = blocks[b2];
    const int pos = static_cast<int>(std::distance(col.begin(), col.find(b1)));
    *base = start[b2] + 6 * pos;
    *stride = 6 * static_cast<int>(col.size());
  };
  diag_base_.resize(nb);
  diag_stride_.resize(nb);
  for (int b = 0; b < nb; ++b) address(b, b, &diag_base_[b], &diag_stride_[b]);

  // Per-constraint layout.
  cdata_.assign(constraints_.size(), ConstraintData());
  int row = 0;
  for (size_t ci = 0; ci < constraints_.size(); ++ci) {
    const Constraint& c = *constraints_[ci];
    ConstraintData& cd = cdata_[ci];
    const int nbc = static_cast<int>(c.bodies().size());
    cd.row = row;
    cd.size = c.size();
    row += cd.size;
    cd.J = Eigen::MatrixXd::Zero(cd.size, 6 * nbc);
    cd.cols.clear();
    cd.kin.clear();
    for (int b : c.bodies()) {
      cd.cols.push_back(b > 0 ? 6 * (b - 1) : -1);
      cd.kin.push_back(&kin_[b]);
    }
    cd.base.assign(nbc * nbc, -1);
    cd.stride.assign(nbc * nbc, 0);
    for (int k1 = 0; k1 < nbc; ++k1)
      for (int k2 = 0; k2 < nbc; ++k2) {
        const int b1 = c.bodies()[k1], b2 = c.bodies()[k2];
        if (b1 > 0 && b2 > 0) address(b1 - 1, b2 - 1, &cd.base[k1 * nbc + k2], &cd.stride[k1 * nbc + k2]);
      }
  }
  m_ = row;

  // Fill-reducing order of the body graph (AMD), expanded to the six rows of a body.
  Eigen::SparseMatrix<double> graph(nb, nb);
  std::vector<Eigen::Triplet<double>> trip;
  for (int b2 = 0; b2 < nb; ++b2)
    for (int b1 : blocks[b2]) trip.emplace_back(b1, b2, 1.0);
  graph.setFromTriplets(trip.begin(), trip.end());
  Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> order;
  Eigen::AMDOrdering<int>()(graph, order);
  std::vector<int> perm(n_);
  for (int k = 0; k < nb; ++k)
    for (int r = 0; r < 6; ++r) perm[6 * k + r] = 6 * order.indices()[k] + r;
  ldlt_.analyze(n_, Hp_, Hi_, perm);

  // Mass matrix diagonal blocks and the penalty alpha: 1e6 times the mean non-zero
  // diagonal entry of M, so the augmented Lagrangian contracts by ~1e-6 per iteration.
  double sum = 0;
  int count = 0;
  for (int b = 1; b <= nb; ++b) {
    const Body& B = bodies_[b];
    for (int k = 0; k < 3; ++k) {
      if (B.m > 0) sum += B.m, ++count;
      if (B.Jp(k, k) > 0) sum += B.Jp(k, k), ++count;
    }
  }
  alpha_ = 1e6 * (count ? sum / count : 1.0);

  auto zeros = [](Eigen::VectorXd& v, int size) { v = Eigen::VectorXd::Zero(size); };
  zeros(Phi_, m_), zeros(gamma_, m_), zeros(lambda_, m_), zeros(work_m_, m_), zeros(work_m2_, m_);
  zeros(work_query_, m_);
  zeros(Q_, n_), zeros(acc_, n_), zeros(work_n_, n_), zeros(work_n2_, n_);
  zeros(x_, 7 * nb), zeros(u_, n_), zeros(x0_, 7 * nb), zeros(u0_, n_);
  zeros(xs_, 7 * nb), zeros(us_, n_);
  for (int s = 0; s < 4; ++s) zeros(kx_[s], 7 * nb), zeros(ku_[s], n_);
  for (int b = 1; b <= nb; ++b) {
    const Body& B = bodies_[b];
    x_.segment<3>(7 * (b - 1)) = B.r;
    const Quaterniond p = B.p.normalized();
    x_.segment<4>(7 * (b - 1) + 3) << p.w(), p.x(), p.y(), p.z();
    u_.segment<3>(6 * (b - 1)) = B.v;
    u_.segment<3>(6 * (b - 1) + 3) = B.w;
  }
  loadKinematics(x_.data(), u_.data());
  deactivateLimits();
  built_ = true;
  acc_valid_ = false;
}

// ---- small linear algebra over the constraint blocks (no allocation)

void Mechanism::mulJ(const double* v, double* out) const {
  for (int e = 0; e < m_; ++e) out[e] = 0.0;
  for (const ConstraintData& cd : cdata_)
    for (size_t k = 0; k < cd.cols.size(); ++k) {
      if (cd.cols[k] < 0) continue;
      for (int e = 0; e < cd.size; ++e) {
        double s = 0;
        for (int c = 0; c < 6; ++c) s += cd.J(e, 6 * k + c) * v[cd.cols[k] + c];
        out[cd.row + e] += s;
      }
    }
}

void Mechanism::mulM(const double* u, double* out) const {
  for (int b = 0; b < numBodies() - 1; ++b) {
    const Body& B = bodies_[b + 1];
    Eigen::Map<Eigen::Matrix<double, 6, 1>> o(out + 6 * b);
    Eigen::Map<const Eigen::Matrix<double, 6, 1>> v(u + 6 * b);
    o.head<3>() = B.m * v.head<3>();
    o.tail<3>() = B.Jp * v.tail<3>();
  }
}

void Mechanism::addJtx(const double* x, double* out) const {
  for (const ConstraintData& cd : cdata_)
    for (size_t k = 0; k < cd.cols.size(); ++k) {
      if (cd.cols[k] < 0) continue;
      for (int c = 0; c < 6; ++c) {
        double s = 0;
        for (int e = 0; e < cd.size; ++e) s += cd.J(e, 6 * k + c) * x[cd.row + e];
        out[cd.cols[k] + c] += s;
      }
    }
}

// H = (mass ? M : 0) + shift I + alpha Phi_q^T Phi_q, into the fixed pattern.
void Mechanism::assembleH(double alpha, double shift, bool mass) {
  std::fill(Hx_.begin(), Hx_.end(), 0.0);
  const int nb = numBodies() - 1;
  for (int b = 0; b < nb; ++b) {
    const Body& B = bodies_[b + 1];
    double* blk = Hx_.data() + diag_base_[b];
    const int st = diag_stride_[b];
    for (int k = 0; k < 3; ++k) {
      blk[k * st + k] += shift + (mass ? B.m : 0.0);
      for (int l = 0; l < 3; ++l) blk[(3 + l) * st + 3 + k] += mass ? B.Jp(k, l) : 0.0;
      blk[(3 + k) * st + 3 + k] += shift;
    }
  }
  for (const ConstraintData& cd : cdata_) addJtJ(cd, cd.J, alpha);
}

// H += weight J^T J for rows J over the bodies of cd (6 columns a body), block by block
// into the fixed pattern; each off-diagonal pair is formed once and added with its transpose.
void Mechanism::addJtJ(const ConstraintData& cd, const Eigen::Ref<const Eigen::MatrixXd>& J, double weight) {
  using Block = Eigen::Matrix<double, 6, 6>;
  const int nbc = static_cast<int>(cd.cols.size());
  for (int k1 = 0; k1 < nbc; ++k1)
    for (int k2 = k1; k2 < nbc; ++k2) {
      const int base = cd.base[k1 * nbc + k2];
      if (base < 0) continue;
      const Block B = weight * J.middleCols<6>(6 * k1).transpose().lazyProduct(J.middleCols<6>(6 * k2));
      const int st = cd.stride[k1 * nbc + k2];
      for (int c = 0; c < 6; ++c)
        for (int r = 0; r < 6; ++r) Hx_[base + c * st + r] += B(r, c);
      if (k2 == k1) continue;
      const int base_t = cd.base[k2 * nbc + k1], st_t = cd.stride[k2 * nbc + k1];
      for (int c = 0; c < 6; ++c)
        for (int r = 0; r < 6; ++r) Hx_[base_t + c * st_t + r] += B(c, r);
    }
}

void Mechanism::factorH(const char* where) {
  if (ldlt_.factorize(Hx_.data(), 0.0, false) != 0) {
    std::ostringstream os;
    os << "at t = " << t_ << " s (" << where
       << "): the constrained mass matrix is singular; some motion moves no mass";
    throw std::runtime_error(os.str());
  }
}

double Mechanism::maxAbs(const Eigen::VectorXd& v, int size) const {
  double m = 0;
  for (int i = 0; i < size; ++i) m = std::max(m, std::fabs(v[i]));
  return m;
}

// ---- state <-> kinematics

void Mechanism::loadKinematics(const double* x, const double* u) {
  for (int b = 1; b < numBodies(); ++b) {
    const double* xb = x + 7 * (b - 1);
    const double* ub = u + 6 * (b - 1);
    BodyKin& k = kin_[b];
    k.r = Vector3d(xb[0], xb[1], xb[2]);
    k.A_Oi = Quaterniond(xb[3], xb[4], xb[5], xb[6]).normalized().toRotationMatrix();
    k.v = Vector3d(ub[0], ub[1], ub[2]);
    k.w = Vector3d(ub[3], ub[4], ub[5]);
  }
}

// ---- queries

Vector3d Mechanism::position(int b) const { return kin_.at(b).r; }
Matrix3d Mechanism::rotation(int b) const { return kin_.at(b).A_Oi; }
Quaterniond Mechanism::orientation(int b) const {
  if (b == kGround) return Quaterniond::Identity();
  const double* p = x_.data() + 7 * (b - 1) + 3;
  return Quaterniond(p[0], p[1], p[2], p[3]).normalized();
}

void Mechanism::jointRows(int joint, std::array<Row, 3>& rows) const {
  const Joint& j = *joints_.at(joint);
  j.coordinates(kin_[j.bodyI()], kin_[j.bodyJ()], rows.data());
}

double Mechanism::jointPosition(int joint, int k) const {
  std::array<Row, 3> rows;
  jointRows(joint, rows);
  return rows.at(k).Phi;
}

double Mechanism::jointVelocity(int joint, int k) const {
  std::array<Row, 3> rows;
  jointRows(joint, rows);
  return rows.at(k).Phi_dot;
}

double Mechanism::jointEffort(int joint, int k) const {
  double tau = joint_effort_.at(joint).at(k) - joint_damping_[joint][k] * jointVelocity(joint, k) +
               friction_effort_[joint][k];
  for (size_t l = 0; l < limits_.size(); ++l)
    if (limits_[l].joint == joint && limits_[l].k == k && limits_[l].active)
      tau -= lambda_[cdata_[limit_constraint_[l]].row];
  return tau;
}

Reaction Mechanism::reaction(int ci) const {
  const ConstraintData& cd = cdata_.at(ci);
  const Constraint& c = *constraints_[ci];
  const int k = static_cast<int>(c.bodies().size()) - 1;  // the last body (j of a joint)
  Eigen::Matrix<double, 6, 1> gen = Eigen::Matrix<double, 6, 1>::Zero();
  for (int e = 0; e < cd.size; ++e) gen -= cd.J.block<1, 6>(e, 6 * k).transpose() * lambda_[cd.row + e];
  const BodyKin& kb = kin_[c.bodies()[k]];
  Reaction r;
  r.force = gen.head<3>();
  Vector3d arm = Vector3d::Zero();
  if (const auto* j = dynamic_cast<const Joint*>(&c)) arm = kb.A_Oi * j->frameJ().sp_B;
  r.torque = kb.A_Oi * gen.tail<3>() - arm.cross(r.force);
  return r;
}

double Mechanism::positionViolation() const { return maxAbs(Phi_, m_); }

double Mechanism::velocityViolation() const {
  mulJ(u_.data(), work_query_.data());
  return maxAbs(work_query_, m_);
}

double Mechanism::kineticEnergy() const {
  double T = 0;
  for (int b = 1; b < numBodies(); ++b)
    T += 0.5 * bodies_[b].m * kin_[b].v.squaredNorm() + 0.5 * kin_[b].w.dot(bodies_[b].Jp * kin_[b].w);
  return T;
}

double Mechanism::potentialEnergy() const {
  double V = 0;
  for (int b = 1; b < numBodies(); ++b) V -= bodies_[b].m * gravity_.dot(kin_[b].r);
  for (const SpringDamper& s : springs_) {
    const Vector3d d = kin_[s.body_j].r + kin_[s.body_j].A_Oi * s.sp_j - kin_[s.body_i].r -
                       kin_[s.body_i].A_Oi * s.sp_i;
    V += 0.5 * s.k * (d.norm() - s.L0) * (d.norm() - s.L0);
  }
  return V;
}

Mechanism::Snapshot Mechanism::snapshot() const {
  Snapshot s;
  s.x.assign(x_.data(), x_.data() + x_.size());
  s.u.assign(u_.data(), u_.data() + u_.size());
  for (const auto& c : constraints_) s.tracked.push_back(c->tracked());
  s.t = t_;
  return s;
}

void Mechanism::restore(const Snapshot& s) {
  x_ = Eigen::Map<const Eigen::VectorXd>(s.x.data(), s.x.size());
  u_ = Eigen::Map<const Eigen::VectorXd>(s.u.data(), s.u.size());
  for (size_t c = 0; c < constraints_.size(); ++c) constraints_[c]->setTracked(s.tracked[c]);
  t_ = s.t;
  deactivateLimits();
  loadKinematics(x_.data(), u_.data());
  finishStep(false);
}

// The one place a limit changes state: its side and its constraint row together.
void Mechanism::setLimitSide(size_t l, int side) {
  LimitData& L = limits_[l];
  L.active = side;
  static_cast<LimitConstraint&>(*constraints_[limit_constraint_[l]])
      .setActive(side != 0, side < 0 ? L.lower : L.upper);
}

void Mechanism::deactivateLimits() {
  for (size_t l = 0; l < limits_.size(); ++l) setLimitSide(l, 0);
}

std::string DependencyReport::describe() const {
  std::ostringstream os;
  if (dependent == 0) {
    os << "all " << equations << " constraint equations are independent";
    return os.str();
  }
  os << dependent << " of " << equations << " constraint equations are dependent (";
  bool first = true;
  for (const auto& e : by_constraint) {
    os << (first ? "" : ", ") << "'" << e.first << "' " << e.second;
    first = false;
  }
  os << ")";
  return os.str();
}

}  // namespace mechanism_sim
