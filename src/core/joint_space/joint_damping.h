// The joint formulation's damping (joint_damping.cpp): the absolute formulation's rule
// (stiff_damping.cpp) in joint coordinates. A damped coordinate whose decay rate h s_k the
// integrator could not follow (past the tableau's stability bound) is stiff, integrated by
// implicit Euler after the stages; the others are efforts in the stages.
#pragma once
#include <cmath>
#include <vector>

#include <Eigen/Core>

#include "core/joint_space/loop_closure.h"
#include "core/joint_space/tree.h"
#include "mechanism_sim/core/model/system.h"
#include "mechanism_sim/core/model/tableau.h"

namespace mechanism_sim {

// 1 / m and J'^-1 of a body (its mass and central inertia): inv_m +inf without mass, has_J
// false where J' is not positive definite.
struct BodyInverse {
  double inv_m = HUGE_VAL;
  Matrix3d inv_J = Matrix3d::Zero();
  bool has_J = false;
};
BodyInverse bodyInverse(const Body& B);

// An upper bound on (M^-1)_kk, M the joint-space inertia of the tree, for a joint coordinate
// whose row over its joint's two bodies (Joint::coordinates) is `row`, in the configuration
// the row was taken in: row M_b^-1 row^T with the two bodies' own masses and central
// inertias (derivation at the definition). +inf (HUGE_VAL) where the row moves a body that
// has no mass or no inertia along it. For a revolute joint the row, and so the bound, is the
// same in every configuration. (JointDamping::classify.) The second form with the
// bodies' inverses (bi, bj: of J's bodies i and j) computed once.
double coordinateInverseMassBound(const System& sys, const Joint& J, const Row& row);
double coordinateInverseMassBound(const Joint& J, const Row& row, const BodyInverse& bi, const BodyInverse& bj);

// The damped coordinates of a tree and their classification, at the stepper's model,
// articulated factors (ws) and closures, which it reads and does not own.
class JointDamping {
 public:
  JointDamping(const TreeModel& model, TreeWorkspace& ws, LoopClosures& closures)
      : model_(model), ws_(ws), closures_(closures) {}
  // Which coordinates are damped, and by how much (the System's damping; sized for the
  // closures' rows).
  void set(const System& sys);
  // Joint damping (the absolute formulation's rule, stiff_damping.cpp, in joint
  // coordinates): which damped coordinates are stiff at this step (ws_ at s.q's factors);
  // returns whether the set changed. The others stay in the stages as efforts. The set
  // found is held in s.damping_hold for the next steps where no coordinate was near the
  // bound (kHold* in joint_damping.cpp). ws_ at s.q's articulated factors.
  bool classify(const System& sys, State& s, double h, const Tableau& tableau);
  // Whether classify reads s's absolute state (x, u): not where no coordinate can be stiff
  // under this step and bound, the last classification having cleared every one by bounds
  // that do not change with the configuration.
  bool readsState(double h, const Tableau& tableau) const {
    return !(h == quiet_h_ && tableau.stiff_bound == quiet_bound_);
  }
  // The stiff ones after the stages: implicit Euler in the metric M + h C (Lie splitting).
  void implicit(const System& sys, State& s, double h);
  struct Damped {
    int j = 0, k = 0, iv = 0;  // joint, its coordinate, q_dot's index
    double c = 0.0;
    // A revolute joint's angle: its rows on the two bodies are the axis in each body's
    // frame, so classify's filter and bound do not change with the configuration:
    // kept in `bound` and `beta` once computed (-1: not yet).
    bool revolute = false;
    double bound = -1.0;
    double beta = -1.0;  // coordinateInverseMassBound
  };
  const std::vector<Damped>& damped() const { return damped_; }
  // per damped() entry: integrated implicitly (classify)
  const std::vector<char>& stiff() const { return stiff_; }
  bool anyStiff() const { return !stiff_list_.empty(); }
  // cut joints with damping (their efforts: JointStepper::accelerations)
  const std::vector<int>& cutDamped() const { return cut_damped_; }

 private:
  // For classify, at ws_'s articulated factors (q0): the columns of M^-1 of the
  // candidates (damp_candidates_) at the damped coordinates, and with closures
  // (M^-1 G^T) and W = (M^-1 G^T) (G M^-1 G^T)^+ there (damp_Yd_, damp_W_).
  void dampedInverseMass();

