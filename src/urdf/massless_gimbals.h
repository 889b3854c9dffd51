// Balls written as gimbals. URDF has no ball joint, so files write one as three revolute
// joints in a chain through two links with neither mass nor inertia (example-parallel-robots'
// `_rev0`, `_rev1`, `_rev2`). With the middle links massless the chain moves exactly as a
// spherical joint at its centre, except at the gimbal's lock (the middle angle at +-pi/2):
// there the outer axes line up, the links must turn infinitely fast for the child to keep
// turning about the lost direction, and the simulated chain leaves the ball's motion (both
// formulations: the joint-space mass matrix is singular there, the absolute formulation's
// massless links are undetermined). Such a chain is simulated as the ball it stands for.
// Internal to the loader.
#pragma once
#include <array>
#include <string>
#include <vector>

#include <urdf_model/model.h>

#include "joint_specs.h"
#include "mechanism_sim/urdf/model.h"
#include "transmissions.h"

namespace mechanism_sim {
namespace urdf_input {

// A chain J0 -> L1 -> J1 -> L2 -> J2 simulated as a ball: the file's joints as written, by
// which the model reports the ball (MechanismModel: the three angles as the file's joints'
// positions, L1 and L2 where they turn to).
struct GimbalChain {
  std::array<JointSpec, 3> joints;  // J0, J1, J2 before the merge
};

// The chains merged and the note naming them ("" if none).
struct MergedGimbals {
  std::vector<GimbalChain> chains;
  std::string note;
};

// Turns each chain J0 -> L1 -> J1 -> L2 -> J2 of the tree that is a ball into one spherical
// joint: J0 becomes spherical at its frame (its rates J0.x, J0.y, J0.z: the relative angular
// velocity in J0's joint frame), J1 and J2 fixed at their zero (L1 and L2 weld to J2's
// child, adding no mass). A chain is a ball when:
//  - J0, J1, J2 are revolute or continuous without limits, damping, friction or mimic, and
//    nothing else names them (an actuator, a transmission, a drive, an initial value, a
//    type override, a coupling, an option);
//  - L1 and L2 have neither mass nor inertia, and nothing but J1 (J2) below them, and no
//    loop closure, spring or coupling holds them;
//  - J1's and J2's origins coincide with J0's (the axes meet at one point) and each axis is
//    perpendicular to the next (Davenport: the three then reach every rotation);
//  - the model has mass somewhere (a kinematic model keeps its joints).
MergedGimbals mergeMasslessGimbals(JointSpecs* specs, const urdf::ModelInterface& urdf, const Extension& ext,
                                 const Transmissions& transmissions, const LoadOptions& options);

}  // namespace urdf_input
}  // namespace mechanism_sim
