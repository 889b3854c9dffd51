// Which constraint equations depend on others at a configuration (the rank of Phi_q), for
// the equality rows and the rows of the active limits. Dependent rows leave the solves
// (State::dropped); the rest must span what all rows span, and span it well.
//
// The test is a sparse LDL^T of the Gram matrix of Phi_q's normalized rows in constraint
// order, skipping zero pivots (a row with less than 1e-9 of its squared norm outside the
// span of the rows before it is dependent), taken in coordinates of the joints' own
// geometry (dependencies.cpp). Within one constraint the rows kept are chosen by a pivoted
// Cholesky of that constraint's Schur complement: the best-conditioned ones, not the first
// ones. A loop's dependent equations are those of its cut joint; which of its rows they are
// depends on how the loop lies in space (the three position rows of a revolute cut joint
// are global: the out-of-plane one is dependent), so the Stepper analyzes again when the
// rows it dropped stop being implied by those it kept, and whenever the set of active
// limits changes (a limit reached together with another through a loop is dependent).
#pragma once
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "core/numerics.h"
#include "mechanism_sim/core/reports.h"
#include "mechanism_sim/core/model/primitives.h"
#include "core/linalg/sparse_ldlt.h"

namespace mechanism_sim {

class System;

class DependencyAnalyzer {
 public:
  static constexpr double kPivotTol = numerics::absolute::kDependencyPivot;
  // Lays out the Gram matrix's pattern (allocates); analyze() then allocates nothing.
  void init(const System& sys);
  bool ready() const { return ready_; }
  // J[c]: the Jacobian of constraint c (6 rows, its size used; dropped rows not zeroed),
  // kin: the loaded body kinematics (ground first), limit_side: per limit. Writes dropped
  // (per row; inactive limits' rows are never dropped) and returns the number of dependent
  // rows; with a report, also what it says (allocates).
  template <class JacobianVector>
  int analyze(const System& sys, const std::vector<BodyKin>& kin, const JacobianVector& J,
              const signed char* limit_side, std::vector<char>& dropped, DependencyReport* report) {
    for (size_t c = 0; c < Jn_.size(); ++c) Jn_[c] = J[c];
    return finish(sys, kin, limit_side, dropped, report);
  }

 private:
  using Mat6 = Eigen::Matrix<double, 6, 6>;
  int finish(const System& sys, const std::vector<BodyKin>& kin, const signed char* limit_side,
             std::vector<char>& dropped, DependencyReport* report);
  // One body shared by constraints a and c (row(a) <= row(c)): Jn_a(slot) Jn_c(slot)^T
  // goes to Gx_ at index_[first + i * 6 + j] (-1: not stored, the lower triangle of a == c).
  struct Contribution {
    int a, slot_a, c, slot_c, first;
  };
  bool ready_ = false;
  std::vector<Eigen::Matrix<double, 6, Eigen::Dynamic>> Jn_;  // per constraint, normalized
  std::vector<Eigen::Vector3d> centroid_;                     // per body: of its joint points
  double size_ = 1.0;
  std::vector<Contribution> contributions_;
  std::vector<int> index_;
  std::vector<double> Gx_;
  std::vector<int> limit_of_;  // per constraint: its limit, or -1
  std::vector<int> diagonal_;  // per row: its diagonal entry in Gx_
  SparseLDLT gram_;
  Mat6 S_;
};

}  // namespace mechanism_sim
