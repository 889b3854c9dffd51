// Whether every motion the joints allow moves mass (mass_check.cpp).
#pragma once
#include "core/absolute/evaluation.h"
#include "core/absolute/solver.h"

namespace mechanism_sim {

// Throws ModelError naming every body that a motion moving no mass moves, where
// M + Phi_q^T W Phi_q (H, assembled here) is singular; ev is evaluated at the pose.
void checkMassRank(const System& sys, Evaluation& ev, PenaltyForm& H);

}  // namespace mechanism_sim
