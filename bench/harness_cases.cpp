// bench_harness: the peer harness's cases (../shared/peers) run from this repository alone.
// Mechanisms, references and metrics: bench/harness_models.h. Per case, as the harness does:
//   * a probe of at most 20 steps estimates the cost of a step;
//   * a monitored run over the whole horizon, from the assembled state of a freshly loaded
//     model, gives the accuracy metric, the largest violation, the energy drift and the
//     solver's shortfalls (untimed; the chain's reference run at dt/10 happens here);
//   * `repeats` timed runs of bare Mechanism::step(dt) calls from MechanismModel::reset()
//     (untimed) over the horizon, or its first k steps when the whole would exceed the
//     budget; the table gives the median per step, and min and max.
// Then the linear-cost check of issue 7: chains of 50 and 400 links, ratio of their costs.
//
//   bench_harness [--cases pendulum,chain,fourbar,screw,linear] [--dt S] [--integrator rk4|rk3|rk2]
//                 [--formulation absolute|joint|auto]
//                 [--repeats N] [--budget S] [--chain-n 10,50,200] [--fourbar-n 1,10,50] [--quick]
//   bench_harness --steps CASE N K   loads one case and takes K steps of 1 ms, untimed, then
//                 prints the solver's work per step: for an instruction count, run it under
//                 valgrind --tool=callgrind at two K and divide the difference
//                 (doc/testing.md "Benchmarks"; figures in bench/RESULTS.md).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "cpu_time.h"
#include "harness_models.h"

using mechanism_sim::MechanismModel;
using mechanism_sim::SolverStats;
using Clock = std::chrono::steady_clock;

