// bench_soak: every example mechanism for a long run (issue 8, item 5). Not a timed test:
// it reports what a long run does to the constraints, the energy and the solver.
//
//   bench_soak [--steps N] [--dt S] [--model FILE]... [--csv OUT] [DIR]
//
// Runs every DIR/*.urdf (default: the package's urdf/), or only the --model files, for N
// steps (default 10^6) of dt (default 1 ms, the step `simulate` and the node use; URDF
// carries no step of its own) through the public MechanismModel API, from the assembled
// initial state, with no commands. After every step it reads:
//   * positionViolation() / relativePositionViolation(), velocityViolation() /
//     relativeVelocityViolation(): the largest over the run is reported;
//   * E = kineticEnergy() + potentialEnergy() (gravity and springs) and the kinetic energy.
// Energy drift, for conservative mechanisms only:
//   drift = max_t |E(t) - E(0)| / KE_peak,  KE_peak = max_t KE(t)   (the column "drift/KE")
// and, as issue 8 words it, the same over max(KE_peak, |E(0)|) ("drift/max(KE,|E0|)"); E(0)
// depends on where gravity's potential is zero (the world origin), so "drift/KE" is the
// stricter and the one to quote.
// Conservative is decided from the built System, not from the URDF text: every joint
// coordinate's damping and Coulomb friction is 0, every spring has zero damping and zero
// actuation force, no joint coordinate is driven (a drive does work), and no position
// limit is active at any step (a stop is perfectly inelastic); the bench commands no
// efforts. Everything else is listed as the reason
// the mechanism is not conservative.
// µs/step is the wall time of the step() calls alone; "wall" includes the monitoring.
// Progress, with E(t)-E(0) at every tenth of the run (a drift that grows steadily or not),
// goes to standard error. A step that throws ends that mechanism's run: the row says
// FAILED with the time and step reached and the message, and the run goes on with the
// next mechanism.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "mechanism_sim/urdf/model.h"

#ifndef MECHANISM_SIM_URDF_DIR
#define MECHANISM_SIM_URDF_DIR "urdf"
#endif

namespace ms = mechanism_sim;
using Clock = std::chrono::steady_clock;

namespace {

struct Options {
  long steps = 1000000;
  double dt = 1e-3;
  std::vector<std::string> models;
  std::string dir = MECHANISM_SIM_URDF_DIR, csv;
};

struct Row {
  std::string model, failure, solver = "-", not_conservative;  // empty: conservative
  long steps = 0;
  double sim_time = 0, wall = 0, step_wall = 0, load_wall = 0;
  double max_phi = 0, max_rel_phi = 0, max_vel = 0, max_rel_vel = 0, t_max_phi = 0;
  double e0 = NAN, ke_peak = 0, max_de = 0, t_max_de = 0, final_de = NAN;
  bool conservative() const { return not_conservative.empty(); }
  double driftKE() const { return ke_peak > 0 ? max_de / ke_peak : NAN; }
  double driftScale() const {
    const double s = std::max(ke_peak, std::fabs(e0));
    return s > 0 ? max_de / s : NAN;
  }
};

[[noreturn]] void usage(const std::string& problem) {
  std::fprintf(stderr, "bench_soak: %s\nusage: bench_soak [--steps N] [--dt S] [--model FILE]... [--csv OUT] [DIR]\n",
               problem.c_str());
  std::exit(2);
}

Options parse(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) usage(a + " needs a value");
      return argv[++i];
    };
    char* end = nullptr;
    if (a == "--steps") {
      const std::string v = value();
      o.steps = std::strtol(v.c_str(), &end, 10);
      if (*end || o.steps < 1) usage("--steps must be a positive integer");
    } else if (a == "--dt") {
      const std::string v = value();
      o.dt = std::strtod(v.c_str(), &end);
      if (*end || !(o.dt > 0) || o.dt > 1) usage("--dt must be in (0, 1] s");
    } else if (a == "--model") {
      o.models.push_back(value());
    } else if (a == "--csv") {
      o.csv = value();
    } else if (!a.empty() && a[0] == '-') {
      usage("unknown option " + a);
    } else {
      o.dir = a;
    }
  }
  if (o.models.empty()) {
    std::error_code ec;
    for (const auto& e : std::filesystem::directory_iterator(o.dir, ec))
      if (e.path().extension() == ".urdf") o.models.push_back(e.path().string());
    if (ec) usage("cannot read " + o.dir + ": " + ec.message());
    std::sort(o.models.begin(), o.models.end());
    if (o.models.empty()) usage("no *.urdf in " + o.dir);
  }
  return o;
}

std::string fmt(const char* f, double v) {
  if (std::isnan(v)) return "-";
  char buf[64];
  std::snprintf(buf, sizeof buf, f, v);
  return buf;
}

