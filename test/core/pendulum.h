// A pendulum with a known motion, for the core tests (test_solver.cpp,
// joint_space/test_joint_stepper.cpp).
#pragma once
#include <cmath>
#include <string>

#include "bodies.h"
#include "mechanism_sim/core/models.h"

namespace mechanism_sim {

constexpr double kG = 9.81;

// A point-like mass m (central inertia Ic) at distance L from a revolute about y through
// `pivot`, released from the horizontal (+x side) at rest, gravity -z.
struct Pendulum {
  double m = 1.0, L = 1.0, Ic = 1e-6;
  Vector3d pivot = Vector3d::Zero();
  int add(Mechanism& mech, const std::string& name = "bob") const {
    const int b = mech.addBody(body(name, m, Ic * Matrix3d::Identity(), pivot + Vector3d(L, 0, 0)));
    mech.addJoint(makeJoint("revolute", name + "_pivot", Mechanism::kGround, models::axisY(pivot), b,
                            models::axisY(Vector3d(-L, 0, 0))));
    return b;
  }
  // Exact motion: (m L^2 + Ic) q'' = m g L cos q, q the angle below the horizontal, by RK4
  // on the scalar equation with a step of 1e-5 s (its own error, against the same in long
  // double: 2.4e-13 m after 10 s, the round-off of its 1e6 steps).
  Vector3d exact(double T) const {
    const double q = exactAngle(T);
    return pivot + L * Vector3d(std::cos(q), 0, -std::sin(q));
  }
  // The angle q of that motion at T; with `reflected` (a rotor's N^2 J behind a gearbox)
  // added to the inertia about the pivot.
  double exactAngle(double T, double reflected = 0.0) const {
    const double c = m * kG * L / (m * L * L + Ic + reflected);
    double q = 0, v = 0;
    const double h = 1e-5;
    auto f = [c](double x) { return c * std::cos(x); };
    for (long k = 0, n = std::lround(T / h); k < n; ++k) {
      const double k1x = v, k1v = f(q);
      const double k2x = v + 0.5 * h * k1v, k2v = f(q + 0.5 * h * k1x);
      const double k3x = v + 0.5 * h * k2v, k3v = f(q + 0.5 * h * k2x);
      const double k4x = v + h * k3v, k4v = f(q + h * k3x);
      q += h / 6.0 * (k1x + 2 * k2x + 2 * k3x + k4x);
      v += h / 6.0 * (k1v + 2 * k2v + 2 * k3v + k4v);
    }
    return q;
  }
};

}  // namespace mechanism_sim