namespace {

struct Options {
  std::set<std::string> cases{"pendulum", "chain", "fourbar", "screw", "linear"};
  double dt = 1e-3;
  std::string integrator = "rk4";
  std::string formulation;  // empty: the default (absolute)
  int repeats = 5;
  double budget = 10.0;  // seconds for the timed repeats of one case
  std::vector<int> chain_n{10, 50, 200}, fourbar_n{1, 10, 50};
  bool quick = false;
  // horizon: the harness's, or short ones for a smoke test
  double horizon(double T) const { return quick ? std::min(T, 0.2) : T; }
};

struct Row {
  std::string name, metric = "-", solver = "-", note;
  int N = 1;
  long steps = 0, timed = 0;
  double med = NAN, min = NAN, max = NAN;  // wall time per step [µs]
  double cpu = NAN;                         // this thread's CPU time per step [µs], median
  double value = NAN, violation = NAN, max_phi = NAN, drift = NAN;
  double evaluations = NAN, factorizations = NAN;  // per step, in the monitored run
};

// What a case measures along its monitored run.
struct Monitor {
  double T = 0, energy_scale = 1;
  std::function<double(const MechanismModel&)> violation;  // after every step; may be empty
  std::function<void(MechanismModel&, Row&)> finish;       // metric and value at T
};

double seconds(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

using bench::cpuSeconds;
using bench::median;

std::vector<int> parseInts(const std::string& s) {
  std::vector<int> out;
  std::stringstream ss(s);
  for (std::string item; std::getline(ss, item, ',');) out.push_back(std::stoi(item));
  return out;
}

std::string num(double x, const char* fmt = "%.3g") {
  if (std::isnan(x)) return "-";
  char b[64];
  std::snprintf(b, sizeof b, fmt, x);
  return b;
}

// The counts of `after` less those of `before` (the worst residuals are kept as they are).
SolverStats since(const SolverStats& before, SolverStats after) {
  after.solves -= before.solves;
  after.solve_shortfalls -= before.solve_shortfalls;
  after.position_projections -= before.position_projections;
  after.position_shortfalls -= before.position_shortfalls;
  after.velocity_projections -= before.velocity_projections;
  after.velocity_shortfalls -= before.velocity_shortfalls;
  after.evaluations -= before.evaluations;
  after.factorizations -= before.factorizations;
  return after;
}

double energy(const MechanismModel& m) { return m.kineticEnergy() + m.potentialEnergy(); }

// Median, min and max of the cost per step of `repeats` runs of k steps from the initial state.
void timeSteps(MechanismModel& model, double dt, long k, int repeats, Row& r) {
  std::vector<double> wall, cpu;
  mechanism_sim::Mechanism& m = model.mechanism();
  for (int i = 0; i < repeats; ++i) {
    model.reset();
    const Clock::time_point t0 = Clock::now();
    const double c0 = cpuSeconds();
    for (long s = 0; s < k; ++s) m.step(dt);
    cpu.push_back((cpuSeconds() - c0) * 1e6 / static_cast<double>(k));
    wall.push_back(seconds(t0) * 1e6 / static_cast<double>(k));
  }
  r.timed = k;
  r.med = median(wall), r.cpu = median(cpu);
  r.min = *std::min_element(wall.begin(), wall.end()), r.max = *std::max_element(wall.begin(), wall.end());
}

Row runCase(const Options& opt, const std::string& name, int N, const Monitor& mon) {
  Row r;
  r.name = name, r.N = N;
  r.steps = std::lround(mon.T / opt.dt);
  try {
    auto model = harness::loadCase(name, N, opt.integrator, opt.formulation);
    // probe: the cost of a step, to fit the timed repeats into the budget
    model->reset();
    const Clock::time_point t0 = Clock::now();
    long probe = 0;
    while (probe < std::min<long>(20, r.steps) && seconds(t0) < 2.0) model->mechanism().step(opt.dt), ++probe;
    const double probe_s = seconds(t0) / static_cast<double>(probe);
    long timed = r.steps;
    if (probe_s * static_cast<double>(r.steps * opt.repeats) > opt.budget)
      timed = std::max<long>(3, static_cast<long>(opt.budget / (opt.repeats * probe_s)));

    // monitored run from a fresh model (its stats then count this run and the assembly)
    auto run = harness::loadCase(name, N, opt.integrator, opt.formulation);
    const SolverStats before = run->mechanism().solverStats();
    const double e0 = energy(*run);
    double viol = 0, phi = run->positionViolation();
    for (long k = 0; k < r.steps; ++k) {
      run->mechanism().step(opt.dt);
      if (mon.violation) viol = std::max(viol, mon.violation(*run));
      phi = std::max(phi, run->positionViolation());
      if (!std::isfinite(phi)) throw std::runtime_error("non-finite state at t = " + num(run->time()));
    }
    r.drift = std::fabs(energy(*run) - e0) / mon.energy_scale;
    r.violation = mon.violation ? viol : NAN;
    r.max_phi = phi;
    mon.finish(*run, r);
    const SolverStats used = since(before, run->mechanism().solverStats());
    r.solver = used.describe();
    r.evaluations = static_cast<double>(used.evaluations) / static_cast<double>(r.steps);
    r.factorizations = static_cast<double>(used.factorizations) / static_cast<double>(r.steps);

    timeSteps(*model, opt.dt, timed, opt.repeats, r);
  } catch (const std::exception& e) {
    r.note = std::string("FAILED: ") + e.what();
  }
  return r;
}

void printHeader() {
  std::printf("| case | N | dt [s] | integrator | steps (timed) | µs/step median [min–max] | µs/step CPU | metric "
              "| value | max violation [m] | max abs(Phi) | energy drift | evaluations / factorizations per step | solver |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
}

void printRow(const Options& opt, const Row& r) {
  const bool cut = r.note.empty() && r.timed < r.steps;  // timed only the first r.timed steps
  const std::string steps = std::to_string(r.steps) + (cut ? " (" + std::to_string(r.timed) + ")" : "");
  std::string cost = num(r.med) + " [" + num(r.min) + "–" + num(r.max) + "]";
  if (!r.note.empty()) cost = r.note;
  std::printf("| %s | %d | %g | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s / %s | %s |\n", r.name.c_str(), r.N, opt.dt,
              opt.integrator.c_str(), steps.c_str(), cost.c_str(), num(r.cpu).c_str(), r.metric.c_str(),
              num(r.value, "%.2e").c_str(),
              num(r.violation, "%.1e").c_str(), num(r.max_phi, "%.1e").c_str(), num(r.drift, "%.1e").c_str(),
              num(r.evaluations, "%.2f").c_str(), num(r.factorizations, "%.2f").c_str(), r.solver.c_str());
  std::fflush(stdout);
}

Eigen::Vector3d point(const MechanismModel& m, int link, const Eigen::Vector3d& p) { return m.linkPose(link) * p; }

int link(const MechanismModel& m, const std::string& name) {
  const int l = m.linkIndex(name);
  if (l < 0) throw std::runtime_error("no link " + name);
  return l;
}

Row pendulum(const Options& opt) {
  using P = harness::PendulumSpec;
  Monitor mon;
  mon.T = opt.horizon(P::T);
  mon.energy_scale = P::m * harness::kG * P::L;
  mon.finish = [&](MechanismModel& m, Row& r) {
    const Eigen::Vector3d c = point(m, link(m, "bob"), {-P::L, 0, 0});
    r.metric = "pos error vs exact [m]";
    r.value = (c.head<2>() - harness::pendulumExact(mon.T)).norm();
  };
  return runCase(opt, "pendulum", 1, mon);
}

Eigen::Vector3d chainTip(const MechanismModel& m, int N) {
  return point(m, link(m, "l" + std::to_string(N - 1)), {harness::ChainSpec::L, 0, 0});
}

Row chain(const Options& opt, int N) {
  using C = harness::ChainSpec;
  Monitor mon;
  mon.T = opt.horizon(C::T);
  mon.energy_scale = N * C::m * harness::kG * N * C::L;
  mon.finish = [&](MechanismModel& m, Row& r) {
    // the harness's reference: the same simulator at a finer step (here dt / 10)
    const double ref_dt = opt.dt / 10;
    auto ref = harness::loadCase("chain", N, opt.integrator, opt.formulation);
    for (long k = std::lround(mon.T / ref_dt); k > 0; --k) ref->mechanism().step(ref_dt);
    r.metric = "tip error vs dt " + num(ref_dt) + " [m]";
    r.value = (chainTip(m, N) - chainTip(*ref, N)).head<2>().norm();
  };
  return runCase(opt, "chain", N, mon);
}

Row fourBar(const Options& opt, int N) {
  using F = harness::FourBarSpec;
  Monitor mon;
  mon.T = opt.horizon(F::T);
  mon.energy_scale = (2 * N + 1) * F::m * harness::kG * F::L;
  const Eigen::Vector3d tip(0, F::L, 0), end(F::L, 0, 0);
  std::vector<int> crank, coupler;
  {  // link indices, and the assembled rates against the harness's start (stderr)
    auto m = harness::loadCase("fourbar", N, opt.integrator, opt.formulation);
    double worst = 0;
    for (int i = 0; i <= N; ++i) {
      crank.push_back(link(*m, "crank" + std::to_string(i)));
      worst = std::max(worst, std::fabs(m->velocity(m->dofIndex("crank_joint" + std::to_string(i))) + F::omega0));
      if (i == N) break;
      coupler.push_back(link(*m, "coupler" + std::to_string(i)));
      worst = std::max(worst, std::fabs(m->velocity(m->dofIndex("coupler_joint" + std::to_string(i))) - F::omega0));
    }
    std::fprintf(stderr, "fourbar N=%d: %d equations, %d dependent; assembled rates off by %.1e%s\n", N,
                 m->numEquations(), m->dependencies().dependent, worst, worst > 1e-9 ? "  WARNING" : "");
  }
  mon.violation = [=](const MechanismModel& m) {
    double v = 0;
    for (int i = 0; i < N; ++i) v = std::max(v, (point(m, coupler[i], end) - point(m, crank[i + 1], tip)).norm());
    return v;
  };
  mon.finish = [&](MechanismModel& m, Row& r) {
    r.metric = "B0 error vs exact [m]";
    r.value = (point(m, crank[0], tip).head<2>() - harness::fourBarExact(N, mon.T)).norm();
  };
  return runCase(opt, "fourbar", N, mon);
}

Row screw(const Options& opt) {
  using S = harness::ScrewSpec;
  Monitor mon;
  mon.T = opt.horizon(S::T);
  mon.energy_scale = S::m * harness::kG * harness::screwDescent(mon.T);
  mon.violation = [](const MechanismModel& m) {
    const double y = point(m, m.linkIndex("nut"), Eigen::Vector3d::Zero()).y();
    return std::fabs(y - S::p * m.position(m.dofIndex("screw")));
  };
  mon.finish = [&](MechanismModel& m, Row& r) {
    const double descent = -point(m, link(m, "nut"), Eigen::Vector3d::Zero()).y();
    const double exact = harness::screwDescent(mon.T);
    r.metric = "descent rel. error";
    r.value = std::fabs(descent - exact) / exact;
  };
  return runCase(opt, "screw", 1, mon);
}

// Issue 7: cost per step linear in bodies, (chain N = 400) / (chain N = 50) <= 8.5.
void linearCost(const Options& opt) {
  const long k = opt.quick ? 50 : 500;
  double wall[2], cpu[2];
  const int sizes[2] = {50, 400};
  for (int i = 0; i < 2; ++i) {
    Row r;
    auto m = harness::loadCase("chain", sizes[i], opt.integrator, opt.formulation);
    timeSteps(*m, opt.dt, k, opt.repeats, r);
    wall[i] = r.med, cpu[i] = r.cpu;
    std::printf("linear cost: chain N = %d: %.4g µs/step wall [%.4g–%.4g], %.4g CPU (median of %d x %ld steps)\n",
                sizes[i], r.med, r.min, r.max, r.cpu, opt.repeats, k);
  }
  const double ratio = wall[1] / wall[0];
  std::printf("linear cost: ratio N=400 / N=50 = %.2f wall, %.2f CPU (issue 7 requires <= 8.5; bodies ratio 8)%s\n",
              ratio, cpu[1] / cpu[0], ratio <= 8.5 ? "" : "  ** ABOVE 8.5 **");
}

std::string cpuModel() {
  std::ifstream f("/proc/cpuinfo");
  for (std::string line; std::getline(f, line);)
    if (line.rfind("model name", 0) == 0) return line.substr(line.find(':') + 2);
  return "unknown CPU";
}

int usage(const char* prog) {
  std::fprintf(stderr,
               "usage: %s [--cases pendulum,chain,fourbar,screw,linear] [--dt S] [--integrator rk4|rk3|rk2] [--formulation absolute|joint|auto]\n"
               "          [--repeats N] [--budget S] [--chain-n 10,50,200] [--fourbar-n 1,10,50] [--quick]\n"
               "       %s --steps pendulum|chain|fourbar|screw N K\n",
               prog, prog);
  return 2;
}

}  // namespace

// --steps CASE N K
int countSteps(const std::string& name, int N, long K) {
  auto m = harness::loadCase(name, N);
  for (long k = 0; k < K; ++k) m->step(1e-3);
  const SolverStats s = m->solverStats();
  const double k = static_cast<double>(std::max(K, 1L));
  std::printf("%s %d, %ld steps: per step %.2f evaluations, %.2f factorizations, %.2f refinement passes; %s\n",
              name.c_str(), N, K, s.evaluations / k, s.factorizations / k, s.solve_passes / k, s.describe().c_str());
  return 0;
}

int main(int argc, char** argv) {
  if (argc == 5 && std::string(argv[1]) == "--steps") {
    const std::string name = argv[2];
    if (!std::set<std::string>{"pendulum", "chain", "fourbar", "screw"}.count(name)) return usage(argv[0]);
    return countSteps(name, std::atoi(argv[3]), std::atol(argv[4]));
  }
  Options opt;
  bool repeats_given = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const bool has = i + 1 < argc;
    if (a == "--quick") opt.quick = true;
    else if (a == "--cases" && has) {
      opt.cases.clear();
      std::stringstream ss(argv[++i]);
      for (std::string c; std::getline(ss, c, ',');) {
        if (!std::set<std::string>{"pendulum", "chain", "fourbar", "screw", "linear"}.count(c)) return usage(argv[0]);
        opt.cases.insert(c);
      }
    } else if (a == "--dt" && has) opt.dt = std::atof(argv[++i]);
    else if (a == "--integrator" && has) opt.integrator = argv[++i];
    else if (a == "--formulation" && has) opt.formulation = argv[++i];
    else if (a == "--repeats" && has) opt.repeats = std::atoi(argv[++i]), repeats_given = true;
    else if (a == "--budget" && has) opt.budget = std::atof(argv[++i]);
    else if (a == "--chain-n" && has) opt.chain_n = parseInts(argv[++i]);
    else if (a == "--fourbar-n" && has) opt.fourbar_n = parseInts(argv[++i]);
    else return usage(argv[0]);
  }
  if (opt.quick && !repeats_given) opt.repeats = 1;
  if (!(opt.dt > 0) || opt.repeats < 1 || (opt.integrator != "rk4" && opt.integrator != "rk2" && opt.integrator != "rk3")) return usage(argv[0]);

  std::printf("bench_harness: %s; dt %g s, %s, formulation %s, median of %d repeats, timing budget %g s per case%s\n\n",
              cpuModel().c_str(), opt.dt, opt.integrator.c_str(), opt.formulation.empty() ? "absolute (default)" : opt.formulation.c_str(), opt.repeats, opt.budget,
              opt.quick ? "; QUICK: horizons cut to 0.2 s" : "");
  printHeader();
  if (opt.cases.count("pendulum")) printRow(opt, pendulum(opt));
  if (opt.cases.count("chain"))
    for (int N : opt.chain_n) printRow(opt, chain(opt, N));
  if (opt.cases.count("fourbar"))
    for (int N : opt.fourbar_n) printRow(opt, fourBar(opt, N));
  if (opt.cases.count("screw")) printRow(opt, screw(opt));
  if (opt.cases.count("linear")) {
    std::printf("\n");
    try {
      linearCost(opt);
    } catch (const std::exception& e) {
      std::printf("linear cost: FAILED: %s\n", e.what());
    }
  }
  return 0;
}
