// The classification of joint damping that both formulations call: which damped
// coordinates are stiff at a step of size h. absolute/stiff_damping.cpp derives the rule
// and integrates the stiff coordinates implicitly in absolute coordinates,
// joint_space/joint_damping.cpp in joint coordinates.
//
// Viscous damping tau_k = -c_k q_dot_k decays on its own at the rates of h C^1/2 P C^1/2 (C
// the dampings, P the constrained inverse mass at the damped coordinates). By Gershgorin
// the rate of coordinate k is at most
//   h s_k,   s_k = sum_l sqrt(c_k c_l) |P_lk|   (l over the damped coordinates, k included),
// and k is stiff where h s_k is past the integrator's stiff_bound (tableau.h: where implicit
// Euler becomes the more accurate of the two on the damped mode; stiff_damping.cpp, item 2).
// P costs solves, so each formulation first screens with a bound on s_k from the inverse
// masses it has at hand, and takes P itself only for the coordinates the screen does not
// clear:
//   absolute: P <= M^-1 (constraints only add effective mass) and M^-1 is block diagonal
//     there (System::Minv): s_k <= sum over the damped rows l on k's bodies b of
//     sqrt(c_k c_l) |q_x,k,b M_b^-1 q_x,l,b^T| (bodyInverseMass);
//   joint: |P_lk| <= sqrt(P_ll P_kk) <= sqrt(beta_l beta_k) with beta_k >= (M^-1)_kk from
//     the bodies' own inertias (coordinateInverseMassBound), then the absolute screen's
//     sum over the joint's own coordinates as a filter (joint_damping.cpp).
// Both then decide with decayRate over P's entries and isStiff.
#pragma once
#include <cmath>

#include <Eigen/Core>

namespace mechanism_sim {
namespace stiff_damping {

using Row6 = Eigen::Matrix<double, 1, 6>;

// Coordinate l's term in s_k: sqrt(c_k c_l) |P_lk|.
inline double term(double c_k, double c_l, double P_lk) { return std::sqrt(c_k * c_l) * std::fabs(P_lk); }

// h s_k = h sum_l term(c_k, c_l, P_lk) over the entries that for_each_entry(add) passes to
// add(c_l, P_lk), in its order.
template <class ForEachEntry>
double decayRate(double h, double c_k, ForEachEntry for_each_entry) {
  double sum = 0.0;
  for_each_entry([&](double c_l, double P_lk) { sum += term(c_k, c_l, P_lk); });
  return h * sum;
}

// Whether a coordinate whose decay rate (or a bound on it) is rate stays out of the
// explicit stages: past the bound (NaN, an infinite rate: stiff).
inline bool isStiff(double rate, double stiff_bound) { return !(rate <= stiff_bound); }

// a M_b^-1 b^T for two rows over one body's six columns [v; omega'], M_b^-1 block diagonal
// (1/m, J'^-1: System::Minv): the screens' entry of the inverse mass.
inline double bodyInverseMass(const Row6& a, const Row6& b, const Eigen::Matrix<double, 6, 6>& Mi) {
  return Mi(0, 0) * a.head<3>().dot(b.head<3>()) + a.tail<3>().dot(b.tail<3>() * Mi.bottomRightCorner<3, 3>().transpose());
}

}  // namespace stiff_damping
}  // namespace mechanism_sim