  const TreeModel& model_;
  TreeWorkspace& ws_;
  LoopClosures& closures_;
  std::vector<BodyKin> kin_;  // the bodies' kinematics at s (the bounds' rows)
  std::vector<Damped> damped_;  // every damped tree coordinate
  // The damped coordinates' paths (set()): per damped_ entry the links of its path to the
  // root (its own first) and their velocity coordinates; per velocity coordinate its link
  // and its damped_ entry (-1: none); per damped_ entry k, the entries l whose paths share
  // coordinates with k's (their common ancestors': the tail of l's path), from
  // shared_first[k] on: l and where in coords[l] the shared ones begin.
  struct Paths {
    std::vector<std::vector<int>> links, coords;
    std::vector<int> link_of_v, damped_of_v;
    struct Shared {
      int l = 0, from = 0;
    };
    std::vector<Shared> shared;
    std::vector<int> shared_first;
  };
  Paths paths_;
  Eigen::MatrixXd damp_Zd_, damp_Xd_;  // L^-T e_l and D^-1 L^-T e_l per damped_ entry l
  Eigen::MatrixXd damp_Minv_;          // (M^-1)_Dk, column a for damped_ entry damp_need_[a]
  Eigen::MatrixXd damp_Yd_, damp_W_;   // (M^-1 G^T)_D and W (damped x closure rows)
  std::vector<int> damp_W_lo_, damp_W_hi_;  // per used closure row: W's column is zero off [lo, hi)
  std::vector<int> damp_used_;         // closure rows whose column of damp_Yd_ is not zero
  std::vector<int> damp_candidates_;   // damped_ entries whose P column is needed
  std::vector<int> damp_need_;         // ... and those closure rows need
  std::vector<int> damp_column_of_;    // per damped_ entry: its column of damp_Minv_, or -1
  std::vector<char> damp_direct_;      // per closure row: on damped coordinates only
  std::vector<int> damp_nz_, damp_nz_first_;  // per closure row: its nonzero entries' coordinates
  std::vector<char> damp_touched_;     // per damped_ entry: its row of damp_Yd_ is not zero
  Eigen::VectorXd damp_col_, damp_x_;  // P e_k at the damped coordinates; scratch
  std::vector<double> damp_filter_, damp_rcb_;   // per damped_ entry, this step: the filter, sqrt(c beta)
  std::vector<BodyInverse> body_inverse_;        // per System body (the bound's)
  AlignedVector<Vector6d> damp_p_;     // the inward passes' forces
  std::vector<char> damp_mark_;        // per link: on a closure row's paths
  std::vector<int> damp_links_;        // those links, children before parents
  std::vector<int> cut_damped_;  // cut joints with damping (efforts: accelerations())
  std::vector<char> stiff_;     // per damped_: integrated implicitly (classifyDamping)
  std::vector<int> stiff_list_;  // indices into damped_ of the stiff ones
  // implicit()'s scratch (nothing in it is read across calls)
  struct ImplicitWork {
    Eigen::MatrixXd Y;  // M^-1 e_iv per damped_ entry: of the stiff ones at the stages' end
    Eigen::MatrixXd K;  // C^-1 / h + E^T M^-1 E over the stiff ones, and its Cholesky factor
    Eigen::VectorXd z, du, zero, qdd, tau;
    AlignedVector<Vector6d> v, f;  // bodies' velocities and momenta
    Eigen::VectorXd w, c;          // with closures
    Eigen::MatrixXd Z, AW;
    ScaledLeastNorm least_norm;    // of G W^-1 G^T
  };
  ImplicitWork implicit_;
  Eigen::VectorXd damp_e_, damp_r_, damp_mu_;  // a unit or closure row; closure-row scratch
  // (h, stiff_bound) under which no coordinate can be stiff in any configuration (classify:
  // every damped coordinate a revolute joint's, cleared by its kept screen or filter), NaN:
  // none
  double quiet_h_ = NAN, quiet_bound_ = NAN;
  std::vector<Row> damp_rows_;   // Joint::coordinates of a damped joint (the bound)
};

}  // namespace mechanism_sim
