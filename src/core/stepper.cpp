// Stepper: forces, the KKT solve, time stepping and projection onto the constraints.
#include "mechanism_sim/core/stepper.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include <Eigen/Eigenvalues>

#include "mechanism_sim/core/couplers.h"

namespace mechanism_sim {
namespace {

// Dimensionless weight of the equations in H = M + kappa Phi_q^T W Phi_q (W: rowWeights).
// Each refinement pass contracts the KKT error by about 1/(kappa sigma), sigma the
// smallest eigenvalue of the row-scaled W^1/2 Phi_q M^-1 Phi_q^T W^1/2 (1 for one joint,
// about 1/N^2 along a chain of N bodies), while H's condition number, and with it the
// round-off a single solve leaves, grows like kappa. Measured on the 10-link chain
// (doc/method.md "Integration method"): 1e6 and 1e7 agree to 3e-10 m, 1e8 drifts by 1e-8 m.
constexpr double kKappa = Stepper::kKappa;
constexpr int kMaxSolvePasses = 12;
// Residual scales have a floor of kFloor times the largest motion (force) in the system,
// so that a body at rest beside moving ones is not judged on round-off alone.
constexpr double kFloor = 1e-6;
// Dropped rows whose relative residual passes this many times the position tolerance are
// no longer implied by the rows kept (finishStep analyzes the dependencies again).
constexpr double kDependentDrift = 10.0;
constexpr int kMaxNewton = 20;
// A projection that ends with a relative residual above position_tol (velocity_tol) is
// counted and the run goes on; above kFailureResidual the constraints are visibly broken
// and the step fails (StepFailure: retaken in halves, then the run stops).
constexpr double kFailureResidual = 1e-6;
constexpr int kMaxVelocityPasses = 8;
constexpr int kMaxHalvings = 6;
constexpr double kMaxTurn = 0.25;  // rad a body may turn in one step (phase error < 1e-6 rad)


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
inline Eigen::Matrix<double, Rows::RowsAtCompileTime, 1> inverseMassTerms(const Rows& Jb,
                                                                          const Eigen::Matrix<double, 6, 6>& Mi) {
  return Jb.template leftCols<3>().rowwise().squaredNorm() * Mi(0, 0) +
         (Jb.template rightCols<3>() * Mi.template bottomRightCorner<3, 3>())
             .cwiseProduct(Jb.template rightCols<3>())
             .rowwise()
             .sum();
}

// A row's weight 1 / (j M~^-1 j^T), or 0 for a row that moves no mass.
inline double weightOf(double s) { return (s > 0 && std::isfinite(s)) ? 1.0 / s : 0.0; }

// |r| / scale, where scale is the size of the terms r was computed from; 0/0 = 0.
inline double relative(double r, double scale) {
  r = std::fabs(r);
  if (r == 0.0) return 0.0;
  return scale > 0.0 ? r / scale : HUGE_VAL;
}

}  // namespace

void loadKinematics(const System& sys, const double* x, const double* u, std::vector<BodyKin>& kin) {
  kin.resize(sys.bodies.size());
  kin[0] = BodyKin();
  for (int b = 1; b <= sys.nb; ++b) {
    const double* xb = x + 7 * (b - 1);
    const double* ub = u + 6 * (b - 1);
    BodyKin& k = kin[b];
    k.r = Vector3d(xb[0], xb[1], xb[2]);
    k.A_Oi = Quaterniond(xb[3], xb[4], xb[5], xb[6]).normalized().toRotationMatrix();
    k.v = Vector3d(ub[0], ub[1], ub[2]);
    k.w = Vector3d(ub[3], ub[4], ub[5]);
  }
}

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

Stepper::Stepper(const System& sys) {
  kin_.assign(sys.bodies.size(), BodyKin());
  J_.clear();
  for (const auto& c : sys.constraints)
    J_.push_back(Jacobian::Zero(6, 6 * static_cast<int>(c->bodies().size())));
  J_frozen_ = J_;
  sizes_.clear();
  for (const auto& c : sys.constraints) sizes_.push_back(c->size());
  auto zeros = [](Eigen::VectorXd& v, int size) { v = Eigen::VectorXd::Zero(size); };
  zeros(Phi_, sys.m), zeros(nu_, sys.m), zeros(gamma_, sys.m), zeros(W_, sys.m), zeros(lam_, sys.m);
  zeros(r2_, sys.m), zeros(s2_, sys.m), zeros(dm_, sys.m), zeros(dl_, sys.m), zeros(query_, sys.m);
  zeros(Q_, sys.n), zeros(a_, sys.n), zeros(r1_, sys.n), zeros(s1_, sys.n), zeros(dn_, sys.n);
  zeros(x0_, 7 * sys.nb), zeros(u0_, sys.n), zeros(xs_, 7 * sys.nb), zeros(us_, sys.n);
  tableau_ = &tableau(parseMethod(sys.options.method));
  for (int s = 0; s < Tableau::kMaxStages; ++s) zeros(kx_[s], 7 * sys.nb), zeros(ku_[s], sys.n);
  zeros(sum_x_, 7 * sys.nb), zeros(sum_u_, sys.n);
  chol_.analyze(sys.nb, sys.block_edges);
  zeros(zero_rows_, sys.m);
  body_scale_.assign(sys.nb, {0.0, 0.0});
  start_scale_.assign(sys.nb, {0.0, 0.0});
  length_scale_ = sys.length_scale;
  // everything a step writes is sized here: a step allocates nothing
  backup_.assign(kMaxHalvings + 1, initialState(sys));
  start_ = backup_[0];
  tracked0_ = backup_[0].tracked;
  tracked_rate_ = backup_[0].tracked;
  zeros(loaded_x_, 7 * sys.nb), zeros(evaluated_x_, 7 * sys.nb);
  factored_x_ = Eigen::VectorXd::Constant(7 * sys.nb, NAN);  // nothing factored yet
  evaluated_side_.assign(sys.limits.size(), 0);
  factored_side_.assign(sys.limits.size(), 1);
  dropped_.assign(sys.m, 0);
  eval_x_ = loaded_x_, eval_u_ = u0_;
  eval_side_ = evaluated_side_;
  // Inverse masses with stand-ins: a massless body weighs the mean mass, a body without
  // moments the mean moment (System scales), and every moment is raised by 1e-3 of the
  // body's mean moment, so a zero principal moment (a thin rod's) does not make the
  // weights of the equations that hold that rotation vanish. They only scale W (the
  // refinement solves the exact KKT system); with 1e-9 instead of 1e-3 a 7 kg ram with
  // ixx = 0 fell short on nearly every solve (test FuzzFindings.ZeroPrincipalMoment...).
  Minv_.assign(sys.nb, Eigen::Matrix<double, 6, 6>::Zero());
  for (int b = 1; b <= sys.nb; ++b) {
    const Body& B = sys.bodies[b];
    const double m = B.m > 0 ? B.m : sys.mass_scale;
    const double tr = B.Jp.trace() / 3.0;
    const Matrix3d Jp = B.Jp + (tr > 0 ? 1e-3 * tr : sys.inertia_scale) * Matrix3d::Identity();
    Minv_[b - 1].topLeftCorner<3, 3>() = Matrix3d::Identity() / m;
    Minv_[b - 1].bottomRightCorner<3, 3>() = Jp.inverse();
  }
  buildTree(sys);
  initDamping(sys);
  // Rows can depend on others where equations close loops or couple joints: those outside
  // the tree (a tree's joint equations and the limits on its coordinates never do).
  for (int ci = 0; ci < sys.numConstraints(); ++ci)
    if (sys.layout[ci].row < sys.m_eq && sys.layout[ci].size > 0 && tree_node_[ci] < 0) watch_dependencies_ = true;
  if (watch_dependencies_) {
    dependencies_.init(sys);
    dropped_before_.assign(sys.m, 0);
  }
  dropped_scale_.assign(sys.m, 0.0);
}

DependencyReport Stepper::analyzeDependencies(const System& sys, State& s) {
  if (!dependencies_.ready()) dependencies_.init(sys);
  DependencyReport report;
  load(sys, s.x.data(), s.u.data());
  refreshDependencies(sys, s, &report);
  return report;
}

bool Stepper::refreshDependencies(const System& sys, State& s, DependencyReport* report) {
  dropped_before_ = s.dropped;
  std::fill(s.dropped.begin(), s.dropped.end(), 0);
  evaluate(sys, s);  // every row, none dropped
  dependencies_.analyze(sys, kin_, J_, s.limit_side.data(), s.dropped, report);
  evaluate(sys, s);
  return s.dropped != dropped_before_;
}

void Stepper::load(const System& sys, const double* x, const double* u) {
  loadKinematics(sys, x, u, kin_);
  loaded_x_ = Eigen::Map<const Eigen::VectorXd>(x, 7 * sys.nb);
}

void Stepper::gather(const Constraint& c, const BodyKin** ptrs) const {
  for (size_t k = 0; k < c.bodies().size(); ++k) ptrs[k] = &kin_[c.bodies()[k]];
}

void Stepper::trackAngles(const System& sys, State& s, std::vector<Tracked>* rates) const {
  const EvalContext ctx = s.context();
  const BodyKin* ptrs[kMaxConstraintBodies];
  Tracked rate;
  for (int ci = 0; ci < sys.numConstraints(); ++ci) {
    gather(*sys.constraints[ci], ptrs);
    sys.constraints[ci]->track(ptrs, ctx, s.tracked[ci], rates ? (*rates)[ci] : rate);
  }
}

void Stepper::evaluate(const System& sys, const State& st) {
  const EvalContext ctx = st.context();
  const BodyKin* ptrs[kMaxConstraintBodies];
  for (int ci = 0; ci < sys.numConstraints(); ++ci) {
    const Constraint& c = *sys.constraints[ci];
    const ConstraintLayout& L = sys.layout[ci];
    gather(c, ptrs);
    c.evaluate(ptrs, ctx, Phi_.segment(L.row, L.size), J_[ci].topRows(L.size), gamma_.segment(L.row, L.size));
  }
  for (int ci : sys.rheonomic) sys.constraints[ci]->velocityTerm(ctx, nu_.data() + sys.layout[ci].row);
  // Dependent equations (assembly found them) are implied by the others near the
  // constraint manifold; off it they are nearly dependent and make the KKT system
  // ill-posed, so they leave the solve (their Phi is still reported).
  // The size of a dropped row's terms is kept (droppedResidual).
  dropped_ = st.dropped;
  if (!dropped_.empty())
    for (int ci = 0; ci < sys.numConstraints(); ++ci) {
      const ConstraintLayout& L = sys.layout[ci];
      for (int e = 0; e < L.size; ++e)
        if (dropped_[L.row + e]) {
          double scale = 0;
          for (size_t k = 0; k < L.bodies.size(); ++k)
            scale += termScale(J_[ci].block<1, 6>(e, 6 * k), kin_[L.bodies[k] + 1].r, length_scale_)(0);
          dropped_scale_[L.row + e] = scale;
          J_[ci].row(e).setZero(), gamma_[L.row + e] = 0.0, nu_[L.row + e] = 0.0;
        }
    }
  evaluated_x_ = loaded_x_;
  evaluated_side_ = st.limit_side;
  ++stats_.evaluations;
}

// ---- products over the constraint blocks (no allocation). J_[c] holds 6 rows (those past
// the constraint's size are zero), so every body block is a fixed-size 6x6.

namespace {
using Vec6 = Eigen::Matrix<double, 6, 1>;
using Mat6 = Eigen::Matrix<double, 6, 6>;
inline Vec6 padded(const double* y, int size) {
  Vec6 v = Vec6::Zero();
  for (int e = 0; e < size; ++e) v[e] = y[e];
  return v;
}
}  // namespace

void Stepper::mulJ(const System& sys, const double* v, double* out) const { mulJ(sys, all_constraints_, v, out); }

void Stepper::mulJ(const System& sys, const std::vector<int>& cs, const double* v, double* out) const {
  for (int ci : cs) {
    const ConstraintLayout& L = sys.layout[ci];
    const Jacobian& J = J_[ci];
    Vec6 y = Vec6::Zero();
    for (size_t s = 0; s < L.bodies.size(); ++s) {
      if (L.bodies[s] < 0) continue;
      y.noalias() += J.middleCols<6>(6 * s) * Eigen::Map<const Vec6>(v + 6 * L.bodies[s]);
    }
    for (int e = 0; e < L.size; ++e) out[L.row + e] = y[e];
  }
}

void Stepper::addJt(const System& sys, const double* y, double* out) const { addJt(sys, all_constraints_, y, out); }

void Stepper::addJt(const System& sys, const std::vector<int>& cs, const double* y, double* out) const {
  for (int ci : cs) {
    const ConstraintLayout& L = sys.layout[ci];
    const Jacobian& J = J_[ci];
    const Vec6 yc = padded(y + L.row, L.size);
    for (size_t s = 0; s < L.bodies.size(); ++s) {
      if (L.bodies[s] < 0) continue;
      Eigen::Map<Vec6>(out + 6 * L.bodies[s]).noalias() += J.middleCols<6>(6 * s).transpose() * yc;
    }
  }
}

void Stepper::mulM(const System& sys, const double* v, double* out) const {
  for (int b = 1; b <= sys.nb; ++b) {
    const Body& B = sys.bodies[b];
    Eigen::Map<Eigen::Matrix<double, 6, 1>> o(out + 6 * (b - 1));
    Eigen::Map<const Eigen::Matrix<double, 6, 1>> vb(v + 6 * (b - 1));
    o.head<3>() = B.m * vb.head<3>();
    o.tail<3>() = B.Jp * vb.tail<3>();
  }
}

const Eigen::VectorXd& Stepper::rowWeights(const System& sys) { return rowWeights(sys, all_constraints_); }

const Eigen::VectorXd& Stepper::rowWeights(const System& sys, const std::vector<int>& cs) {
  for (int ci : cs) {
    const ConstraintLayout& L = sys.layout[ci];
    const Jacobian& J = J_[ci];
    Vec6 sum = Vec6::Zero();  // diag(J M~^-1 J^T)
    for (size_t k = 0; k < L.bodies.size(); ++k)
      if (L.bodies[k] >= 0) sum += inverseMassTerms(J.middleCols<6>(6 * k), Minv_[L.bodies[k]]);
    for (int e = 0; e < L.size; ++e) W_[L.row + e] = weightOf(sum[e]);
  }
  return W_;
}

// H = mass M + shift M~ + kappa sum_c J_c^T W_c J_c, block by block into the factor's
// storage (M~: the stand-in masses of Minv_, used as Levenberg-Marquardt damping).
void Stepper::assembleH(const System& sys, double kappa, double mass, double shift) {
  chol_.setZero();
  for (int b = 1; b <= sys.nb; ++b) {
    bool t = false;
    auto& D = chol_.block(chol_.address(b - 1, b - 1, &t));
    const Body& B = sys.bodies[b];
    D.topLeftCorner<3, 3>().diagonal().array() += mass * B.m;
    D.bottomRightCorner<3, 3>() += mass * B.Jp;
    if (shift != 0.0) D.diagonal() += shift * Minv_[b - 1].diagonal().cwiseInverse();
  }
  for (int ci = 0; ci < sys.numConstraints(); ++ci)
    addPenalty(sys, ci, kappa, chol_, sys.layout[ci].address.data(), sys.layout[ci].transposed.data());
}

namespace {
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

void Stepper::addPenalty(const System& sys, int ci, double kappa, BlockCholesky& target, const int* address,
                         const char* transposed) {
  const Jacobian& J = J_[ci];
  const ConstraintLayout& L = sys.layout[ci];
  const int k = static_cast<int>(L.bodies.size());
  const Vec6 w = kappa * padded(W_.data() + L.row, L.size);
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

// The KKT matrix of the tree joints with the other equations in penalty form:
//   bodies: M + kappa sum_p J_p^T W_p J_p;  tree block t, body b: J_tb;  t, t: 0
// (a tree block's rows: its joint's equations, then the drives and limits merged into it;
// -1 on the padding rows past them and on rows that are zero, an inactive limit's or a
// dropped one's: decoupled, dl = -r2, which is 0 in a solve, their gamma being 0).
//
// Every block is written here, none only added to: the blocks the penalized equations add
// to (body pairs) are zeroed first, the others assigned (a tree has no fill), so the
// storage is not swept clean before each factorization.
void Stepper::assembleKKT(const System& sys) {
  for (int b = 1; b <= sys.nb; ++b) {
    bool t = false;
    auto& D = kkt_.block(kkt_.address(b - 1, b - 1, &t));
    D.setZero();
    D.topLeftCorner<3, 3>().diagonal().array() = sys.bodies[b].m;
    D.bottomRightCorner<3, 3>() = sys.bodies[b].Jp;
  }
  for (int a : kkt_added_) kkt_.block(a).setZero();
  for (int ci : penalized_) addPenalty(sys, ci, kKappa, kkt_, kkt_address_[ci].data(), kkt_transposed_[ci].data());
  for (int ci = 0; ci < sys.numConstraints(); ++ci) {
    if (tree_node_[ci] < 0) continue;
    const ConstraintLayout& L = sys.layout[ci];
    const std::vector<NodeRow>& rows = node_rows_[tree_node_[ci] - sys.nb];
    const Jacobian& J = J_[ci];
    const std::vector<int>& address = kkt_address_[ci];
    for (size_t s = 0; s < L.bodies.size(); ++s) {
      if (L.bodies[s] < 0) continue;
      // rows: the joint's equations (zero past its size), then its drives and limits
      BlockCholesky::Block& B = kkt_.block(address[s]);
      if (kkt_transposed_[ci][s]) {
        B = J.middleCols<6>(6 * s).transpose();
        for (size_t r = L.size; r < rows.size(); ++r)
          B.col(r) = J_[rows[r].constraint].row(rows[r].e).segment<6>(6 * s).transpose();
      } else {
        B = J.middleCols<6>(6 * s);
        for (size_t r = L.size; r < rows.size(); ++r) B.row(r) = J_[rows[r].constraint].row(rows[r].e).segment<6>(6 * s);
      }
    }
    auto& D = kkt_.block(address.back());
    D.setZero();
    const int size = static_cast<int>(rows.size());
    for (int e = size; e < 6; ++e) D(e, e) = -1.0;
    if (!dropped_.empty())
      for (int e = 0; e < L.size; ++e)
        if (dropped_[L.row + e]) D(e, e) = -1.0;
    for (int e = L.size; e < size; ++e)  // an inactive limit's row is zero
      if (J_[rows[e].constraint].row(rows[e].e).squaredNorm() == 0.0) D(e, e) = -1.0;
  }
}

// The spanning tree (forest) of joints held exactly by the KKT factorization: from the
// ground outwards (depth first), a joint joins the tree when it ties a body not yet
// reached (which must have a positive definite mass matrix: its pivot is then definite)
// to one that is; bodies left over start trees of their own. Block rows are eliminated
// leaves first: each body, then the joint to its parent, before the parent. A joint's
// drives and limits are rows of its block; a mechanism with loop closures or couplers
// keeps H for everything (below).
void Stepper::buildTree(const System& sys) {
  const int nc = sys.numConstraints();
  tree_node_.assign(nc, -1);
  all_constraints_.resize(nc);
  for (int ci = 0; ci < nc; ++ci) all_constraints_[ci] = ci;
  auto definite = [&](int body) {  // moving-body index
    const Body& B = sys.bodies[body + 1];
    const double tr = B.Jp.trace();
    return B.m > 0 && tr > 0 && Eigen::SelfAdjointEigenSolver<Matrix3d>(B.Jp).eigenvalues().minCoeff() > 1e-6 * tr;
  };
  std::vector<int> parent_joint(sys.nb, -1), parent(sys.nb, -1);
  std::vector<char> reached(sys.nb, 0);
  std::vector<int> roots;  // bodies no tree joint ties to the ground (floating ones)
  std::vector<int> joint_cs;
  for (int j = 0; j < sys.numJoints(); ++j)
    if (sys.joints[j]->size() > 0 && sys.joints[j]->bodies().size() == 2) joint_cs.push_back(sys.joint_constraint[j]);
  std::vector<std::vector<int>> incident(sys.nb + 1);  // [nb]: the ground's
  for (int ci : joint_cs)
    for (int b : sys.layout[ci].bodies) incident[b < 0 ? sys.nb : b].push_back(ci);
  std::vector<std::pair<int, size_t>> path;
  auto grow = [&](int top) {  // top: a moving body or -1 (the ground)
    path.assign(1, {top, 0});
    while (!path.empty()) {
      auto& [x, next] = path.back();
      const std::vector<int>& js = incident[x < 0 ? sys.nb : x];
      if (next == js.size()) {
        path.pop_back();
        continue;
      }
      const int ci = js[next++];
      if (tree_node_[ci] >= 0) continue;
      const int a = sys.layout[ci].bodies[0], b = sys.layout[ci].bodies[1];
      const int y = a == x ? b : a;
      if (y < 0 || reached[y] || !definite(y)) continue;
      reached[y] = 1;
      parent[y] = x;
      parent_joint[y] = ci;
      tree_node_[ci] = 0;  // numbered below
      path.push_back({y, 0});
    }
  };
  grow(-1);
  for (int b = 0; b < sys.nb; ++b)
    if (!reached[b]) reached[b] = 1, roots.push_back(b), grow(b);
  // Trees only: besides the tree's joints there may be drives and limits of tree joints
  // (rows of the joint's block, or weighted when they do not fit: no fill either way, they
  // couple the body pair of a tree joint), not loop closures or couplers. Near
  // a configuration where a loop's equations become dependent (a parallelogram passing
  // flat) the exact tree rows push all of the inconsistency into the loop's penalized
  // rows: the four-bar at h = 1/64 ms left 38 solves short by up to 1.6e-4 (relative)
  // this way, against 69 by at most 7.6e-8 in penalty form, which spreads it over every
  // equation by its weight. A loop's passes stay in either form, so mechanisms with
  // loops keep H.
  std::vector<char> allowed(nc, 0);
  for (const DriveSpec& D : sys.drives) allowed[D.constraint] = tree_node_[sys.joint_constraint[D.joint]] >= 0;
  for (const LimitSpec& L : sys.limits) allowed[L.constraint] = tree_node_[sys.joint_constraint[L.joint]] >= 0;
  bool tree = false;
  for (int ci = 0; ci < nc; ++ci) {
    if (tree_node_[ci] >= 0) tree = true;
    else if (sys.layout[ci].size > 0 && !allowed[ci]) {
      tree = false;
      break;
    }
  }
  if (!tree) {
    std::fill(tree_node_.begin(), tree_node_.end(), -1);
    penalized_ = all_constraints_;
    kkt_ = BlockCholesky();
    return;
  }
  // post-order: children before parents, each body followed by its parent joint
  std::vector<std::vector<int>> children(sys.nb + 1);  // [nb]: the ground's
  for (int b = 0; b < sys.nb; ++b)
    if (parent_joint[b] >= 0) children[parent[b] < 0 ? sys.nb : parent[b]].push_back(b);
  std::vector<int> order;
  std::vector<int> tree_cs;
  std::vector<std::pair<int, size_t>> stack;
  auto visit = [&](int top) {  // iterative post-order of the subtree of body `top`
    stack.push_back({top, 0});
    while (!stack.empty()) {
      auto& [b, next] = stack.back();
      if (next < children[b].size()) {
        const int c = children[b][next++];
        stack.push_back({c, 0});
        continue;
      }
      order.push_back(b);
      if (parent_joint[b] >= 0) tree_cs.push_back(parent_joint[b]), order.push_back(-1 - parent_joint[b]);
      stack.pop_back();
    }
  };
  for (int b : children[sys.nb]) visit(b);
  for (int r : roots) visit(r);
  for (size_t k = 0; k < tree_cs.size(); ++k) tree_node_[tree_cs[k]] = sys.nb + static_cast<int>(k);
  for (int& o : order)
    if (o < 0) o = tree_node_[-1 - o];
  const int nodes = sys.nb + static_cast<int>(tree_cs.size());
  // The rows of each tree block: its joint's equations, then the drives and limits of
  // that joint while they fit in 6 (a coordinate has at most one of each; the rest stay
  // weighted). An inactive limit's row is zero: then, like padding, it is decoupled.
  node_rows_.assign(tree_cs.size(), {});
  for (size_t k = 0; k < tree_cs.size(); ++k) {
    const ConstraintLayout& L = sys.layout[tree_cs[k]];
    for (int e = 0; e < L.size; ++e) node_rows_[k].push_back({L.row + e, tree_cs[k], e});
  }
  std::vector<char> merged(nc, 0);
  auto attach = [&](int c, int joint) {
    const int node = tree_node_[sys.joint_constraint[joint]];
    if (node < 0) return;
    std::vector<NodeRow>& rows = node_rows_[node - sys.nb];
    const ConstraintLayout& L = sys.layout[c];
    if (static_cast<int>(rows.size()) + L.size > 6) return;
    for (int e = 0; e < L.size; ++e) rows.push_back({L.row + e, c, e});
    merged[c] = 1;
  };
  for (const DriveSpec& D : sys.drives) attach(D.constraint, D.joint);
  for (const LimitSpec& L : sys.limits) attach(L.constraint, L.joint);
  std::vector<signed char> signs(nodes, 1);
  for (int k = sys.nb; k < nodes; ++k) signs[k] = -1;
  std::vector<std::pair<int, int>> edges;
  penalized_.clear();
  for (int ci = 0; ci < nc; ++ci) {
    const ConstraintLayout& L = sys.layout[ci];
    if (tree_node_[ci] >= 0) {
      for (int b : L.bodies)
        if (b >= 0) edges.push_back({tree_node_[ci], b});
      continue;
    }
    if (merged[ci]) continue;  // rows of its joint's block
    penalized_.push_back(ci);
    for (int b1 : L.bodies)
      for (int b2 : L.bodies)
        if (b1 >= 0 && b2 >= 0 && b1 < b2) edges.push_back({b1, b2});
  }
  kkt_.analyze(nodes, edges, order, signs);
  kkt_address_.assign(nc, {});
  kkt_transposed_.assign(nc, {});
  for (int ci = 0; ci < nc; ++ci) {
    const ConstraintLayout& L = sys.layout[ci];
    const int k = static_cast<int>(L.bodies.size());
    bool t = false;
    if (tree_node_[ci] >= 0) {
      for (int s = 0; s < k; ++s) {
        const int a = L.bodies[s] < 0 ? -1 : kkt_.address(tree_node_[ci], L.bodies[s], &t);
        kkt_address_[ci].push_back(a);
        kkt_transposed_[ci].push_back(t);
      }
      kkt_address_[ci].push_back(kkt_.address(tree_node_[ci], tree_node_[ci], &t));
      continue;
    }
    // A drive or limit merged into its joint's block has no blocks of its own: its body
    // pair is coupled through the joint's block row, not directly (a tree has no
    // body-body block). Asking for one failed for every limited joint below a moving body.
    if (merged[ci]) continue;
    kkt_address_[ci].assign(k * k, -1);
    kkt_transposed_[ci].assign(k * k, 0);
    for (int k1 = 0; k1 < k; ++k1)
      for (int k2 = k1; k2 < k; ++k2) {
        if (L.bodies[k1] < 0 || L.bodies[k2] < 0) continue;
        kkt_address_[ci][k1 * k + k2] = kkt_.address(L.bodies[k1], L.bodies[k2], &t);
        kkt_transposed_[ci][k1 * k + k2] = t;
      }
  }
  z_ = Eigen::VectorXd::Zero(6 * nodes);
  kkt_added_.clear();
  for (int ci : penalized_)
    for (size_t k = 0; k < kkt_address_[ci].size(); ++k) {
      const int a = kkt_address_[ci][k];
      if (a >= nodes) kkt_added_.push_back(a);  // off the diagonal (the diagonal is assigned)
    }
  std::sort(kkt_added_.begin(), kkt_added_.end());
  kkt_added_.erase(std::unique(kkt_added_.begin(), kkt_added_.end()), kkt_added_.end());
  for (auto& e : edges)
    if (e.first > e.second) std::swap(e.first, e.second);
  std::sort(edges.begin(), edges.end());
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
  if (kkt_.offDiagonalBlocks() != static_cast<int>(edges.size()))  // (no fill in a tree)
    throw InternalError("the tree KKT factorization has fill");
}

void Stepper::factor(const System& sys, const char* where, double t, bool reweight, bool penalty) {
  ++stats_.factorizations;
  factored_x_ = evaluated_x_;
  factored_side_ = evaluated_side_;
  if (!penalty && kkt_.size() > 0) {
    if (reweight) rowWeights(sys, penalized_);  // the tree's rows have none
    assembleKKT(sys);
    if (kkt_.factorize(0.0, false) == 0) {
      kkt_mode_ = true;
      return;
    }
    // a pivot of the tree is not definite (its joint's equations are dependent at this
    // configuration): this factorization takes every equation in penalty form
    reweight = true;
  }
  if (reweight) rowWeights(sys);
  kkt_mode_ = false;
  assembleH(sys, kKappa, 1.0, 0.0);
  if (chol_.factorize(0.0, false) != 0) {
    std::ostringstream os;
    os << "at t = " << t << " s (" << where
       << "): the constrained mass matrix is singular; some motion moves no mass";
    throw SimulationError(os.str());
  }
}

void Stepper::precondition(const System& sys, const double* r1, const double* r2, bool multipliers) {
  if (!kkt_mode_) {  // H alone: every row weighted
    if (r1 != dn_.data()) std::copy(r1, r1 + sys.n, dn_.data());
    for (int e = 0; e < sys.m; ++e) dm_[e] = kKappa * W_[e] * r2[e];
    addJt(sys, dm_.data(), dn_.data());
    chol_.solve(dn_.data());
    if (!multipliers) return;
    mulJ(sys, dn_.data(), dm_.data());
    for (int e = 0; e < sys.m; ++e) dl_[e] = kKappa * W_[e] * (dm_[e] - r2[e]);
    return;
  }
  // the tree blocks' rows exactly, the others (drives and limits that did not fit) weighted
  const std::vector<int>& pen = penalized_;
  for (int ci : pen) {
    const ConstraintLayout& L = sys.layout[ci];
    for (int e = 0; e < L.size; ++e) dm_[L.row + e] = kKappa * W_[L.row + e] * r2[L.row + e];
  }
  z_.head(sys.n) = Eigen::Map<const Eigen::VectorXd>(r1, sys.n);  // the bodies' rows of z_
  addJt(sys, pen, dm_.data(), z_.data());
  for (size_t k = 0; k < node_rows_.size(); ++k) {
    double* zc = z_.data() + 6 * (sys.nb + k);
    const size_t size = node_rows_[k].size();
    for (size_t r = 0; r < size; ++r) zc[r] = r2[node_rows_[k][r].row];
    for (size_t r = size; r < 6; ++r) zc[r] = 0.0;
  }
  kkt_.solve(z_.data());
  dn_ = z_.head(sys.n);
  if (multipliers)
    for (size_t k = 0; k < node_rows_.size(); ++k)
      for (size_t r = 0; r < node_rows_[k].size(); ++r) dl_[node_rows_[k][r].row] = z_[6 * (sys.nb + k) + r];
  if (!multipliers) return;
  mulJ(sys, pen, dn_.data(), dm_.data());
  for (int ci : pen) {
    const ConstraintLayout& L = sys.layout[ci];
    for (int e = L.row; e < L.row + L.size; ++e) dl_[e] = kKappa * W_[e] * (dm_[e] - r2[e]);
  }
}

// Q per body: [f (global, at the centre of mass); n' (body components)].
void Stepper::forces(const System& sys, const State& s, const Inputs& in,
                     const std::vector<std::array<double, 3>>& friction) {
  for (int b = 1; b <= sys.nb; ++b) {
    const Body& B = sys.bodies[b];
    const BodyKin& k = kin_[b];
    Q_.segment<3>(6 * (b - 1)) = B.m * sys.gravity + in.force[b];
    Q_.segment<3>(6 * (b - 1) + 3) = in.torque[b] - k.w.cross(B.Jp * k.w);  // Euler, in omega'
  }
  auto addForceAt = [&](int b, const Vector3d& sp, const Vector3d& f) {
    if (b == System::kGround) return;
    Q_.segment<3>(6 * (b - 1)) += f;
    Q_.segment<3>(6 * (b - 1) + 3) += sp.cross(kin_[b].A_Oi.transpose() * f);
  };
  for (size_t i = 0; i < sys.springs.size(); ++i) {
    const SpringDamper& sd = sys.springs[i];
    const Gap g = gap(kin_[sd.body_i], sd.sp_i, kin_[sd.body_j], sd.sp_j);
    const double L = g.d.norm();
    if (!(L > 1e-12 * sys.length_scale)) continue;  // direction undefined; no force
    const Vector3d e = g.d / L;
    const double F = sd.k * (L - sd.L0) + sd.c * e.dot(g.d_dot) + sd.f_act + in.spring_actuation[i];
    addForceAt(sd.body_i, sd.sp_i, F * e);
    addForceAt(sd.body_j, sd.sp_j, -F * e);
  }
  Row rows[kMaxJointDofs];
  for (int j = 0; j < sys.numJoints(); ++j) {
    const auto& tau = in.effort[j];
    const auto& c = split_ ? stage_damping_[j] : sys.damping[j];  // (stiff_damping.cpp)
    const auto& fr = friction[j];
    const int dof = sys.joints[j]->dof();
    bool any = false;
    for (int k = 0; k < dof; ++k) any = any || tau[k] != 0.0 || c[k] != 0.0 || fr[k] != 0.0;
    if (!any) continue;
    jointRows(sys, s, j, rows);
    const int bs[2] = {sys.joints[j]->bodyI(), sys.joints[j]->bodyJ()};
    for (int k = 0; k < dof; ++k) {
      const double effort = tau[k] - c[k] * rows[k].Phi_dot + fr[k];  // along q_k
      for (int b = 0; b < 2; ++b)
        if (bs[b] != System::kGround)
          Q_.segment<6>(6 * (bs[b] - 1)) += rows[k].J.segment<6>(6 * b).transpose() * effort;
    }
  }
}

void Stepper::jointRows(const System& sys, const State& s, int j, Row* rows) const {
  const Joint& jt = *sys.joints[j];
  jt.coordinates(kin_[jt.bodyI()], kin_[jt.bodyJ()], s.tracked[jt.id()], rows);
}

// The residual scales of solveKKT: the size of the terms each residual was computed
// from, as inverses: per body, the largest force (torque) term of its three components,
// forces and torques measured against each other through the length scale; per equation, |gamma| + |J_r| |a_r|max +
// |J_theta| |a_theta|max. Both have a floor at kFloor of the system's largest.
void Stepper::residualScales(const System& sys) {
  // accelerations: at least the centripetal scale V^2 / L of the motion
  double V = 0;  // of the loaded state
  for (int b = 1; b <= sys.nb; ++b)
    V = std::max({V, kin_[b].v.cwiseAbs().maxCoeff(), kin_[b].w.cwiseAbs().maxCoeff() * length_scale_});
  mulM(sys, a_.data(), s1_.data());
  for (int i = 0; i < sys.n; ++i) s1_[i] = std::fabs(Q_[i]) + std::fabs(s1_[i]);
  // ... and at least what the loads alone would do (a mechanism at rest against stops has
  // accelerations of round-off size: they are not the scale of its equations)
  double F = 0;  // the largest applied force, torques through the length scale
  for (int i = 0; i < sys.n; i += 6)
    F = std::max({F, Q_.segment<3>(i).cwiseAbs().maxCoeff(), Q_.segment<3>(i + 3).cwiseAbs().maxCoeff() / length_scale_});
  const double a_floor = kFloor * std::max({motionScale(sys, a_), V * V / length_scale_, sys.acceleration_scale,
                                            F / sys.mass_scale});
  for (int e = 0; e < sys.m; ++e) s2_[e] = std::fabs(gamma_[e]);
  bodyScales(sys, a_, a_floor);
  for (int ci = 0; ci < sys.numConstraints(); ++ci) {
    const ConstraintLayout& L = sys.layout[ci];
    const Jacobian& J = J_[ci];
    const Vec6 lam = padded(lam_.data() + L.row, L.size);
    Vec6 jas = Vec6::Zero();
    for (size_t s = 0; s < L.bodies.size(); ++s) {
      if (L.bodies[s] < 0) continue;
      const int col = 6 * L.bodies[s];
      const auto Jb = J.middleCols<6>(6 * s);
      const std::array<double, 2>& as = body_scale_[L.bodies[s]];
      jas += Jb.leftCols<3>().cwiseAbs().rowwise().sum() * as[0] + Jb.rightCols<3>().cwiseAbs().rowwise().sum() * as[1];
      Eigen::Map<Vec6>(s1_.data() + col) += (Jb.transpose() * lam).cwiseAbs();
    }
    for (int e = 0; e < L.size; ++e) s2_[L.row + e] += jas[e];
  }
  double f_floor = 0;  // the largest force in the system (torques through the length scale)
  for (int i = 0; i < sys.n; i += 6)
    f_floor = std::max({f_floor, s1_[i], s1_[i + 1], s1_[i + 2],
                        (s1_[i + 3] + s1_[i + 4] + s1_[i + 5]) / length_scale_});
  f_floor *= kFloor;
  for (int i = 0; i < sys.n; i += 6) {
    const double f = std::max({s1_[i], s1_[i + 1], s1_[i + 2]});
    const double n = std::max({s1_[i + 3], s1_[i + 4], s1_[i + 5]});
    const double fs = std::max({f, n / length_scale_, f_floor});
    const double ns = std::max({n, f * length_scale_, f_floor * length_scale_});
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
bool Stepper::solveKKT(const System& sys, HState hstate, double t, bool rescale) {
  constexpr double kNearbyGain = 0.25;
  const double tol = sys.options.solve_tol;
  double res = 0, previous_res = HUGE_VAL;
  // warm (a, lambda from a nearby solve): their sizes are the solution's to O(h); cold
  // (nothing yet): the scales are taken again after the first update
  const bool cold = (sys.n > 0 && a_.cwiseAbs().maxCoeff() == 0.0) || (sys.m > 0 && lam_.cwiseAbs().maxCoeff() == 0.0);
  if (rescale || cold) residualScales(sys);
  for (int pass = 0;; ++pass) {
    mulM(sys, a_.data(), r1_.data());
    for (int i = 0; i < sys.n; ++i) r1_[i] = Q_[i] - r1_[i];
    for (int ci = 0; ci < sys.numConstraints(); ++ci) {
      const ConstraintLayout& L = sys.layout[ci];
      const Jacobian& J = J_[ci];
      const Vec6 lam = padded(lam_.data() + L.row, L.size);
      Vec6 ja = Vec6::Zero();
      for (size_t s = 0; s < L.bodies.size(); ++s) {
        if (L.bodies[s] < 0) continue;
        const int col = 6 * L.bodies[s];
        const auto Jb = J.middleCols<6>(6 * s);
        ja.noalias() += Jb * Eigen::Map<const Vec6>(a_.data() + col);
        Eigen::Map<Vec6>(r1_.data() + col).noalias() -= Jb.transpose() * lam;
      }
      for (int e = 0; e < L.size; ++e) r2_[L.row + e] = gamma_[L.row + e] - ja[e];
    }
    res = scaledMax(r1_, s1_, r2_, s2_);
    if (cold && pass == 1) {
      residualScales(sys);
      res = scaledMax(r1_, s1_, r2_, s2_);
    }
    if (res <= tol) {
      ++stats_.solves;
      return true;
    }
    if (hstate == HState::kNearby && pass >= 1 && res > kNearbyGain * previous_res) {
      factor(sys, "stage", t, false);
      hstate = HState::kCurrent;
    } else if (pass == kMaxSolvePasses || (pass >= 2 && res > 0.5 * previous_res)) {
      // No progress: what is left is inconsistent (equations that are dependent at this
      // very configuration, e.g. a parallelogram passing flat). Further passes would only
      // push the iterate along the nearly dependent direction: keep the better of the last
      // two iterates (the last pass is undone when it made things worse), count it.
      if (res > previous_res) {
        a_ -= dn_;
        lam_ -= dl_;
        res = previous_res;
      }
      break;
    }
    previous_res = res;
    if (hstate == HState::kNone) factor(sys, "stage 1", t), hstate = HState::kCurrent;
    ++stats_.solve_passes;
    precondition(sys, r1_.data(), r2_.data(), true);
    a_ += dn_;
    lam_ += dl_;
  }
  ++stats_.solves;
  ++stats_.solve_shortfalls;
  stats_.worst_solve = std::max(stats_.worst_solve, res);
  return false;
}

// Least-norm multipliers (stepper.h). With every row in J (the dependent ones too) and H =
// M + kappa J^T W J factored, the iteration
//   r = g - J^T lambda,  lambda += kappa W J H^-1 r,   from lambda = 0,   g = Q - M a,
// keeps lambda in the range of W J, where the solution of J^T lambda = g with the least
// sum lambda_e^2 / W_e lies; in W-scaled coordinates it contracts the error by about
// 1 / (kappa sigma) per pass on that range (sigma as in solveKKT) and leaves the null space
// of J^T (the dependencies) alone, so it converges to the least-norm solution.
double Stepper::minimumNormMultipliers(const System& sys, const State& s, const Inputs& in, Eigen::VectorXd& lambda) {
  State all = s;
  std::fill(all.dropped.begin(), all.dropped.end(), 0);
  load(sys, all.x.data(), all.u.data());
  evaluate(sys, all);
  factor(sys, "reactions", s.t, true, true);  // penalty form: all rows weighted alike
  forces(sys, all, in, all.friction);
  have_eval_ = false;
  // g = Q - M a: the constraint forces (the limits' part taken out: they keep their own)
  mulM(sys, s.acc.data(), dn_.data());
  Eigen::VectorXd g = Q_ - dn_;
  Eigen::VectorXd limit_lambda = Eigen::VectorXd::Zero(sys.m);
  limit_lambda.tail(sys.m - sys.m_eq) = s.lambda.tail(sys.m - sys.m_eq);
  dn_.setZero();
  addJt(sys, limit_lambda.data(), dn_.data());
  g -= dn_;
  double g_scale = 0;  // forces and torques through the length scale
  for (int i = 0; i < sys.n; i += 6)
    g_scale = std::max({g_scale, g.segment<3>(i).cwiseAbs().maxCoeff(), g.segment<3>(i + 3).cwiseAbs().maxCoeff() / length_scale_});
  lambda = Eigen::VectorXd::Zero(sys.m);
  double res = 0;
  for (int pass = 0; pass < kMaxSolvePasses + 8; ++pass) {
    dn_ = g;
    dm_ = -lambda;
    addJt(sys, dm_.data(), dn_.data());  // r = g - J^T lambda
    res = 0;
    for (int i = 0; i < sys.n; i += 6)
      res = std::max({res, dn_.segment<3>(i).cwiseAbs().maxCoeff(), dn_.segment<3>(i + 3).cwiseAbs().maxCoeff() / length_scale_});
    res = g_scale > 0 ? res / g_scale : 0.0;
    if (res <= sys.options.solve_tol * 100) break;
    chol_.solve(dn_.data());
    mulJ(sys, dn_.data(), dm_.data());
    for (int e = 0; e < sys.m_eq; ++e) lambda[e] += kKappa * W_[e] * dm_[e];
  }
  lambda.tail(sys.m - sys.m_eq) = s.lambda.tail(sys.m - sys.m_eq);
  ++stats_.solves;
  if (res > sys.options.solve_tol * 100) {
    ++stats_.solve_shortfalls;
    stats_.worst_solve = std::max(stats_.worst_solve, res);
  }
  return res;
}

// (x, u) -> (x_dot, u_dot): r_dot = v, p_dot = p (x) (0, w) / 2, u_dot = a.
static void positionRates(int nb, const double* x, const double* u, double* xdot) {
  for (int b = 0; b < nb; ++b) {
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

void Stepper::rates(const System& sys, const State& s, const Inputs& in,
                    const std::vector<std::array<double, 3>>& friction, const double* x,
                    const double* u, double* xdot, double* udot, bool reweight) {
  load(sys, x, u);
  evaluate(sys, s);
  // H at the stage's own Jacobian: with kappa = 1e7 even the O(h^2) difference between
  // RK4's two midpoint stages makes refinement on the other's H diverge (measured)
  factor(sys, "stage", s.t, reweight);
  forces(sys, s, in, friction);
  // the residual scales of the step's first solve (stages differ from it by O(h))
  solveKKT(sys, HState::kCurrent, s.t, false);
  positionRates(sys.nb, x, u, xdot);
  std::copy(a_.data(), a_.data() + sys.n, udot);
}

// Friction for the step h about to be taken, from the state with H factored there.
// The effective inertia along coordinate k is I = 1 / (G P G^T), P the constrained inverse
// mass (the factored matrix applied to G^T: exactly on a tree's KKT matrix, up to 1/kappa
// with H); the effort that leaves q_dot = 0 after the step is I (q_dot / h + q_ddot_free)
// with q_ddot_free = G a_free - gamma_G (the coordinate's own velocity term), and friction
// supplies it up to f. A planar joint's two in-plane
// translations are taken together: the effort vector that stops both, from their 2x2
// effective inertia, clamped radially to the friction disc (Coulomb's law in the plane:
// the friction force has one magnitude limit whatever its direction).
void Stepper::frictionFor(const System& sys, State& s, const Inputs& in, double h) {
  for (auto& f : s.friction) f = {0.0, 0.0, 0.0};
  forces(sys, s, in, s.friction);
  a_ = s.acc;
  lam_ = s.lambda;
  solveKKT(sys, HState::kCurrent, s.t);
  Row rows[kMaxJointDofs];
  for (int j = 0; j < sys.numJoints(); ++j) {
    const auto& f = sys.friction[j];
    const Joint& jt = *sys.joints[j];
    const int dof = jt.dof();
    bool has = false;
    for (int k = 0; k < dof; ++k) has = has || f[k] > 0.0;
    if (!has) continue;
    jointRows(sys, s, j, rows);
    const int bs[2] = {jt.bodyI(), jt.bodyJ()};
    // needed_k: the effort along q_k that stops the coordinate within the step, from the
    // coupled effective inertia (G H^-1 G^T)^-1 of the coordinates that have friction
    double needed[3] = {0, 0, 0}, gHg[3][3] = {{0}};
    auto solveRow = [&](int k) {  // dn_ = P G_k^T
      dn_.setZero();
      for (int b = 0; b < 2; ++b)
        if (bs[b] != System::kGround) dn_.segment<6>(6 * (bs[b] - 1)) = rows[k].J.segment<6>(6 * b).transpose();
      precondition(sys, dn_.data(), zero_rows_.data(), false);
    };
    auto dotRow = [&](int k, const Eigen::VectorXd& x) {
      double d = 0;
      for (int b = 0; b < 2; ++b)
        if (bs[b] != System::kGround) d += rows[k].J.segment<6>(6 * b).dot(x.segment<6>(6 * (bs[b] - 1)));
      return d;
    };
    double rate[3] = {0, 0, 0};  // q_dot / h + q_ddot_free (with the coordinate's own gamma)
    for (int k = 0; k < dof; ++k) {
      if (f[k] <= 0.0) continue;
      rate[k] = rows[k].Phi_dot / h - rows[k].gamma + dotRow(k, a_);
      solveRow(k);
      for (int l = 0; l < dof; ++l)
        if (f[l] > 0.0) gHg[l][k] = dotRow(l, dn_);
    }
    const bool disc = jt.planarTranslation() && f[0] > 0.0 && f[1] > 0.0;
    if (disc) {  // the two in-plane translations together: a 2x2 effective inertia
      const double det = gHg[0][0] * gHg[1][1] - gHg[0][1] * gHg[1][0];
      if (det > 0) {
        needed[0] = (gHg[1][1] * rate[0] - gHg[0][1] * rate[1]) / det;
        needed[1] = (-gHg[1][0] * rate[0] + gHg[0][0] * rate[1]) / det;
        // clamp to the ellipse (needed_0 / f_0)^2 + (needed_1 / f_1)^2 <= 1, radially
        const double r = std::hypot(needed[0] / f[0], needed[1] / f[1]);
        const double scale = r > 1.0 ? 1.0 / r : 1.0;
        s.friction[j][0] = -scale * needed[0];
        s.friction[j][1] = -scale * needed[1];
      }
    }
    for (int k = disc ? 2 : 0; k < dof; ++k) {
      if (f[k] <= 0.0 || !(gHg[k][k] > 0)) continue;
      needed[k] = rate[k] / gHg[k][k];
      s.friction[j][k] = -std::max(-f[k], std::min(f[k], needed[k]));
    }
  }
}

void Stepper::step(const System& sys, State& s, const Inputs& in, double h) {
  if (!(h > 0) || !std::isfinite(h)) throw UsageError("step must be positive and finite");
  // A step that fails leaves the State where it was (the last accepted step), not part
  // way through its substeps.
  start_ = s;
  try {
    advance(sys, s, in, h, 0);
  } catch (...) {
    s = start_;
    have_eval_ = false;
    split_ = false;
    throw;
  }
}

// A step whose projection cannot bring the state back onto the constraints is taken
// again as two half steps (at most kMaxHalvings deep); SolverStats counts them.
//
// A body turning more than kMaxTurn rad in one step is beyond what RK4 follows accurately
// (its phase error per step grows like (w h)^5): such a step is taken as halves, and
// past kMaxHalvings the run stops naming the body and the step that would do.
void Stepper::advance(const System& sys, State& s, const Inputs& in, double h, int depth) {
  int fastest = 0;
  double spin = 0;
  for (int b = 0; b < sys.nb; ++b) {
    const double w = s.u.segment<3>(6 * b + 3).norm();
    if (w > spin) spin = w, fastest = b + 1;
  }
  if (spin * h > kMaxTurn) {
    if (depth >= kMaxHalvings) {
      const double asked = h * (1 << depth);
      std::ostringstream os;
      os << "body '" << sys.bodies[fastest].name << "' turns " << fmt(spin * asked) << " rad in one step of "
         << asked << " s (" << (1 << depth) << " substeps still turn " << fmt(spin * h)
         << " rad each); steps of at most " << fmt(kMaxTurn / spin) << " s follow it";
      throw SimulationError(os.str());
    }
    ++stats_.halved_steps;
    advance(sys, s, in, 0.5 * h, depth + 1);
    advance(sys, s, in, 0.5 * h, depth + 1);
    return;
  }
  if (depth > 0) backup_[depth] = s;  // depth 0 starts from start_ (step())
  try {
    stepOnce(sys, s, in, h);
  } catch (const StepFailure&) {
    if (depth >= kMaxHalvings) throw;
    s = depth > 0 ? backup_[depth] : start_;
    ++stats_.halved_steps;
    advance(sys, s, in, 0.5 * h, depth + 1);
    advance(sys, s, in, 0.5 * h, depth + 1);
  }
}

void Stepper::stepOnce(const System& sys, State& s, const Inputs& in, double h) {
  // Stage 1 at the accepted state. Its accelerations and multipliers are in the State (the
  // last step solved them there); the evaluation left by that step is reused when it
  // describes this very state (compared by content). A solve runs, on a fresh
  // factorization, only when the inputs changed, so a restored State continues
  // bit-identically.
  load(sys, s.x.data(), s.u.data());
  const bool reuse = have_eval_ && eval_x_ == s.x && eval_u_ == s.u && eval_side_ == s.limit_side &&
                     eval_t_ == s.t && eval_drive_ == s.drive;
  if (!reuse) evaluate(sys, s);
  // Damped coordinates too stiff for the stages leave them (finishStep integrates them).
  classifyDamping(sys, s, h);
  bool factored = false;
  if (frictionActs(sys)) {
    factor(sys, "stage 1", s.t);
    factored = true;
    frictionFor(sys, s, in, h);
  }
  forces(sys, s, in, s.friction);
  a_ = s.acc;
  lam_ = s.lambda;
  solveKKT(sys, factored ? HState::kCurrent : HState::kNone, s.t);
  have_eval_ = false;  // the stages below overwrite the evaluation
  x0_ = s.x;
  u0_ = s.u;
  positionRates(sys.nb, x0_.data(), u0_.data(), kx_[0].data());
  ku_[0] = a_;
  // Branch references of tracked angles at each stage: predicted from their rates, so
  // an angle may advance by more than pi in one step (a wheel at 4000 rad/s, 1 ms). The
  // rates at this state are those finishStep tracked here when the evaluation is reused.
  tracked0_ = s.tracked;
  if (!reuse) {
    const EvalContext ctx = s.context();
    const BodyKin* ptrs[kMaxConstraintBodies];
    for (int ci = 0; ci < sys.numConstraints(); ++ci) {
      gather(*sys.constraints[ci], ptrs);
      sys.constraints[ci]->trackedRates(ptrs, ctx, tracked_rate_[ci]);
    }
  }
  auto predictTracked = [&](double dt) {
    for (size_t ci = 0; ci < s.tracked.size(); ++ci)
      for (int k = 0; k < 2; ++k) s.tracked[ci][k] = tracked0_[ci][k] + tracked_rate_[ci][k] * dt;
  };
  const double t0 = s.t;
  // y = y0 + (h / den) (sum_j w_j k_j) over the first n rates k (tableau.h: the sum in
  // order of j, zero weights skipped, into sum, preallocated).
  auto combine = [h](const double* w, int n, double den, const Eigen::VectorXd& y0, const Eigen::VectorXd* k,
                     Eigen::VectorXd& sum, Eigen::VectorXd& y) {
    bool first = true;
    for (int j = 0; j < n; ++j) {
      if (w[j] == 0.0) continue;
      if (first) sum = w[j] * k[j];
      else sum += w[j] * k[j];
      first = false;
    }
    y = y0 + (h / den) * sum;
  };
  const Tableau& T = *tableau_;
  for (int k = 1; k < T.stages; ++k) {
    combine(T.a[k], k, T.a_den[k], x0_, kx_, sum_x_, xs_);
    combine(T.a[k], k, T.a_den[k], u0_, ku_, sum_u_, us_);
    const double dt = T.c[k] * h;
    predictTracked(dt);
    s.t = t0 + dt;  // rheonomic equations (drives) are evaluated at the stage's time
    // the row weights only precondition: computed at the first stage, kept for the step
    rates(sys, s, in, s.friction, xs_.data(), us_.data(), kx_[k].data(), ku_[k].data(), k == 1);
  }
  combine(T.b, T.stages, T.b_den, x0_, kx_, sum_x_, s.x);
  combine(T.b, T.stages, T.b_den, u0_, ku_, sum_u_, s.u);
  for (int b = 0; b < sys.nb; ++b) s.x.segment<4>(7 * b + 3).normalize();
  predictTracked(h);  // references near the new angles; finishStep tracks them exactly
  s.t = t0 + h;
  ++s.steps;
  finishStep(sys, s, in, true);
}

void Stepper::settle(const System& sys, State& s, const Inputs& in) {
  for (int b = 0; b < sys.nb; ++b) s.x.segment<4>(7 * b + 3).normalize();
  finishStep(sys, s, in, false);
}

bool Stepper::frictionActs(const System& sys) const {
  for (const auto& f : sys.friction)
    if (f[0] > 0 || f[1] > 0 || f[2] > 0) return true;
  return false;
}

// Brings a new state onto the constraints and solves its accelerations:
//  1. limits that were passed become active (a perfectly inelastic stop);
//  2. H is factored here (the penalty form needs H at the current Jacobian: a stale one
//     would turn kappa |delta J| into error);
//  3. positions: simplified Newton on Phi = 0, mass-orthogonal;
//  4. velocities onto Phi_q v = 0, mass-orthogonal;
//  5. tracked angles move on; accelerations and multipliers are solved at the final state
//     (refined on its own Jacobian) and stored in the State; limits that would pull let go.
void Stepper::finishStep(const System& sys, State& s, const Inputs& in, bool after_stages) {
  load(sys, s.x.data(), s.u.data());
  // 0. stiff joint damping, implicit Euler (stiff_damping.cpp): velocities and positions
  //    move, and H is left factored with the damping in it (refactored below)
  if (after_stages && split_) {
    evaluate(sys, s);
    implicitDamping(sys, s, split_h_);
    load(sys, s.x.data(), s.u.data());
  }
  split_ = false;  // from here on forces() applies all the damping (the state's own)
  // After the stages, H and Phi_q of the last stage are a consistent pair: the Newton
  // steps use them frozen (the correction's direction is off by O(h) in a step of the
  // size of the local error: below RK4's truncation). A limit that just became active
  // is not in them: then full Newton, H refactored each iteration.
  // (H consistent with the evaluation: factored at the same positions)
  const bool consistent = factored_x_ == evaluated_x_ && factored_side_ == evaluated_side_;
  // Where rows can depend on others, a change of the active limits is analyzed
  // (dependencies.h): a limit reached together with another through a loop is dependent.
  const bool limits_changed = updateLimits(sys, s);
  bool frozen = !limits_changed && after_stages && consistent;
  if (limits_changed && watch_dependencies_) {
    refreshDependencies(sys, s);  // (leaves s evaluated)
  } else {
    if (frozen) std::swap(J_, J_frozen_);
    evaluate(sys, s);
  }
  bool moved = projectPositions(sys, s, frozen);
  // A projection that stops one joint on its limit moves the joints around it: in a chain
  // it can carry another joint past its own stop (a three-rod chain swinging onto its
  // stops ended 3.4e-4 rad past one this way). Such limits become active and the
  // positions are projected again, at most once per limit.
  for (size_t pass = 0; pass < sys.limits.size() && updateLimits(sys, s); ++pass) {
    frozen = false;
    if (watch_dependencies_) refreshDependencies(sys, s);
    else evaluate(sys, s);
    moved = projectPositions(sys, s, false) || moved;
  }
  // The rows kept stopped implying the rows dropped: the loop turned in space so that
  // another of its cut joint's rows is the dependent one (a parallelogram gripper on an
  // arm turning it by 90 degrees). Analyzed again here and projected again.
  if (watch_dependencies_ && droppedResidual(sys) > kDependentDrift * sys.options.position_tol &&
      refreshDependencies(sys, s)) {
    frozen = false;
    moved = projectPositions(sys, s, false) || moved;
  }
  if (moved || !frozen) factor(sys, "projection", s.t, !frozen);  // velocities need H at this Phi_q
  const bool sped = projectVelocities(sys, s);
  // Tracked angles move to the new pose. The evaluation above stands when neither
  // projection moved the state: its branch references were predicted within O(h^2) of
  // these (the branch, all an evaluation takes from them, is the same).
  if (moved || sped) load(sys, s.x.data(), s.u.data());
  trackAngles(sys, s, &tracked_rate_);  // (the next step's stage 1 reuses the rates)
  if (moved || sped) evaluate(sys, s);
  for (int pass = 0;; ++pass) {
    forces(sys, s, in, s.friction);
    solveKKT(sys, HState::kNearby, s.t);
    if (pass > static_cast<int>(sys.limits.size()) || !releaseLimits(sys, s)) break;
    if (watch_dependencies_) refreshDependencies(sys, s);
    else evaluate(sys, s);
    factor(sys, "limit release", s.t);
  }
  s.acc = a_;
  s.lambda = lam_;
  eval_x_ = s.x, eval_u_ = s.u, eval_side_ = s.limit_side, eval_t_ = s.t, eval_drive_ = s.drive;
  have_eval_ = true;
}

// Activates a limit whose coordinate has passed its bound; returns whether any did.
bool Stepper::updateLimits(const System& sys, State& s) {
  bool changed = false;
  Row rows[kMaxJointDofs];
  for (size_t l = 0; l < sys.limits.size(); ++l) {
    const LimitSpec& L = sys.limits[l];
    if (s.limit_side[l]) continue;
    jointRows(sys, s, L.joint, rows);
    const double q = rows[L.k].Phi;
    const int side = q < L.lower ? -1 : q > L.upper ? 1 : 0;
    if (!side) continue;
    for (const DriveSpec& D : sys.drives)
      if (D.joint == L.joint && D.k == L.k) {
        std::ostringstream os;
        os << "at t = " << s.t << " s: the drive of joint '" << sys.joints[L.joint]->name()
           << "' moves it to " << fmt(q) << ", past its limits [" << fmt(L.lower) << ", "
           << fmt(L.upper) << "]; change the drive or the limits";
        throw SimulationError(os.str());
      }
    s.limit_side[l] = static_cast<signed char>(side);
    changed = true;
  }
  return changed;
}

// Releases limits whose multiplier would pull; returns whether any did.
bool Stepper::releaseLimits(const System& sys, State& s) {
  bool released = false;
  for (size_t l = 0; l < sys.limits.size(); ++l) {
    if (!s.limit_side[l]) continue;
    const double lam = lam_[sys.layout[sys.limits[l].constraint].row];
    if ((s.limit_side[l] < 0 && lam > 0) || (s.limit_side[l] > 0 && lam < 0)) {
      s.limit_side[l] = 0;
      released = true;
    }
  }
  return released;
}

// max_e |Phi_e| / (size of its terms): each row's terms are its Jacobian entries times the
// coordinates they multiply (|J_r| |r| for positions, |J_theta| for rotations).
double Stepper::rowScale(const Constraint& c, const Eigen::Ref<const Eigen::MatrixXd>& J, int e) const {
  double scale = 0;
  for (size_t k = 0; k < c.bodies().size(); ++k)
    scale += termScale(J.block<1, 6>(e, 6 * k), kin_[c.bodies()[k]].r, length_scale_)(0);
  return scale;
}

double Stepper::rowWeight(const System& sys, int constraint, const Eigen::Ref<const Eigen::MatrixXd>& row) const {
  const ConstraintLayout& L = sys.layout[constraint];
  double s = 0;
  for (size_t k = 0; k < L.bodies.size(); ++k)
    if (L.bodies[k] >= 0) s += inverseMassTerms(row.block<1, 6>(0, 6 * k), Minv_[L.bodies[k]])(0);
  return weightOf(s);
}

double Stepper::positionResidual(const System& sys) const {
  // per constraint, all rows at once: row e's scale is rowScale(c, J, e)
  double worst = 0;
  for (int ci = 0; ci < sys.numConstraints(); ++ci) {
    const ConstraintLayout& L = sys.layout[ci];
    const Jacobian& J = J_[ci];
    Vec6 scale = Vec6::Zero();
    for (size_t k = 0; k < L.bodies.size(); ++k)  // (kin_[0] is the ground's: r = 0)
      scale += termScale(J.middleCols<6>(6 * k), kin_[L.bodies[k] + 1].r, length_scale_);
    for (int e = 0; e < L.size; ++e)
      if (dropped_.empty() || !dropped_[L.row + e]) worst = std::max(worst, relative(Phi_[L.row + e], scale[e]));
  }
  return worst;
}

double Stepper::droppedResidual(const System& sys) const {
  double worst = 0;
  for (int e = 0; e < sys.m_eq; ++e)
    if (dropped_[e]) worst = std::max(worst, relative(Phi_[e], dropped_scale_[e]));
  return worst;
}

// max_e |(Phi_q v)_e| / (size of its terms): |J_r| |v|_max + |J_theta| |w'|_max per body.
double Stepper::velocityResidual(const System& sys, const Eigen::VectorXd& u) const {
  const double floor = kFloor * std::max(motionScale(sys, u), sys.velocity_scale);
  bodyScales(sys, u, floor);
  return velocityResidualAtScales(sys, u, body_scale_);
}

// As velocityResidual, against given body scales (bodyScales()).
double Stepper::velocityResidualAtScales(const System& sys, const Eigen::VectorXd& u,
                                         const std::vector<std::array<double, 2>>& scales) const {
  double worst = 0;
  for (int ci = 0; ci < sys.numConstraints(); ++ci) {
    const ConstraintLayout& L = sys.layout[ci];
    const Jacobian& J = J_[ci];
    Vec6 value = -padded(nu_.data() + L.row, L.size);
    Vec6 scale = value.cwiseAbs();
    for (size_t k = 0; k < L.bodies.size(); ++k) {
      if (L.bodies[k] < 0) continue;
      const auto Jb = J.middleCols<6>(6 * k);
      const std::array<double, 2>& bs = scales[L.bodies[k]];
      value.noalias() += Jb * u.segment<6>(6 * L.bodies[k]);
      scale += Jb.leftCols<3>().cwiseAbs().rowwise().sum() * bs[0] + Jb.rightCols<3>().cwiseAbs().rowwise().sum() * bs[1];
    }
    for (int e = 0; e < L.size; ++e)
      if (dropped_.empty() || !dropped_[L.row + e]) worst = std::max(worst, relative(value[e], scale[e]));
  }
  return worst;
}

void Stepper::bodyScales(const System& sys, const Eigen::VectorXd& u, double floor) const {
  for (int b = 0; b < sys.nb; ++b) {
    const double v0 = u.segment<3>(6 * b).cwiseAbs().maxCoeff(), w0 = u.segment<3>(6 * b + 3).cwiseAbs().maxCoeff();
    body_scale_[b] = {std::max({v0, w0 * length_scale_, floor}), std::max({w0, v0 / length_scale_, floor / length_scale_})};
  }
}

// max over bodies of max(|v|, |w'| L) (or of accelerations): the system's motion scale.
double Stepper::motionScale(const System& sys, const Eigen::VectorXd& u) const {
  double V = 0;
  for (int b = 0; b < sys.nb; ++b)
    V = std::max({V, u.segment<3>(6 * b).cwiseAbs().maxCoeff(),
                  u.segment<3>(6 * b + 3).cwiseAbs().maxCoeff() * length_scale_});
  return V;
}

double Stepper::positionViolation() const { return Phi_.size() ? Phi_.cwiseAbs().maxCoeff() : 0.0; }

double Stepper::velocityViolation(const System& sys, const Eigen::VectorXd& u) const {
  mulJ(sys, u.data(), query_.data());
  query_ -= nu_;
  return query_.size() ? query_.cwiseAbs().maxCoeff() : 0.0;
}

// r += dr, p <- p (x) exp(dtheta'/2): a displacement in variation coordinates.
void displace(const System& sys, Eigen::VectorXd& x, const double* dq) {
  for (int b = 0; b < sys.nb; ++b) {
    double* xb = x.data() + 7 * b;
    const double* d = dq + 6 * b;
    xb[0] += d[0], xb[1] += d[1], xb[2] += d[2];
    Quaterniond p(xb[3], xb[4], xb[5], xb[6]);
    p = (p * expRotation(Vector3d(d[3], d[4], d[5]))).normalized();
    xb[3] = p.w(), xb[4] = p.x(), xb[5] = p.y(), xb[6] = p.z();
  }
}

// The constraint with the largest |r| over its rows (r per equation), and that value.
static int worstConstraint(const System& sys, const Eigen::VectorXd& r, double* value) {
  int worst = 0;
  *value = -1.0;
  for (int ci = 0; ci < sys.numConstraints(); ++ci) {
    const ConstraintLayout& L = sys.layout[ci];
    const double e = L.size ? r.segment(L.row, L.size).cwiseAbs().maxCoeff() : 0.0;
    if (e > *value) *value = e, worst = ci;
  }
  return worst;
}

[[noreturn]] void Stepper::leftConstraints(const System& sys, double t, double err) const {
  double worst_err = 0;
  const int worst = worstConstraint(sys, Phi_, &worst_err);
  std::ostringstream os;
  os << "the step left the constraints (relative residual " << fmt(err) << ", largest at '"
     << sys.constraints[worst]->name() << "': " << fmt(worst_err) << ", reached at t = " << t
     << " s); try a smaller step";
  throw StepFailure(os.str());
}

// Mass-orthogonal projection of positions, simplified Newton: dq from the factored
// matrix applied to r2 = -Phi (precondition(): on H, dq = -H^-1 Phi_q^T W Phi, the
// least-squares step, dependent equations included; on the tree KKT matrix the
// mass-orthogonal step onto the tree's equations), renewing the factorization when
// progress is slow.
bool Stepper::projectPositions(const System& sys, State& s, bool frozen) {
  const double tol = sys.options.position_tol;
  double err = positionResidual(sys), previous = HUGE_VAL;
  int it = 0;
  for (; err > tol && it < kMaxNewton; ++it) {
    if (!frozen || (it > 1 && err > 0.1 * previous)) {  // full Newton
      factor(sys, "position projection", s.t);
      frozen = false;
    }
    previous = err;
    r2_ = -Phi_;
    r1_.setZero();
    if (frozen) std::swap(J_, J_frozen_);
    precondition(sys, r1_.data(), r2_.data(), false);
    if (frozen) std::swap(J_, J_frozen_);
    displace(sys, s.x, dn_.data());
    load(sys, s.x.data(), s.u.data());
    evaluate(sys, s);
    err = positionResidual(sys);
  }
  ++stats_.position_projections;
  if (err > tol) {
    ++stats_.position_shortfalls;
    stats_.worst_position = std::max(stats_.worst_position, err);
    if (err > kFailureResidual) leftConstraints(sys, s.t, err);
  }
  return it > 0;
}

// Mass-orthogonal projection of velocities onto Phi_q v = nu: dv from the factored matrix
// applied to r2 = nu - Phi_q v (on H: dv = H^-1 Phi_q^T W r2), repeated until the relative
// residual meets velocity_tol. A pass that gains less than a factor 2 ends it (as in
// solveKKT): what is left lies along equations that are nearly dependent at this
// configuration (a parallelogram passing flat), where each further pass moves the
// velocities by about residual / sigma_min^2 along the dependent direction and gains
// little (measured: 8 passes of 0.98 each moved them by 1.2e-7 m/s to gain 10%). A pass
// that made it worse is undone; the residual left is counted. The gain is measured against
// the scales of the velocities the projection started from: the residual relative to the
// current velocities does not fall when the projection stops most of the motion (a limit
// that just engaged: relative 1 before and after a pass that cut the velocity into it by
// a factor 270).
bool Stepper::projectVelocities(const System& sys, State& s) {
  const double tol = sys.options.velocity_tol;
  double err = velocityResidual(sys, s.u);
  const bool moves = err > tol;
  double gauge = err;  // the residual against the starting scales
  if (moves) start_scale_ = body_scale_;
  for (int it = 0; err > tol && it < kMaxVelocityPasses; ++it) {
    mulJ(sys, s.u.data(), r2_.data());
    r2_ = nu_ - r2_;
    r1_.setZero();
    precondition(sys, r1_.data(), r2_.data(), false);
    s.u += dn_;
    err = velocityResidual(sys, s.u);
    if (err <= tol) break;
    const double previous = gauge;
    gauge = velocityResidualAtScales(sys, s.u, start_scale_);
    if (gauge > previous) {
      s.u -= dn_;
      err = velocityResidual(sys, s.u);
      break;
    }
    if (gauge > 0.5 * previous) break;
  }
  ++stats_.velocity_projections;
  if (err <= tol) return moves;
  ++stats_.velocity_shortfalls;
  stats_.worst_velocity = std::max(stats_.worst_velocity, err);
  if (err > kFailureResidual) {
    // as for positions: the step cannot be repaired (it is retaken in halves, then the run
    // stops) rather than going on with the velocity constraints visibly broken
    mulJ(sys, s.u.data(), query_.data());
    query_ -= nu_;
    double worst_v = 0;
    const int worst = worstConstraint(sys, query_, &worst_v);
    std::ostringstream os;
    os << "the velocities cannot be brought onto the constraints (relative residual " << fmt(err)
       << ", largest at '" << sys.constraints[worst]->name() << "': " << fmt(worst_v) << ", reached at t = " << s.t
       << " s); the mechanism may be near a singular or locking configuration (joint axes almost but not "
          "exactly aligned?) or too badly scaled for double precision (parts of very different sizes)";
    throw StepFailure(os.str());
  }
  return moves;
}

}  // namespace mechanism_sim
