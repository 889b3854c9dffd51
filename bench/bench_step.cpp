// Cost of one integration step (RK4 + projections, the default) for an N-link pendulum
// chain and a chain of N four-bar loops, N = 1 .. 400. Results: bench/RESULTS.md.
#include <benchmark/benchmark.h>

#include "mechanism_sim/core/models.h"

using namespace mechanism_sim;

static void run(benchmark::State& state, Mechanism& m) {
  m.build();
  m.assemble();
  for (int i = 0; i < 10; ++i) m.step(1e-3);  // warm up
  for (auto _ : state) m.step(1e-3);
  state.counters["bodies"] = m.numBodies() - 1;
  state.counters["equations"] = m.numEquations();
  state.counters["violation"] = m.positionViolation();
}

static void BM_PendulumChain(benchmark::State& state) {
  Mechanism m;
  models::pendulumChain(m, static_cast<int>(state.range(0)), 0.5, 1.0, 0.3);
  run(state, m);
}

static void BM_FourBarChain(benchmark::State& state) {
  Mechanism m;
  models::fourBarChain(m, static_cast<int>(state.range(0)));
  run(state, m);
}

BENCHMARK(BM_PendulumChain)->Arg(1)->Arg(2)->Arg(5)->Arg(10)->Arg(25)->Arg(50)->Arg(100)->Arg(200)->Arg(400)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_FourBarChain)->Arg(1)->Arg(2)->Arg(5)->Arg(10)->Arg(25)->Arg(50)->Arg(100)->Arg(200)->Arg(400)->Unit(benchmark::kMicrosecond);
BENCHMARK_MAIN();
