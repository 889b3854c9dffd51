// Assembly on the spanning tree: closes the loops in the tree's joint coordinates, so
// that the tree's joints hold exactly at every iterate (tree_assembly.cpp).
#pragma once
#include <vector>

#include "core/joint_space/tree.h"
#include "mechanism_sim/core/mechanism.h"

namespace mechanism_sim {

// Brings s from its pose onto the loops' cut joints, couplers, drives and the targets by
// continuation on model's joint coordinates, each limited coordinate held within its
// limits; restarts the loops that stay open from drawn poses. s is left at the closest
// pose reached, placed and evaluated by st. Returns the largest residual there, each
// equation over its unit (scale-free).
double assembleOnTree(const System& sys, State& s, Stepper& st, const std::vector<CoordinateTarget>& targets,
                      const TreeModel& model);

}  // namespace mechanism_sim
