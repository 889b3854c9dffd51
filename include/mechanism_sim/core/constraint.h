// A constraint is a set of scalar equations Phi(q) = 0 over a few bodies.
#pragma once
#include <array>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "mechanism_sim/core/primitives.h"

namespace mechanism_sim {

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
  virtual void evaluate(const BodyKin* const* kin, Eigen::Ref<Eigen::VectorXd> Phi,
                        Eigen::Ref<Eigen::MatrixXd> J, Eigen::Ref<Eigen::VectorXd> gamma) const = 0;
  // Called with an accepted state (after assembly and every step): angle trackers
  // move their turn count here.
  virtual void accept(const BodyKin* const* /*kin*/) {}
  // Angles tracked through turns (the branch references); saved and restored with a state.
  const std::array<double, 2>& tracked() const { return tracked_; }
  void setTracked(const std::array<double, 2>& t) { tracked_ = t; }

 protected:
  std::array<double, 2> tracked_{};

 private:
  std::string name_;
  std::vector<int> bodies_;
};

// Writes Rows into the outputs of Constraint::evaluate, for two-body constraints.
class RowWriter {
 public:
  RowWriter(Eigen::Ref<Eigen::VectorXd> Phi, Eigen::Ref<Eigen::MatrixXd> J,
            Eigen::Ref<Eigen::VectorXd> gamma)
      : Phi_(Phi), J_(J), gamma_(gamma) {}
  void put(const Row& row) {
    Phi_(n_) = row.Phi;
    J_.row(n_) = row.J;
    gamma_(n_) = row.gamma;
    ++n_;
  }
  int count() const { return n_; }

 private:
  Eigen::Ref<Eigen::VectorXd> Phi_;
  Eigen::Ref<Eigen::MatrixXd> J_;
  Eigen::Ref<Eigen::VectorXd> gamma_;
  int n_ = 0;
};

}  // namespace mechanism_sim
