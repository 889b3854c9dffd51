// Reactions of the spanning tree's joints in the joint formulation: the
// multipliers of the tree joints' rows of State::lambda, which the joint stepper does not
// solve (its tree joints have no equations), from the recursive Newton-Euler pass over the
// accelerations the State holds (Featherstone, "Rigid Body Dynamics Algorithms" (RBDA),
// 2008, section 5.3, table 5.1: the inward loop f_i = f^B_i - f^x_i + sum over children c
// of X^T f_c), with every other force on a body as its external force: gravity, the
// inputs, springs, the joints' applied efforts (appliedForces' Q) and the closures'
// constraint forces -Phi_x^T lambda (couplers, drives, active limits, cut joints: their
// multipliers as the stepper solved them).
//
// What is left at a body is the wrench its tree joint transmits to it. In the absolute
// formulation that is -Phi_x,c^T lambda + q_x,c^T tau (the joint's constraint rows and
// coordinate rows on that body, c), size + dof = 6 columns of full rank: one 6 x 6 solve
// per joint gives lambda (State::lambda's rows and sign, doc/method.md) and tau, the effort
// transmitted along the coordinates besides the applied ones already in Q. On a tree the
// absolute formulation's multipliers are unique, so these are they (test_tree_reactions.cpp).
#pragma once
#include <vector>

#include <Eigen/Core>

#include "core/absolute/evaluation.h"
#include "core/joint_space/tree.h"
#include "mechanism_sim/core/model/system.h"

namespace mechanism_sim {

// Scratch of treeJointMultipliers, sized once for a System: filling it allocates nothing.
struct TreeReactionWorkspace {
  explicit TreeReactionWorkspace(const System& sys);
  Evaluation ev;   // the State's kinematics, every equation (none dropped) and Q
  State context;   // the State's evaluation context, with no row dropped
  AlignedVector<Vector6d> load;  // per moving body: [f (global); n' (body)] at its centre of
                                 // mass, everything on it but its tree joint
  std::vector<char> tree;        // per constraint: a joint of the tree, or a coupler it holds
  std::vector<double> tie_effort;  // per link: the held couplers' efforts on its coordinate
  std::vector<double> tie_x, tie_col;  // per master's link: its effort left over, its column's size
  double worst_effort = 0.0;     // of the last call: largest |tau| (relative), see below
};

// lambda (size sys.m): on entry the rows of every constraint that is not a tree joint hold
// their multipliers (State::lambda as JointStepper writes it); on return the tree joints'
// rows hold theirs, from s (x, u, acc: the joint state's bodies and accelerations, tracked
// angles, limit sides) and the inputs in. w.ev is then s's evaluation (the Jacobians
// lambda goes with). w.worst_effort: the largest effort a joint transmits along its
// coordinates beyond the applied ones, against its reaction (0 when the accelerations were
// solved under these inputs; joint damping integrated implicitly where stiff is not in
// them: stiff_damping.cpp).
void treeJointMultipliers(const System& sys, const TreeModel& model, const State& s, const Inputs& in,
                          TreeReactionWorkspace& w, Eigen::VectorXd& lambda);

}  // namespace mechanism_sim
