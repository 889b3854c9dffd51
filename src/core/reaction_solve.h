// The Mechanism's reaction queries' own solves (mechanism.cpp), private to the facade.
#pragma once
#include <memory>

#include "core/absolute/evaluation.h"
#include "core/absolute/solver.h"
#include "core/joint_space/tree_reactions.h"
#include "mechanism_sim/core/mechanism.h"

namespace mechanism_sim {

// The reactions' solves, with their own evaluations and scratch (queries leave stepping
// alone): the least-norm one (absolute formulation, dependent equations), the tree pass
// (joint formulation).
struct Mechanism::ReactionSolve {
  SolverStats stats;
  Evaluation ev;
  std::unique_ptr<ConstraintSolver> solver;
  std::unique_ptr<TreeReactionWorkspace> tree;
};

}  // namespace mechanism_sim
