// Assembly: brings a State onto the constraints from the file's pose (assembly.cpp). It
// closes the loops on the spanning tree's joint coordinates by continuation
// (joint_space/tree.h), then polishes in absolute coordinates with the absolute stepper's
// projections (absolute/), so it sits beside the facade, above both formulations.
#pragma once
#include <vector>

#include "mechanism_sim/core/mechanism.h"

namespace mechanism_sim {

// Brings the state onto the constraints (positions, then velocities), holding the given
// joint coordinates; checks that every free motion moves mass and reports dependent
// equations. Throws ModelError naming the joints that do not close.
AssemblyReport assemble(const System& sys, State& s, Stepper& stepper,
                        const std::vector<CoordinateTarget>& positions,
                        const std::vector<CoordinateTarget>& velocities, DependencyReport* deps);

}  // namespace mechanism_sim