// What makes the built System non-conservative (limits are watched while it runs).
std::string dissipation(const ms::MechanismModel& m) {
  const ms::System& sys = m.mechanism().system();
  std::vector<std::string> why;
  for (const ms::Dof& d : m.dofs()) {
    if (sys.damping[d.joint_index][d.k] != 0) why.push_back("damping on " + d.name);
    if (sys.friction[d.joint_index][d.k] != 0) why.push_back("friction on " + d.name);
    if (d.drive >= 0) why.push_back("drive on " + d.name);  // it does work on the mechanism
  }
  for (const ms::SpringDamper& s : sys.springs) {
    if (s.c != 0) why.push_back("damped spring " + s.name);
    if (s.f_act != 0) why.push_back("actuated spring " + s.name);
  }
  std::string out;
  for (const auto& w : why) out += (out.empty() ? "" : ", ") + w;
  return out;
}

Row soak(const std::string& path, const Options& o) {
  Row r;
  r.model = std::filesystem::path(path).filename().string();
  const auto load_start = Clock::now();
  std::unique_ptr<ms::MechanismModel> m;
  try {
    m = ms::loadModelFile(path);
  } catch (const std::exception& e) {
    r.failure = std::string("load: ") + e.what();
    return r;
  }
  r.load_wall = std::chrono::duration<double>(Clock::now() - load_start).count();
  const ms::System& sys = m->mechanism().system();
  r.not_conservative = dissipation(*m);

  auto energy = [&] { return m->kineticEnergy() + m->potentialEnergy(); };
  r.e0 = energy();
  r.ke_peak = m->kineticEnergy();
  r.max_phi = m->positionViolation();
  r.max_rel_phi = m->relativePositionViolation();
  r.max_vel = m->velocityViolation();
  r.max_rel_vel = m->relativeVelocityViolation();
  std::string limit_hit;
  auto watchLimits = [&] {
    const auto& side = m->mechanism().state().limit_side;
    for (size_t l = 0; l < side.size() && limit_hit.empty(); ++l)
      if (side[l]) {
        const ms::LimitSpec& spec = sys.limits[l];
        std::string dof = sys.joints[spec.joint]->name();
        const std::string k = sys.joints[spec.joint]->dofName(spec.k);
        if (!k.empty()) dof += "." + k;
        limit_hit = fmt("%.6g", m->time());
        limit_hit = "limit of " + dof + " active from t = " + limit_hit + " s";
      }
  };
  watchLimits();

  double step_seconds = 0;
  const long report_every = std::max(1L, o.steps / 10);
  const auto start = Clock::now();
  for (long k = 1; k <= o.steps; ++k) {
    const double t_before = m->time();
    const auto t0 = Clock::now();
    try {
      m->step(o.dt);
    } catch (const std::exception& e) {
      std::ostringstream os;
      os.precision(10);
      os << "step " << k << " from t = " << t_before << " s threw: " << e.what() << " (time() afterwards: "
         << m->time() << " s)";
      r.failure = os.str();
      break;
    }
    step_seconds += std::chrono::duration<double>(Clock::now() - t0).count();
    r.steps = k;
    const double phi = m->positionViolation(), e = energy(), ke = m->kineticEnergy();
    if (phi > r.max_phi) r.max_phi = phi, r.t_max_phi = m->time();
    r.max_rel_phi = std::max(r.max_rel_phi, m->relativePositionViolation());
    r.max_vel = std::max(r.max_vel, m->velocityViolation());
    r.max_rel_vel = std::max(r.max_rel_vel, m->relativeVelocityViolation());
    r.ke_peak = std::max(r.ke_peak, ke);
    const double de = std::fabs(e - r.e0);
    if (de > r.max_de) r.max_de = de, r.t_max_de = m->time();
    if (!std::isfinite(phi + e)) {
      std::ostringstream os;
      os << "non-finite state after step " << k << " (t = " << m->time() << " s): |Phi| " << phi << ", E " << e;
      r.failure = os.str();
      break;
    }
    if (limit_hit.empty()) watchLimits();
    if (k % report_every == 0) {
      std::fprintf(stderr, "  %s: %ld%% (t = %.0f s, %.1f s wall): E-E0 %.2e J, KE %.3g J, |Phi| %.1e\n",
                   r.model.c_str(), 100 * k / o.steps, m->time(),
                   std::chrono::duration<double>(Clock::now() - start).count(), e - r.e0, ke, phi);
      std::fflush(stderr);
    }
  }
  r.wall = std::chrono::duration<double>(Clock::now() - start).count();
  r.sim_time = m->time();
  r.step_wall = r.steps > 0 ? step_seconds / r.steps : NAN;
  r.final_de = energy() - r.e0;
  r.solver = m->solverStats().describe();
  if (!limit_hit.empty()) r.not_conservative += (r.not_conservative.empty() ? "" : ", ") + limit_hit;
  return r;
}

