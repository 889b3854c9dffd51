// The mechanisms of the peer-engine harness (../shared/peers, README there), written as
// URDF strings for mechanism_sim::loadModelString, and their reference solutions. The
// parameters, initial conditions and references are the harness's; bench/harness_cases.cpp
// and bench/bench_factor.cpp share them, so the speed table in bench/RESULTS.md ("Peer run
// at `bf3526c`") can be reproduced from this repository alone.
//
// All mechanisms: gravity (0, -9.81, 0); planar ones in the x-y plane, revolute axes +z.
//   pendulum  1 kg, centre of mass 1 m from a revolute at the origin, central inertia 1e-6
//             (isotropic); starts at rest at (-1, 0, 0); 10 s.
//   chain     N rods, 0.1 m, 0.1 kg, centre of mass at mid-length, transverse inertia mL^2/12,
//             axial 1e-3 of that; joint 0 at the origin, joint i at the tip of link i-1;
//             starts straight along +x at rest; 2 s.
//   four-bar  N+1 cranks (1 m, 1 kg, along local +y) pinned to ground at (i, 0, 0), N couplers
//             (1 m, 1 kg, along local +x) pinned to the tip of crank i; loop i closed by a
//             revolute joint (axis z) between coupler i's far end and crank i+1's tip.
//             Starts with cranks vertical, couplers horizontal, every crank turning clockwise
//             at 1 rad/s (given as crank_joint0 = -1 rad/s; assembly gives the rest); 5 s.
//   screw     1 kg, isotropic inertia 0.01, lead 0.01 m per revolution along +y, at rest; 2 s.
#pragma once
#include <memory>
#include <string>

#include <Eigen/Core>

#include "mechanism_sim/urdf/model.h"

namespace harness {

constexpr double kG = 9.81;
constexpr double kPi = 3.14159265358979323846;

struct PendulumSpec {
  static constexpr double m = 1.0, L = 1.0, Ic = 1e-6, T = 10.0;
};
struct ChainSpec {
  static constexpr double m = 0.1, L = 0.1, It = m * L * L / 12.0, Ia = 1e-3 * It, T = 2.0;
};
struct FourBarSpec {
  static constexpr double m = 1.0, L = 1.0, It = m * L * L / 12.0, Ia = 1e-3 * It;
  static constexpr double omega0 = 1.0, T = 5.0;
};
struct ScrewSpec {
  static constexpr double m = 1.0, I = 0.01, lead = 0.01, p = lead / (2.0 * kPi), T = 2.0;
};

std::string pendulumUrdf();                 // link "bob", joint "j"
std::string chainUrdf(int N);               // links "l0".."l{N-1}", joints "j0".."j{N-1}"
std::string fourBarUrdf(int N);             // links "crankI", "couplerI"; loops "loopI"
std::string screwUrdf();                    // link "nut", joint "screw"
mechanism_sim::LoadOptions fourBarOptions();  // crank_joint0 at -omega0 (clockwise)

// Loads one of the above by case name ("pendulum", "chain", "fourbar", "screw").
std::unique_ptr<mechanism_sim::MechanismModel> loadCase(const std::string& name, int N,
                                                        const std::string& integrator = "",
                                                        const std::string& formulation = "");

// ---- reference solutions (classical RK4 with h = 1e-5 on the exact 1-dof equations)
// Pendulum centre of mass at time T: (mL^2 + Ic) q'' = m g L cos q, COM = -L (cos q, sin q).
Eigen::Vector2d pendulumExact(double T);
// Four-bar on its parallelogram branch: [(N+1)/3 + N] phi'' = g [(N+1)/2 + N] sin phi,
// phi(0) = 0, phi'(0) = omega0; tip of crank 0, B0 = (sin phi, cos phi).
Eigen::Vector2d fourBarExact(int N, double T);
// Screw descent 1/2 a T^2, a = g m p^2 / (m p^2 + I).
double screwDescent(double T);

}  // namespace harness
