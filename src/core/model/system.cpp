// System: validation and layout, done once.
#include "mechanism_sim/core/model/system.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>
#include <sstream>

#include <Eigen/Eigenvalues>

#include "mechanism_sim/core/model/couplers.h"
#include "mechanism_sim/core/model/coupling.h"
#include "mechanism_sim/core/model/errors.h"
#include "mechanism_sim/core/model/primitives.h"
#include "core/absolute/evaluation.h"
#include "core/numerics.h"
#include "mechanism_sim/core/model/tableau.h"

namespace mechanism_sim {
namespace {

// extent: the body's own size, the largest distance from its reference point (its centre
// of mass) to the joint frames and spring ends on it. Its moments are judged against
// max(|Jp|, m extent^2), the inertia it turns with about its joints: round-off in the
// moments of a point mass held away from its joint (-5e-20 kg m^2 from a parallel-axis sum)
// is not a fault.
void validateBody(const Body& b, double extent) {
  const std::string who = "body '" + b.name + "': ";
  if (!std::isfinite(b.m) || b.m < 0) throw ModelError(who + "mass must be finite and >= 0");
  if (!b.Jp.allFinite()) throw ModelError(who + "inertia must be finite");
  const double scale = std::max(1e-300, b.Jp.cwiseAbs().maxCoeff());
  if ((b.Jp - b.Jp.transpose()).cwiseAbs().maxCoeff() > 1e-9 * scale)
    throw ModelError(who + "inertia must be symmetric");
  const Eigen::Vector3d ev = Eigen::SelfAdjointEigenSolver<Matrix3d>(b.Jp).eigenvalues();
  const double tol = 1e-9 * std::max(scale, b.m * extent * extent);
  if (ev.minCoeff() < -tol) throw ModelError(who + "inertia has a negative principal moment");
  if (ev(2) > ev(0) + ev(1) + tol)
    throw ModelError(who + "inertia violates the triangle inequality (largest principal "
                     "moment exceeds the sum of the other two)");
  if (!b.r.allFinite() || !b.p.coeffs().allFinite() || b.p.norm() < 1e-9 || !b.v.allFinite() ||
      !b.w.allFinite())
    throw ModelError(who + "initial state must be finite with a non-zero orientation");
}

}  // namespace

Formulation parseFormulation(const std::string& name) {
  for (Formulation f : {Formulation::kAuto, Formulation::kJoint, Formulation::kAbsolute})
    if (name == formulationName(f)) return f;
  throw ModelError("unknown formulation '" + name + "' (known: auto, joint, absolute)");
}

const char* formulationName(Formulation f) {
  switch (f) {
    case Formulation::kJoint: return "joint";
    case Formulation::kAbsolute: return "absolute";
    default: return "auto";
  }
}

void IntegratorOptions::validate() const {
  parseMethod(method);
  parseFormulation(formulation);
  if (!(position_tol > 0) || !(velocity_tol > 0) || !(solve_tol > 0))
    throw ModelError("integrator tolerances must be positive");
}

void System::finalize() {
  nb = numBodies() - 1;
  if (nb < 1) throw ModelError("the mechanism has no moving body");
  std::vector<double> extent(numBodies(), 0.0);
  auto reach = [&](int b, const Vector3d& sp) {
    if (b >= 0 && b < numBodies()) extent[b] = std::max(extent[b], sp.norm());
  };
  for (const Joint* j : joints) reach(j->bodyI(), j->frameI().sp_B), reach(j->bodyJ(), j->frameJ().sp_B);
  for (const SpringDamper& s : springs) reach(s.body_i, s.sp_i), reach(s.body_j, s.sp_j);
  for (int b = 1; b <= nb; ++b) validateBody(bodies[b], extent[b]);
  if (!gravity.allFinite()) throw ModelError("gravity must be finite");
  options.validate();
  validateRotors(*this);
  for (const SumFriction& F : sum_friction) {
    if (F.terms.empty() || F.terms.size() > static_cast<size_t>(kMaxCoordinateEfforts))
      throw ModelError("friction '" + F.name + "': on 1 to " + std::to_string(kMaxCoordinateEfforts) + " coordinates");
    if (!(F.f >= 0.0) || !std::isfinite(F.f)) throw ModelError("friction '" + F.name + "': its bound must be finite and >= 0");
    LimitSpec as_limit;  // (the same terms as a limit's: joints' coordinates, coefficients)
    as_limit.joint = F.terms[0].joint, as_limit.k = F.terms[0].k, as_limit.terms = F.terms;
    try {
      validateLimit(*this, as_limit);
    } catch (const ModelError& e) {
      throw ModelError("friction '" + F.name + "': " + e.what());
    }
  }

  // Drives become constraints after joints and couplers, limits after all others (free
  // until reached).
  constraints.erase(std::remove_if(constraints.begin(), constraints.end(),
                                   [](const std::shared_ptr<Constraint>& c) {
                                     return c->limit() >= 0 || c->drive() >= 0;
                                   }),
                    constraints.end());
  for (size_t d = 0; d < drives.size(); ++d) {
    DriveSpec& D = drives[d];
    if (D.joint < 0 || D.joint >= numJoints() || D.k < 0 || D.k >= joints[D.joint]->dof())
      throw ModelError("drive " + std::to_string(d) + ": no such joint coordinate");
    const Joint& j = *joints[D.joint];
    if (!j.holonomicCoordinates())
      throw ModelError("joint '" + j.name() + "': a drive needs a position coordinate (this joint's rates are not the derivatives of its coordinates)");
    for (size_t e = 0; e < d; ++e)
      if (drives[e].joint == D.joint && drives[e].k == D.k)
        throw ModelError("joint '" + j.name() + "': the coordinate is already driven");
    if (!std::isfinite(D.q0)) throw ModelError("joint '" + j.name() + "': drive start position not finite");
    D.constraint = numConstraints();
    constraints.push_back(std::make_shared<DriveConstraint>(j, D.k, static_cast<int>(d), D.profile));
  }
  m_eq = 0;
  for (const auto& c : constraints) m_eq += c->size();
  for (size_t l = 0; l < limits.size(); ++l) {
    LimitSpec& L = limits[l];
    validateLimit(*this, L);
    L.constraint = numConstraints();
    if (L.terms.empty()) L.terms = {{L.joint, L.k, 1.0}};
    std::vector<CouplingTerm> terms;
    for (const LimitTerm& t : L.terms) terms.push_back({joints[t.joint], t.k, t.c});
    constraints.push_back(std::make_shared<LimitConstraint>(L.name.empty() ? joints[L.joint]->name() + " limit" : L.name,
                                                            std::move(terms), static_cast<int>(l), L.lower, L.upper));
  }
  rheonomic.clear();
  for (int c = 0; c < numConstraints(); ++c) {
    constraints[c]->setId(c);
    if (constraints[c]->rheonomic()) rheonomic.push_back(c);
    if (static_cast<int>(constraints[c]->bodies().size()) > kMaxConstraintBodies)
      throw ModelError("constraint '" + constraints[c]->name() + "' couples more than " +
                       std::to_string(kMaxConstraintBodies) + " bodies");
  }
  n = 6 * nb;

  layout.assign(constraints.size(), ConstraintLayout());
  int row = 0;
  for (size_t ci = 0; ci < constraints.size(); ++ci) {
    const Constraint& c = *constraints[ci];
    ConstraintLayout& L = layout[ci];
    L.row = row;
    L.size = c.size();
    row += L.size;
    L.bodies.clear();
    for (int b : c.bodies()) L.bodies.push_back(b - 1);
  }
  m = row;
  all_constraints.resize(constraints.size());
  for (int ci = 0; ci < numConstraints(); ++ci) all_constraints[ci] = ci;

  // Scales of the problem.
  // A body has moments when its mean moment passes 1e-9 of the largest: a point mass's
  // round-off (-5e-20 kg m^2 from a parallel-axis sum) is none, not a moment whose inverse
  // (1e18) would swamp the weights of the equations on it.
  double largest_moment = 0;
  for (int b = 1; b <= nb; ++b) largest_moment = std::max(largest_moment, bodies[b].Jp.trace() / 3.0);
  auto hasMoments = [&](const Body& B) { return B.Jp.trace() / 3.0 > 1e-9 * largest_moment; };
  double msum = 0, isum = 0;
  int mcount = 0, icount = 0;
  for (int b = 1; b <= nb; ++b) {
    if (bodies[b].m > 0) msum += bodies[b].m, ++mcount;
    if (hasMoments(bodies[b])) isum += bodies[b].Jp.trace() / 3.0, ++icount;
  }
  double L = 0;
  for (const Joint* j : joints) L = std::max({L, j->frameI().sp_B.norm(), j->frameJ().sp_B.norm()});
  for (const SpringDamper& s : springs) L = std::max({L, s.sp_i.norm(), s.sp_j.norm(), s.L0});
  // the extent of the bodies' initial positions (translation-invariant)
  Vector3d lo = bodies[1].r, hi = bodies[1].r;
  for (int b = 1; b <= nb; ++b) lo = lo.cwiseMin(bodies[b].r), hi = hi.cwiseMax(bodies[b].r);
  L = std::max(L, (hi - lo).norm());
  length_scale = L > 0 ? L : 1.0;
  mass_scale = mcount ? msum / mcount : 1.0;
  updateLoadScales();
  inertia_scale = icount ? isum / icount : mass_scale * length_scale * length_scale;
  damping.resize(joints.size(), {0, 0, 0});
  friction.resize(joints.size(), {0, 0, 0});
  // Inverse masses with stand-ins: a massless body weighs the mean mass, a body without
  // moments (hasMoments) the mean moment, and every moment is raised by 1e-3 of the body's mean
  // moment, so a zero principal moment (a thin rod's) does not make the weights of the
  // equations that hold that rotation vanish. They only scale W (the refinement solves the
  // exact KKT system); a much smaller raise leaves a body with a zero moment (a 7 kg ram
  // with ixx = 0, test FuzzFindings.ZeroPrincipalMoment...) weighting its rows so unevenly
  // that nearly every solve falls short.
  Minv.assign(nb, Eigen::Matrix<double, 6, 6>::Zero());
  for (int b = 1; b <= nb; ++b) {
    const Body& B = bodies[b];
    const double m = B.m > 0 ? B.m : mass_scale;
    const Matrix3d Jp = hasMoments(B) ? Matrix3d(B.Jp + 1e-3 * B.Jp.trace() / 3.0 * Matrix3d::Identity())
                                      : Matrix3d(inertia_scale * Matrix3d::Identity());
    Minv[b - 1].topLeftCorner<3, 3>() = Matrix3d::Identity() / m;
    Minv[b - 1].bottomRightCorner<3, 3>() = Jp.inverse();
  }
}

void System::updateLoadScales() {
  acceleration_scale = gravity.norm();
  for (const SpringDamper& s : springs)
    acceleration_scale = std::max(acceleration_scale, (s.k * std::max(s.L0, length_scale) + std::fabs(s.f_act)) / mass_scale);
  velocity_scale = std::sqrt(acceleration_scale * length_scale);
}

State initialState(const System& sys) {
  State s;
  s.x = Eigen::VectorXd::Zero(BodyCoordinates::positions(sys));
  s.u = Eigen::VectorXd::Zero(sys.n);
  for (int b = 1; b <= sys.nb; ++b) {
    const Body& B = sys.bodies[b];
    s.x.segment<3>(BodyCoordinates::x(b - 1)) = B.r;
    const Quaterniond p = B.p.normalized();
    s.x.segment<4>(BodyCoordinates::x(b - 1) + 3) << p.w(), p.x(), p.y(), p.z();
    s.u.segment<3>(BodyCoordinates::u(b - 1)) = B.v;
    s.u.segment<3>(BodyCoordinates::u(b - 1) + 3) = B.w;
  }
  for (const auto& c : sys.constraints) s.tracked.push_back(c->initialTracked());
  s.limit_side.assign(sys.limits.size(), 0);
  s.dropped.assign(sys.m, 0);
  s.lambda = Eigen::VectorXd::Zero(sys.m);
  s.acc = Eigen::VectorXd::Zero(sys.n);
  s.friction.assign(sys.joints.size(), {0, 0, 0});
  s.sum_friction.assign(sys.sum_friction.size(), 0.0);
  for (const DriveSpec& D : sys.drives) {
    const double v = D.profile.kind() == DriveProfile::Kind::kVelocity ? D.profile.velocity() : 0.0;
    s.drive.push_back(DriveRamp{0.0, D.q0, v, v, 0.0});
  }
  return s;
}

Inputs zeroInputs(const System& sys) {
  Inputs in;
  in.effort.assign(sys.joints.size(), {0, 0, 0});
  in.force.assign(sys.bodies.size(), Vector3d::Zero());
  in.torque.assign(sys.bodies.size(), Vector3d::Zero());
  in.spring_actuation.assign(sys.springs.size(), 0.0);
  return in;
}

int limitSide(const LimitSpec& L, double q) {
  const double slack = 8 * std::numeric_limits<double>::epsilon() * std::max(std::fabs(L.lower), std::fabs(L.upper));
  return q < L.lower - slack ? -1 : q > L.upper + slack ? 1 : 0;
}

void validateLimit(const System& sys, const LimitSpec& L) {
  const std::vector<LimitTerm> terms = L.terms.empty() ? std::vector<LimitTerm>{{L.joint, L.k, 1.0}} : L.terms;
  if (terms[0].joint != L.joint || terms[0].k != L.k)
    throw ModelError(limitSubject(sys, L) + ": a limit's (joint, k) is its first term's");
  for (size_t i = 0; i < terms.size(); ++i) {
    const LimitTerm& t = terms[i];
    if (t.joint < 0 || t.joint >= sys.numJoints())
      throw ModelError("limit on joint " + std::to_string(t.joint) + ": no such joint");
    const Joint& j = *sys.joints[t.joint];
    if (t.k < 0 || t.k >= j.dof())
      throw ModelError("joint '" + j.name() + "': a limit on coordinate " + std::to_string(t.k) + ", which it does not have");
    if (!j.holonomicCoordinates()) throw ModelError("joint '" + j.name() + "': limits need a position coordinate");
    if (!std::isfinite(t.c) || t.c == 0.0)
      throw ModelError(limitSubject(sys, L) + ": the limit's coefficient of joint '" + j.name() + "' must be finite and non-zero");
    for (size_t e = 0; e < i; ++e)
      if (terms[e].joint == t.joint && terms[e].k == t.k)
        throw ModelError(limitSubject(sys, L) + ": joint '" + j.name() + "' appears twice in one limit");
  }
  if (!(L.lower <= L.upper) || !std::isfinite(L.lower) || !std::isfinite(L.upper))
    throw ModelError(limitSubject(sys, L) + ": limits need finite lower <= upper");
}

std::string limitSubject(const System& sys, const LimitSpec& L) {
  if (!L.name.empty()) return "coupling '" + L.name + "'";
  return L.joint >= 0 && L.joint < sys.numJoints() ? "joint '" + sys.joints[L.joint]->name() + "'"
                                                    : "limit on joint " + std::to_string(L.joint);
}

double limitSlack(const System& sys, const LimitSpec& L) {
  return numerics::kLimitSlack * (std::fabs(L.lower) + std::fabs(L.upper) + sys.length_scale);
}

bool drivenAtLimit(const System& sys, const LimitSpec& L, double q, double t) {
  // (no copy of the terms: a step allocates nothing)
  auto driven = [&](int joint, int k) {
    for (const DriveSpec& D : sys.drives)
      if (D.joint == joint && D.k == k) return true;
    return false;
  };
  if (L.terms.empty() && !driven(L.joint, L.k)) return false;
  for (const LimitTerm& term : L.terms)
    if (!driven(term.joint, term.k)) return false;  // a coordinate free to stop
  const size_t n = std::max<size_t>(1, L.terms.size());
  // within the assembly's slack of the bound (a gripper's finger held at its stop, off by
  // round-off): the drive holds it there, no limit to activate
  const double slack = limitSlack(sys, L);
  if (q >= L.lower - slack && q <= L.upper + slack) return true;
  std::ostringstream os;
  os << "at t = " << t << " s: the drive" << (n > 1 ? "s of " : " of ") << limitSubject(sys, L)
     << " move" << (n > 1 ? " its sum" : "s it") << " to " << fmt(q) << ", past its limits ["
     << fmt(L.lower) << ", " << fmt(L.upper) << "]; change the drive or the limits";
  throw SimulationError(os.str());
}

Vector3d SpringDamper::forceOnI(const BodyKin& ki, const BodyKin& kj, double actuation, double length_scale) const {
  const Gap g = gap(ki, sp_i, kj, sp_j);
  const double L = g.d.norm();
  if (!(L > 1e-12 * length_scale)) return Vector3d::Zero();
  const Vector3d e = g.d / L;
  return (k * (L - L0) + c * e.dot(g.d_dot) + f_act + actuation) * e;
}

}  // namespace mechanism_sim
