// The harness's mechanisms as URDF (+ the mechanism_sim extension) and their references.
#include "harness_models.h"

#include <cmath>
#include <sstream>
#include <stdexcept>

namespace harness {
namespace {

// A URDF document being written: numbers at full precision.
class Urdf {
 public:
  explicit Urdf(const std::string& name) {
    os_.precision(17);
    os_ << "<robot name=\"" << name
        << "\" xmlns:mechanism_sim=\"https://mechanism-sim.github.io/urdf-extension\">\n"
        << "<link name=\"base\"/>\n";
  }
  // A link with its centre of mass at c and a diagonal central inertia.
  void link(const std::string& name, Eigen::Vector3d c, double m, Eigen::Vector3d I) {
    os_ << "<link name=\"" << name << "\"><inertial><origin xyz=\"" << c.x() << " " << c.y()
        << " " << c.z() << "\"/><mass value=\"" << m << "\"/><inertia ixx=\"" << I.x()
        << "\" iyy=\"" << I.y() << "\" izz=\"" << I.z()
        << "\" ixy=\"0\" ixz=\"0\" iyz=\"0\"/></inertial></link>\n";
  }
  // A continuous tree joint with its frame at `origin` in the parent link.
  void joint(const std::string& name, const std::string& parent, const std::string& child,
             Eigen::Vector3d origin, const char* axis = "0 0 1") {
    os_ << "<joint name=\"" << name << "\" type=\"continuous\"><parent link=\"" << parent
        << "\"/><child link=\"" << child << "\"/><origin xyz=\"" << origin.x() << " "
        << origin.y() << " " << origin.z() << "\"/><axis xyz=\"" << axis << "\"/></joint>\n";
  }
  std::ostream& raw() { return os_; }
  std::string close() {
    os_ << "<mechanism_sim:gravity xyz=\"0 " << -kG << " 0\"/>\n</robot>\n";
    return os_.str();
  }