void printTable(const std::vector<Row>& rows) {
  std::printf(
      "| model | steps | sim time [s] | wall [s] | µs/step | max abs(Phi) | max rel. Phi | max abs(Phi_q v) "
      "| max rel. Phi_q v | E(0) [J] | KE peak [J] | max abs(E-E0) [J] | drift/KE | drift/max(KE,abs(E0)) "
      "| solver |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  for (const Row& r : rows) {
    const bool c = r.conservative();
    std::printf("| %s | %ld%s | %.0f | %.1f | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s |\n",
                r.model.c_str(), r.steps, r.failure.empty() ? "" : " (FAILED)", r.sim_time, r.wall,
                fmt("%.3g", r.step_wall * 1e6).c_str(), fmt("%.1e", r.max_phi).c_str(),
                fmt("%.1e", r.max_rel_phi).c_str(), fmt("%.1e", r.max_vel).c_str(),
                fmt("%.1e", r.max_rel_vel).c_str(), fmt("%.4g", r.e0).c_str(), fmt("%.4g", r.ke_peak).c_str(),
                fmt("%.1e", r.max_de).c_str(), c ? fmt("%.1e", r.driftKE()).c_str() : "n/c",
                c ? fmt("%.1e", r.driftScale()).c_str() : "n/c", r.solver.c_str());
  }
  std::printf("\nConservative (drift columns):\n");
  for (const Row& r : rows)
    if (r.conservative() && r.steps > 0)
      std::printf("- %s: largest abs(E-E0) at t = %.6g s; E(T)-E(0) = %.2e J; largest abs(Phi) at t = %.6g s\n",
                  r.model.c_str(), r.t_max_de, r.final_de, r.t_max_phi);
  std::printf("\nNot conservative (n/c: no drift claimed), because of:\n");
  for (const Row& r : rows)
    if (!r.conservative()) std::printf("- %s: %s\n", r.model.c_str(), r.not_conservative.c_str());
  bool failed = false;
  for (const Row& r : rows)
    if (!r.failure.empty()) {
      if (!failed) std::printf("\nFailures:\n");
      failed = true;
      std::printf("- %s: %s\n", r.model.c_str(), r.failure.c_str());
    }
}

void writeCsv(const std::string& path, const std::vector<Row>& rows, const Options& o) {
  std::ofstream f(path);
  if (!f) {
    std::fprintf(stderr, "bench_soak: cannot write %s\n", path.c_str());
    return;
  }
  f.precision(6);
  f << "model,dt,steps,sim_time,wall_s,us_per_step,load_s,max_abs_phi,t_max_abs_phi,max_rel_phi,max_abs_phi_q_v,"
       "max_rel_phi_q_v,e0,ke_peak,max_abs_de,t_max_abs_de,final_de,conservative,drift_ke,drift_scale,"
       "not_conservative,solver,failure\n";
  auto quote = [](const std::string& s) {
    std::string q = "\"";
    for (char c : s) q += c == '"' ? std::string("\"\"") : std::string(1, c);
    return q + "\"";
  };
  for (const Row& r : rows)
    f << r.model << ',' << o.dt << ',' << r.steps << ',' << r.sim_time << ',' << r.wall << ',' << r.step_wall * 1e6
      << ',' << r.load_wall << ',' << r.max_phi << ',' << r.t_max_phi << ',' << r.max_rel_phi << ',' << r.max_vel
      << ',' << r.max_rel_vel << ',' << r.e0 << ',' << r.ke_peak << ',' << r.max_de << ',' << r.t_max_de << ','
      << r.final_de << ',' << (r.conservative() ? 1 : 0) << ',' << r.driftKE() << ',' << r.driftScale() << ','
      << quote(r.not_conservative) << ',' << quote(r.solver) << ',' << quote(r.failure) << '\n';
}

}  // namespace

int main(int argc, char** argv) {
  const Options o = parse(argc, argv);
  const std::time_t now = std::time(nullptr);
  char date[64];
  std::strftime(date, sizeof date, "%Y-%m-%d %H:%M UTC", std::gmtime(&now));
  std::printf("bench_soak: %zu models, %ld steps of %g s each, started %s\n\n", o.models.size(), o.steps, o.dt, date);
  std::fflush(stdout);
  std::vector<Row> rows;
  for (const std::string& path : o.models) {
    std::fprintf(stderr, "%s\n", path.c_str());
    rows.push_back(soak(path, o));
    if (!rows.back().failure.empty()) std::fprintf(stderr, "  FAILED: %s\n", rows.back().failure.c_str());
  }
  printTable(rows);
  if (!o.csv.empty()) writeCsv(o.csv, rows, o);
  bool failed = false;
  for (const Row& r : rows) failed = failed || !r.failure.empty();
  return failed ? 1 : 0;
}
