// The Runge-Kutta methods' tableaus (tableau.h): the method by name and the stage loop's
// sums, which both steppers form through these.
#include "mechanism_sim/core/model/tableau.h"

#include <type_traits>

#include "mechanism_sim/core/model/errors.h"

namespace mechanism_sim {

Method parseMethod(const std::string& name) {
  for (Method m : {Method::kRk4, Method::kRk3, Method::kRk2})
    if (name == tableau(m).name) return m;
  throw ModelError("unknown integrator '" + name + "' (known: rk4, rk3, rk2)");
}

namespace {

// The stages' terms w_j k_j of a combination (j < n, w_j != 0) and their sum at entry i in
// order of j; sum<M>: M terms, known when compiled (1 to 4, RK4's rows), or 0: m, read at
// run time.
struct StageTerms {
  const double* k[Tableau::kMaxStages];
  double w[Tableau::kMaxStages];
  int m = 0;
  StageTerms(const double* weights, int n, const double* const* stages) {
    for (int j = 0; j < n; ++j)
      if (weights[j] != 0.0) k[m] = stages[j], w[m++] = weights[j];
  }
  template <int M>
  double sum(Eigen::Index i) const {
    double s = w[0] * k[0][i];
    for (int j = 1; j < (M > 0 ? M : m); ++j) s += w[j] * k[j][i];
    return s;
  }
  // f(std::integral_constant<int, M>()) with M as sum<M> takes it (m > 0)
  template <class F>
  void dispatch(F&& f) const {
    switch (m) {
      case 1: f(std::integral_constant<int, 1>()); break;
      case 2: f(std::integral_constant<int, 2>()); break;
      case 3: f(std::integral_constant<int, 3>()); break;
      case 4: f(std::integral_constant<int, 4>()); break;
      default: f(std::integral_constant<int, 0>());
    }
  }
};

}  // namespace

void combineStages(double h, const double* w, int n, double den, const Eigen::VectorXd& y0, const double* const* k,
                   Eigen::VectorXd& y) {
  const StageTerms terms(w, n, k);
  y.resize(y0.size());
  if (terms.m == 0) {
    y = y0;
    return;
  }
  const double c = h / den;
  terms.dispatch([&](auto M) {
    for (Eigen::Index i = 0; i < y0.size(); ++i) y(i) = y0(i) + c * terms.sum<decltype(M)::value>(i);
  });
}

void compensatedUpdate(double h, const double* w, int n, double den, const Eigen::VectorXd& y0,
                       const double* const* k, const Eigen::VectorXd& c0, Eigen::VectorXd& c, Eigen::VectorXd& y) {
  const StageTerms terms(w, n, k);
  const double wh = h / den;
  auto update = [&](Eigen::Index i, double sum) {
    const double d = wh * sum + c0(i);
    const double t = y0(i) + d;
    const double dd = t - y0(i);
    c(i) = (y0(i) - (t - dd)) + (d - dd);
    y(i) = t;
  };
  if (terms.m == 0) {
    for (Eigen::Index i = 0; i < y.size(); ++i) update(i, 0.0);
    return;
  }
  terms.dispatch([&](auto M) {
    for (Eigen::Index i = 0; i < y.size(); ++i) update(i, terms.sum<decltype(M)::value>(i));
  });
}

}  // namespace mechanism_sim