 private:
  std::ostringstream os_;
};

// Classical RK4 on x'' = f(x) from (x, v) over T with step h, in long double. The shared
// harness (../shared/peers/common/bench_common.hpp) integrates the same reference in double
// at 1e-5 s: 5e5 additions of rounded increments leave its angle 1.1e-11 rad off for the
// one-loop four-bar (2.0e-12 for N = 10, 1.5e-11 for N = 50), the size of the errors it is
// used to judge. In long double at 1e-4 s the reference agrees with itself at 1e-5 s to
// 1e-16 (truncation and round-off both far below the double results compared with it).
template <class F>
double rk4(F f, double x0, double v0, double T, double h0) {
  using R = long double;
  const R h = h0;
  R x = x0, v = v0;
  const long n = std::lround(T / h0);
  for (long k = 0; k < n; ++k) {
    const R k1x = v, k1v = f(x);
    const R k2x = v + 0.5L * h * k1v, k2v = f(x + 0.5L * h * k1x);
    const R k3x = v + 0.5L * h * k2v, k3v = f(x + 0.5L * h * k2x);
    const R k4x = v + h * k3v, k4v = f(x + h * k3x);
    x += h / 6.0L * (k1x + 2 * k2x + 2 * k3x + k4x);
    v += h / 6.0L * (k1v + 2 * k2v + 2 * k3v + k4v);
  }
  return static_cast<double>(x);
}

}  // namespace

std::string pendulumUrdf() {
  using P = PendulumSpec;
  Urdf u("pendulum");
  u.link("bob", {-P::L, 0, 0}, P::m, Eigen::Vector3d::Constant(P::Ic));
  u.joint("j", "base", "bob", Eigen::Vector3d::Zero());
  return u.close();
}

std::string chainUrdf(int N) {
  using C = ChainSpec;
  Urdf u("chain");
  for (int i = 0; i < N; ++i) {
    const std::string l = "l" + std::to_string(i);
    u.link(l, {C::L / 2, 0, 0}, C::m, {C::Ia, C::It, C::It});
    u.joint("j" + std::to_string(i), i == 0 ? "base" : "l" + std::to_string(i - 1), l,
            {i == 0 ? 0.0 : C::L, 0, 0});
  }
  return u.close();
}

std::string fourBarUrdf(int N) {
  using F = FourBarSpec;
  Urdf u("fourbar");
  for (int i = 0; i <= N; ++i) {
    const std::string crank = "crank" + std::to_string(i);
    u.link(crank, {0, F::L / 2, 0}, F::m, {F::It, F::Ia, F::It});
    u.joint("crank_joint" + std::to_string(i), "base", crank, {i * F::L, 0, 0});
    if (i == N) break;
    const std::string coupler = "coupler" + std::to_string(i);
    u.link(coupler, {F::L / 2, 0, 0}, F::m, {F::Ia, F::It, F::It});
    u.joint("coupler_joint" + std::to_string(i), crank, coupler, {0, F::L, 0});
  }
  // Loop i: joint frame at coupler i's far end (parent) and at crank i+1's tip (child).
  for (int i = 0; i < N; ++i)
    u.raw() << "<mechanism_sim:joint name=\"loop" << i << "\" type=\"revolute\"><parent link=\"coupler"
            << i << "\"/><child link=\"crank" << i + 1 << "\"/><origin xyz=\"" << F::L
            << " 0 0\"/><child_origin xyz=\"0 " << F::L
            << " 0\"/><axis xyz=\"0 0 1\"/></mechanism_sim:joint>\n";
  return u.close();
}

std::string screwUrdf() {
  using S = ScrewSpec;
  Urdf u("screw");
  u.link("nut", Eigen::Vector3d::Zero(), S::m, Eigen::Vector3d::Constant(S::I));
  u.joint("screw", "base", "nut", Eigen::Vector3d::Zero(), "0 1 0");
  u.raw() << "<mechanism_sim:joint name=\"screw\" type=\"screw\" lead=\"" << S::lead << "\"/>\n";
  return u.close();
}

mechanism_sim::LoadOptions fourBarOptions() {
  mechanism_sim::LoadOptions o;
  o.velocities.push_back({"crank_joint0", -FourBarSpec::omega0});
  return o;
}

std::unique_ptr<mechanism_sim::MechanismModel> loadCase(const std::string& name, int N,
                                                        const std::string& integrator,
                                                        const std::string& formulation) {
  mechanism_sim::LoadOptions o = name == "fourbar" ? fourBarOptions() : mechanism_sim::LoadOptions();
  o.integrator = integrator;
  o.formulation = formulation;
  if (name == "pendulum") return mechanism_sim::loadModelString(pendulumUrdf(), "pendulum.urdf", o);
  if (name == "chain") return mechanism_sim::loadModelString(chainUrdf(N), "chain.urdf", o);
  if (name == "fourbar") return mechanism_sim::loadModelString(fourBarUrdf(N), "fourbar.urdf", o);
  if (name == "screw") return mechanism_sim::loadModelString(screwUrdf(), "screw.urdf", o);
  throw std::invalid_argument("no harness case '" + name + "'");
}

Eigen::Vector2d pendulumExact(double T) {
  using P = PendulumSpec;
  const long double c = P::m * kG * P::L / (P::m * P::L * P::L + P::Ic);
  const double q = rk4([c](long double x) { return c * std::cos(x); }, 0.0, 0.0, T, 1e-4);
  return {-P::L * std::cos(q), -P::L * std::sin(q)};
}

Eigen::Vector2d fourBarExact(int N, double T) {
  const long double a = kG * ((N + 1) / 2.0L + N) / ((N + 1) / 3.0L + N);
  const double phi = rk4([a](long double x) { return a * std::sin(x); }, 0.0, FourBarSpec::omega0, T, 1e-4);
  return {std::sin(phi), std::cos(phi)};
}

double screwDescent(double T) {
  using S = ScrewSpec;
  const double a = kG * S::m * S::p * S::p / (S::m * S::p * S::p + S::I);
  return 0.5 * a * T * T;
}

}  // namespace harness
