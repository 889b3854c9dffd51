// A constraint is a set of scalar equations Phi(q) = 0 over a few bodies.
#pragma once
#include <array>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "mechanism_sim/core/model/primitives.h"

namespace mechanism_sim {

// A constraint couples at most this many bodies (a coupler: the bodies of two joints; a
// coupling: those of up to kMaxCouplingTerms joints). The steppers keep this many pointers
// on the stack per evaluation, so a model without couplings pays nothing for it.
constexpr int kMaxConstraintBodies = 16;
// A constraint on joint coordinates names at most this many (coordinateEfforts).
constexpr int kMaxCoordinateEfforts = 8;
constexpr int kMaxCouplingTerms = kMaxCoordinateEfforts;

// Angles a constraint tracks through turns (the branch references): part of the State.
using Tracked = std::array<double, 2>;

struct DriveRamp;  // drive.h
class Joint;       // joint.h

// An effort along coordinate k of a joint that a constraint's multiplier lambda stands for:
// tau = sign * lambda (Constraint::coordinateEfforts).
struct CoordinateEffort {
  const Joint* joint = nullptr;
  int k = 0;
  double sign = 0.0;
};

// What constraints read besides the bodies: the State's tracked angles (indexed by
// constraint id), the sides of the position limits (indexed by limit id), the time and
// the velocity drives' references (indexed by drive id), for rheonomic equations.
// rates false: Phi and its Jacobian are asked for alone (the queries' evaluation,
// Mechanism::evaluated): a joint then leaves the rates out of its geometry (kNoRates), which
// gives Phi and J every bit they have with them; gamma has no meaning then.
struct EvalContext {
  const Tracked* tracked = nullptr;
  const signed char* limit_side = nullptr;
  double t = 0.0;
  const DriveRamp* drive = nullptr;
  bool rates = true;
};

class Constraint {
 public:
  Constraint(std::string name, std::vector<int> bodies)
      : name_(std::move(name)), bodies_(std::move(bodies)) {}
  virtual ~Constraint() = default;

  const std::string& name() const { return name_; }
  // Bodies the equations involve (0 is ground); kin[k] below is the state of bodies()[k].
  const std::vector<int>& bodies() const { return bodies_; }
  virtual std::string type() const = 0;
  // Number of scalar equations, all independent in every pose.
  virtual int size() const = 0;
  // Phi (size), Jacobian J (size x 6*bodies().size(), columns [r, theta'] per body)
  // and gamma (size) with J a = gamma for every admissible acceleration a.
  virtual void evaluate(const BodyKin* const* kin, const EvalContext& ctx,
                        Eigen::Ref<Eigen::VectorXd> Phi, Eigen::Ref<Eigen::MatrixXd> J,
                        Eigen::Ref<Eigen::VectorXd> gamma) const = 0;
  // The tracked angles of an accepted state, moved from those of the state before
  // (angle trackers count turns here), and their rates there (as trackedRates()).
  // Stateless: the angles live in the State.
  virtual void track(const BodyKin* const* /*kin*/, const EvalContext& /*ctx*/, Tracked& /*t*/, Tracked& rate) const {
    rate = Tracked{};
  }
  // track()'s angles alone (the same bits), where their rates are not wanted: the joint
  // stepper's cut joints after a step. A joint computes the angles without the rates.
  virtual void trackAngles(const BodyKin* const* kin, const EvalContext& ctx, Tracked& t) const {
    Tracked rate;
    track(kin, ctx, t, rate);
  }
  // Rates of the tracked angles at (kin): a step predicts its stages' branch references
  // from them, so a joint may turn more than pi in one step.
  virtual void trackedRates(const BodyKin* const* /*kin*/, const EvalContext& /*ctx*/, Tracked& rate) const {
    rate = Tracked{};
  }
  // Rheonomic equations Phi(q, t) = 0 (drives) have a velocity equation Phi_q v = nu with
  // nu = -Phi_t; velocityTerm writes nu (size()). Scleronomic ones: nu = 0.
  virtual bool rheonomic() const { return false; }
  virtual void velocityTerm(const EvalContext& /*ctx*/, double* nu) const {
    for (int e = 0; e < size(); ++e) nu[e] = 0.0;
  }
  // The joint whose body j is body b (a body of this constraint): its reaction's torque on
  // b is taken about that joint's point B_j; nullptr: about b's centre of mass.
  virtual const Joint* jointOn(int /*b*/) const { return nullptr; }
  // Constraints on joint coordinates: the efforts along those coordinates their multiplier
  // stands for (at most kMaxCoordinateEfforts, written to out; their number is returned),
  // with the sides of the limits in ctx. Other constraints: none.
  virtual int coordinateEfforts(const EvalContext& /*ctx*/, CoordinateEffort* /*out*/) const { return 0; }
  // Constraints System::finalize makes from its drive and limit lists (so each build
  // lays them out again): their entry there, or -1.
  virtual int drive() const { return -1; }
  virtual int limit() const { return -1; }
  // Tracked angles of the pose the constraint was defined in.
  virtual Tracked initialTracked() const { return Tracked{}; }
  // Position in its System's constraint list: where its tracked angles are in the State.
  int id() const { return id_; }
  void setId(int id) { id_ = id; }

