// Kinematic mechanisms (doc/method.md, "Kinematic models"): with no mass on any moving body
// every degree of freedom must be prescribed. Which joint coordinates the equations leave
// free, found before build so that their drives enter the System with the others.
#pragma once
#include <utility>
#include <vector>

#include "mechanism_sim/core/model/system.h"

namespace mechanism_sim {

// For each candidate coordinate (joint, k), in order: whether its row q_x,k is independent of
// the equality equations (joints, couplers, drives; not the limits) and of the candidates
// taken before it, at the bodies' initial poses. sys: described, not yet finalized (a copy
// is laid out here). Rows in velocity coordinates with the rotations scaled by the length
// scale, so both kinds of column weigh alike; a row joins when its part off the others'
// span exceeds 1e-8 of its size (Gram-Schmidt, twice). A coordinate with no position
// (holonomicCoordinates() false) is never taken.
std::vector<char> independentCoordinates(const System& sys, const std::vector<std::pair<int, int>>& candidates);

}  // namespace mechanism_sim
