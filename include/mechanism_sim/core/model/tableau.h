// The explicit Runge-Kutta methods of the Stepper as Butcher tableaus (doc/method.md
// "Integration method"). One stage loop (Stepper::stepOnce) runs them all:
//   stage k (k >= 1) starts from  y0 + h sum_j a_kj k_j,  at time t0 + c_k h;
//   the step ends at              y0 + h sum_j b_j k_j.
// Each row of a, and b, is written as weights over a common denominator (a_kj =
// a[k][j] / a_den[k], b_j = b[j] / b_den), and the stage loop forms (h / den) (sum_j w_j k_j)
// with the sum in order of j, skipping zero weights: the grouping of each method written
// out by hand (k_1 + 2 k_2 + 2 k_3 + k_4 for RK4), so that it gives those sums' bits.
#pragma once
#include <string>

#include <Eigen/Core>

namespace mechanism_sim {

// The integrators IntegratorOptions::method names ("rk4", "rk3", "rk2").
enum class Method { kRk2, kRk3, kRk4 };

struct Tableau {
  static constexpr int kMaxStages = 4;
  const char* name;  // as IntegratorOptions::method spells it
  int stages;
  double c[kMaxStages];
  double a[kMaxStages][kMaxStages];  // lower-triangular numerators (row 0 unused)
  double a_den[kMaxStages];
  double b[kMaxStages];  // numerators
  double b_den;
  // s_k = c_k h / m_k above which a damped coordinate is too stiff for the stages
  // (stiff_damping.cpp, 2.): below the method's stability limit on the negative real axis.
  double stiff_bound;
};

// Heun: one stage at x0 + h k1, weights 1/2, 1/2.
inline constexpr Tableau kHeun{"rk2", 2, {0, 1}, {{0}, {1}}, {1, 1}, {1, 1}, 2, 1.0};
// Kutta's third-order method (Hairer, Norsett & Wanner I, II.1): c = 0, 1/2, 1, stage 3 at
// x0 + h (2 k2 - k1), weights 1/6, 4/6, 1/6. Its stability region holds the imaginary axis
// up to |w h| = sqrt(3) (Heun's holds none of it), so an undamped oscillation does not
// grow; three solves a step instead of RK4's four.
inline constexpr Tableau kKutta3{"rk3", 3, {0, 0.5, 1}, {{0}, {1}, {-1, 2}}, {1, 2, 1}, {1, 4, 1}, 6, 1.6};
// Classical RK4.
inline constexpr Tableau kRk4{
    "rk4", 4, {0, 0.5, 0.5, 1}, {{0}, {1}, {0, 1}, {0, 0, 1}}, {1, 2, 2, 1}, {1, 2, 2, 1}, 6, 2.0};

constexpr const Tableau& tableau(Method m) {
  return m == Method::kRk2 ? kHeun : m == Method::kRk3 ? kKutta3 : kRk4;
}

// The method IntegratorOptions::method names; throws ModelError for an unknown name.
Method parseMethod(const std::string& name);

// The stage loop's sums (tableau.cpp), both steppers', over the first n rates k[j] (each
// of y0's size), per entry in one pass: the sum in order of j, zero weights skipped.
//   combineStages:     y = y0 + (h / den) sum_j w_j k_j (no weight: y = y0);
//   compensatedUpdate: the same with the round-off c0 carried in, y = y0 + ((h / den)
//                      sum_j w_j k_j + c0) split into y (rounded) and its round-off c
//                      (compensated summation, Knuth's TwoSum: exact in binary floating
//                      point without a test of magnitudes). y and c are sized by the caller.
void combineStages(double h, const double* w, int n, double den, const Eigen::VectorXd& y0, const double* const* k,
                   Eigen::VectorXd& y);
void compensatedUpdate(double h, const double* w, int n, double den, const Eigen::VectorXd& y0,
                       const double* const* k, const Eigen::VectorXd& c0, Eigen::VectorXd& c, Eigen::VectorXd& y);

}  // namespace mechanism_sim