 private:
  std::string name_;
  std::vector<int> bodies_;
  int id_ = 0;
};

// Writes Rows into the outputs of Constraint::evaluate, for two-body constraints.
class RowWriter {
 public:
  // wanted: a bit per row (bit e: row e), the rows the caller reads; a helper that writes
  // several rows may skip computing them when none is wanted (wants(), skip()).
  // compact: only the wanted rows are written, in their order, into the outputs' first
  // rows (rows past the 32nd are not wanted then).
  RowWriter(Eigen::Ref<Eigen::VectorXd> Phi, Eigen::Ref<Eigen::MatrixXd> J,
            Eigen::Ref<Eigen::VectorXd> gamma, unsigned wanted = ~0u, bool compact = false)
      : Phi_(Phi), J_(J), gamma_(gamma), wanted_(wanted), compact_(compact) {}
  // Whether any of the next n rows is wanted; skip(n) passes them, written or not.
  bool wants(int n) const { return n_ >= 32 || ((wanted_ >> n_) & ((n >= 32 ? ~0u : (1u << n) - 1u))) != 0; }
  void skip(int n) { n_ += n; }
  void put(const Row& row) {
    if (compact_) {
      if (wanted(n_)) Phi_(k_) = row.Phi, J_.row(k_) = row.J, gamma_(k_) = row.gamma, ++k_;
      ++n_;
      return;
    }
    Phi_(n_) = row.Phi;
    J_.row(n_) = row.J;
    gamma_(n_) = row.gamma;
    ++n_;
  }
  // The three rows of a three-row primitive.
  void put(const Rows3& rows) {
    if (compact_) {
      for (int r = 0; r < 3; ++r)
        if (wanted(n_ + r)) Phi_(k_) = rows.Phi(r), J_.row(k_) = rows.J.row(r), gamma_(k_) = rows.gamma(r), ++k_;
      n_ += 3;
      return;
    }
    Phi_.segment<3>(n_) = rows.Phi;
    J_.middleRows<3>(n_) = rows.J;
    gamma_.segment<3>(n_) = rows.gamma;
    n_ += 3;
  }
  int count() const { return n_; }

 private:
  Eigen::Ref<Eigen::VectorXd> Phi_;
  Eigen::Ref<Eigen::MatrixXd> J_;
  Eigen::Ref<Eigen::VectorXd> gamma_;
  unsigned wanted_;
  bool compact_;
  int n_ = 0;
  int k_ = 0;  // (compact: rows written)
  bool wanted(int n) const { return n < 32 && ((wanted_ >> n) & 1u); }
};

}  // namespace mechanism_sim
