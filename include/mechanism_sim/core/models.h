// Reference mechanisms built in code (no URDF), for tests and benchmarks. All move in the
// x-z plane under gravity -z with revolute axes along y.
#pragma once
#include "mechanism_sim/core/mechanism.h"

namespace mechanism_sim {
namespace models {

// Inertia of a slender rod of mass m and length L along body x, about its centre.
Matrix3d rodInertia(double m, double L);
// Joint frame at point sp with its z axis along global y (bodies start unrotated).
JointFrame axisY(const Vector3d& sp);

// N links of length L and mass m in a chain hanging from ground at the origin, released
// from angle theta0 below the horizontal (0: horizontal). Returns the first body index.
int pendulumChain(Mechanism& m, int n, double L = 0.5, double mass = 1.0, double theta0 = 0.0);

// N four-bar loops in series: N+1 cranks of length r pivoted on ground at x = 0, d, .., N d
// and N couplers joining their tips (each loop: ground, crank k, coupler k, crank k+1).
// With every crank parallel the loops are parallelograms. 3N+1 revolute joints, 1 dof.
int fourBarChain(Mechanism& m, int n, double r = 0.4, double d = 1.0, double theta0 = 1.0);

}  // namespace models
}  // namespace mechanism_sim
