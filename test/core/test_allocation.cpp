// Once built and assembled, a step allocates no heap memory: counted by replacing the
// global operator new for this test program.
#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>
#include <new>

#include "mechanism_sim/core/models.h"

namespace {
std::atomic<long> g_allocations{0};
std::atomic<bool> g_counting{false};
}  // namespace

void* operator new(std::size_t size) {
  if (g_counting) ++g_allocations;
  if (void* p = std::malloc(size ? size : 1)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }

namespace mechanism_sim {
namespace {

long allocationsIn(Mechanism& m, int steps) {
  g_allocations = 0;
  g_counting = true;
  for (int s = 0; s < steps; ++s) m.step(1e-3);
  g_counting = false;
  return g_allocations;
}

TEST(Allocation, CounterSeesAnAllocation) {
  g_allocations = 0;
  g_counting = true;
  std::vector<double>* v = new std::vector<double>(100, 1.0);
  g_counting = false;
  EXPECT_GE(g_allocations.load(), 2);  // the vector and its storage
  delete v;
}

TEST(Allocation, StepAllocatesNothing) {
  Mechanism chain;
  models::pendulumChain(chain, 20, 0.5, 1.0, 0.3);
  chain.build();
  chain.assemble();
  chain.setJointDamping(3, 0, 0.1);
  chain.setJointEffort(4, 0, 0.5);
  EXPECT_EQ(allocationsIn(chain, 200), 0);

  Mechanism loops;
  models::fourBarChain(loops, 10);
  loops.setJointLimits(0, 0, -0.2, 0.2);
  loops.build();
  loops.assemble();
  EXPECT_EQ(allocationsIn(loops, 200), 0);
}

}  // namespace
}  // namespace mechanism_sim
