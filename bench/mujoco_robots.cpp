// CPU time a step of real robot files here and in MuJoCo 2.2.2 (libmujoco-dev) loading the
// same URDF, RK4 at 1 ms in both, in one process and interleaved (these machines are
// noisy: compare the ratio of one run). Issue 20 asks for the 7-dof arm and the quadruped of
// ../shared/robots to be no slower a step than MuJoCo RK4. Figures in bench/RESULTS.md.
//
//   bench_mujoco_robots [--steps N] [--repeats R] [--formulation auto|joint|absolute] FILE...
//
// What MuJoCo is given: the file's text without <visual> and <collision> (no meshes to load;
// neither engine simulates contact here) and <mujoco><compiler boundinertia="1e-12"/>, which
// MuJoCo needs for the point-mass links of legged robots ("mass and inertia of moving
// bodies must be larger than mjMINVAL"; 1e-12 kg m^2 changes nothing measurable). Its URDF
// defaults otherwise: static bodies fused (this loader merges fixed joints alike), root
// welded to the world, joint damping from <dynamics>, limits as soft constraints (here hard
// stops), contacts off. Both start at the zero pose, at rest; each run is N steps from a
// fresh state, timed without the load (the median of R runs).
#include <mujoco/mujoco.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <unistd.h>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "cpu_time.h"
#include "mechanism_sim/core/mechanism.h"
#include "mechanism_sim/urdf/model.h"

namespace {

using bench::cpuSeconds;
using bench::median;

std::string mujocoText(const std::string& urdf) {
  std::string x = std::regex_replace(urdf, std::regex("<(visual|collision)\\b(?:(?!</\\1>)[^])*</\\1>"), "");
  x = std::regex_replace(x, std::regex("<(visual|collision)\\b[^>]*/>"), "");
  if (x.find("<mujoco") != std::string::npos) return x;  // the file's own compiler options
  return std::regex_replace(x, std::regex("(<robot\\b[^>]*>)"),
                            "$1<mujoco><compiler boundinertia=\"1e-12\"/></mujoco>",
                            std::regex_constants::format_first_only);
}

}  // namespace

int main(int argc, char** argv) {
  int steps = 5000, repeats = 5;
  std::string formulation = "auto";
  std::vector<std::string> files;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--steps" && i + 1 < argc) steps = std::atoi(argv[++i]);
    else if (a == "--repeats" && i + 1 < argc) repeats = std::atoi(argv[++i]);
    else if (a == "--formulation" && i + 1 < argc) formulation = argv[++i];
    else if (!a.empty() && a[0] == '-') {
      std::fprintf(stderr, "usage: %s [--steps N] [--repeats R] [--formulation auto|joint|absolute] FILE...\n", argv[0]);
      return 2;
    } else files.push_back(a);
  }
  if (files.empty() || steps < 1 || repeats < 1) {
    std::fprintf(stderr, "usage: %s [--steps N] [--repeats R] [--formulation auto|joint|absolute] FILE...\n", argv[0]);
    return 2;
  }
  constexpr double h = 1e-3;
  std::printf("| robot | dofs (MuJoCo) | formulation here | µs a step, MuJoCo RK4 | µs a step, here | ratio |\n");
  std::printf("|---|---|---|---|---|---|\n");
  int status = 0;
  for (const std::string& file : files) {
    std::ifstream in(file);
    if (!in) {
      std::fprintf(stderr, "%s: cannot read\n", file.c_str());
      status = 1;
      continue;
    }
    std::stringstream text;
    text << in.rdbuf();
    const std::string tmp = "/tmp/bench_mujoco_robots_" + std::to_string(getpid()) + ".urdf";
    std::ofstream(tmp) << mujocoText(text.str());
    char error[1000] = "";
    mjModel* m = mj_loadXML(tmp.c_str(), nullptr, error, sizeof error);
    std::remove(tmp.c_str());
    if (!m) {
      std::fprintf(stderr, "%s: MuJoCo: %s\n", file.c_str(), error);
      status = 1;
      continue;
    }
    m->opt.timestep = h;
    m->opt.integrator = mjINT_RK4;
    m->opt.disableflags |= mjDSBL_CONTACT;
    mjData* d = mj_makeData(m);
    mechanism_sim::LoadOptions options;
    options.formulation = formulation;
    std::string ran;
    std::vector<double> mj, here;
    try {
      for (int r = 0; r < repeats; ++r) {
        mj_resetData(m, d);
        double t0 = cpuSeconds();
        for (int k = 0; k < steps; ++k) mj_step(m, d);
        mj.push_back((cpuSeconds() - t0) / steps * 1e6);
        auto model = mechanism_sim::loadModelFile(file, options);
        mechanism_sim::Mechanism& mech = model->mechanism();
        t0 = cpuSeconds();
        for (int k = 0; k < steps; ++k) mech.step(h);
        here.push_back((cpuSeconds() - t0) / steps * 1e6);
        ran = mech.formulation();
      }
    } catch (const std::exception& e) {
      std::fprintf(stderr, "%s: %s\n", file.c_str(), e.what());
      status = 1;
    }
    if (!here.empty())
      std::printf("| %s | %d | %s | %.1f | %.1f | %.2f |\n", file.c_str(), m->nv, ran.c_str(), median(mj), median(here),
                  median(here) / median(mj));
    std::fflush(stdout);
    mj_deleteData(d);
    mj_deleteModel(m);
  }
  return status;
}
