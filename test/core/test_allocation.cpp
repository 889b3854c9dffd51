// Once built and assembled, a step allocates no heap memory. The counter sees the C heap,
// not only operator new: Eigen allocates its dynamic matrices with std::malloc (its
// aligned_malloc), so a VectorXd temporary in a step never passes through operator new.
// Without AddressSanitizer this program defines malloc and its relatives, forwarding to
// glibc's own allocator (__libc_malloc, ...: what it defines stays one heap, whoever
// frees it); operator new (libstdc++'s, which calls malloc) is counted through them.
// AddressSanitizer replaces malloc itself: then its allocation hooks count.
// MECHANISM_SIM_ALLOC_TRACE=1 prints a backtrace of every counted allocation (addresses:
// addr2line -e <library> -f -C -i <offset> names the line).
#include <gtest/gtest.h>

#include <errno.h>
#include <execinfo.h>
#include <unistd.h>

#include <atomic>
#include <cstdlib>
#include <functional>
#include <new>

#include "mechanism_sim/core/models.h"

#include "sanitizers.h"

namespace {
std::atomic<long> g_allocations{0};
std::atomic<bool> g_counting{false};
bool g_trace = false;
thread_local bool t_in_trace = false;

void counted() {
  if (!g_counting.load(std::memory_order_relaxed)) return;
  ++g_allocations;
  if (g_trace && !t_in_trace) {  // backtrace() was called once before counting: no allocation here
    t_in_trace = true;
    void* frames[32];
    const int n = backtrace(frames, 32);
    static const char kHeader[] = "-- allocation in the counted region:\n";
    ssize_t ignored = write(2, kHeader, sizeof(kHeader) - 1);
    (void)ignored;
    backtrace_symbols_fd(frames, n, 2);
    t_in_trace = false;
  }
}
}  // namespace

#ifdef MECHANISM_SIM_TEST_ASAN
extern "C" int __sanitizer_install_malloc_and_free_hooks(void (*malloc_hook)(const volatile void*, std::size_t),
                                                         void (*free_hook)(const volatile void*));
namespace {
void asanMallocHook(const volatile void*, std::size_t) { counted(); }
void asanFreeHook(const volatile void*) {}
bool installCounter() {
  static const bool installed = __sanitizer_install_malloc_and_free_hooks(&asanMallocHook, &asanFreeHook) != 0;
  return installed;
}
}  // namespace
#else
extern "C" {
void* __libc_malloc(std::size_t);
void* __libc_calloc(std::size_t, std::size_t);
void* __libc_realloc(void*, std::size_t);
void* __libc_memalign(std::size_t, std::size_t);
void __libc_free(void*);

void* malloc(std::size_t n) noexcept {
  counted();
  return __libc_malloc(n);
}
void* calloc(std::size_t n, std::size_t size) noexcept {
  counted();
  return __libc_calloc(n, size);
}
void* realloc(void* p, std::size_t n) noexcept {
  counted();
  return __libc_realloc(p, n);
}
void free(void* p) noexcept { __libc_free(p); }
void* memalign(std::size_t alignment, std::size_t n) noexcept {
  counted();
  return __libc_memalign(alignment, n);
}
void* aligned_alloc(std::size_t alignment, std::size_t n) noexcept {
  counted();
  return __libc_memalign(alignment, n);
}
int posix_memalign(void** out, std::size_t alignment, std::size_t n) noexcept {
  if (alignment % sizeof(void*) != 0 || (alignment & (alignment - 1)) != 0) return EINVAL;
  counted();
  void* p = __libc_memalign(alignment, n);
  if (!p) return ENOMEM;
  *out = p;
  return 0;
}
void* valloc(std::size_t n) noexcept {
  counted();
  return __libc_memalign(static_cast<std::size_t>(sysconf(_SC_PAGESIZE)), n);
}
}  // extern "C"
namespace {
bool installCounter() { return true; }
}  // namespace
#endif

namespace mechanism_sim {
namespace {

// Allocations counted while body() runs; false (and a failure) if no counter could be set.
bool countIn(const std::function<void()>& body, long* allocations) {
  if (!installCounter()) {
    ADD_FAILURE() << "AddressSanitizer's allocation hooks could not be installed";
    return false;
  }
  static const bool warm = [] {  // loads what backtrace() needs before anything is counted
    g_trace = std::getenv("MECHANISM_SIM_ALLOC_TRACE") != nullptr;
    void* frames[4];
    return backtrace(frames, 4) > 0;
  }();
  (void)warm;
  g_allocations = 0;
  g_counting = true;
  body();
  g_counting = false;
  *allocations = g_allocations;
  return true;
}

// Steps with, after each, extra() inside the counted region (a test's injected temporary).
long allocationsIn(Mechanism& m, int steps, const std::function<void()>& extra = {}) {
  long n = -1;
  countIn(
      [&] {
        for (int s = 0; s < steps; ++s) {
          m.step(1e-3);
          if (extra) extra();
        }
      },
      &n);
  return n;
}

void buildChain(Mechanism& chain) {
  models::pendulumChain(chain, 20, 0.5, 1.0, 0.3);
  chain.build();
  chain.assemble();
  chain.setJointDamping(3, 0, 0.1);
  chain.setJointEffort(4, 0, 0.5);
}

void buildLoops(Mechanism& loops) {
  models::fourBarChain(loops, 10);
  loops.setJointLimits(0, 0, -0.2, 0.2);
  loops.build();
  loops.assemble();
}

TEST(Allocation, CounterSeesOperatorNew) {
  long n = -1;
  std::vector<double>* v = nullptr;
  ASSERT_TRUE(countIn([&] { v = new std::vector<double>(100, 1.0); }, &n));
  EXPECT_EQ(n, 2);  // the vector and its storage
  delete v;
}

// What the operator-new counter missed: an Eigen temporary (std::malloc) and the other
// entry points of the C heap, each counted once.
TEST(Allocation, CounterSeesTheCHeap) {
  volatile double sink = 0;
  long n = -1;
  ASSERT_TRUE(countIn(
      [&] {
        Eigen::VectorXd a = Eigen::VectorXd::LinSpaced(50, 0.0, 1.0);
        sink = sink + a.sum();
      },
      &n));
  EXPECT_EQ(n, 1);
  void* p = nullptr;
  ASSERT_TRUE(countIn(
      [&] {
        p = std::calloc(3, 8);
        p = std::realloc(p, 4000);
        std::free(p);
        p = std::aligned_alloc(64, 128);
        std::free(p);
        if (posix_memalign(&p, 64, 100) == 0) std::free(p);
      },
      &n));
  EXPECT_EQ(n, 4);
  EXPECT_NEAR(sink, 25.0, 1e-12);  // the sum of 50 points spread evenly over [0, 1]
}

// The counter sees a temporary of the mechanism's size added to a step: one per step.
TEST(Allocation, StepWithAnInjectedTemporaryIsCounted) {
  Mechanism chain;
  buildChain(chain);
  volatile double sink = 0;
  const long n = allocationsIn(chain, 50, [&] {
    const Eigen::VectorXd doubled = 2.0 * chain.state().u;  // a VectorXd temporary
    sink = sink + doubled.squaredNorm();
  });
  EXPECT_EQ(n, 50);
  EXPECT_GT(sink, 0.0);
}

TEST(Allocation, StepAllocatesNothing) {
  Mechanism chain;
  buildChain(chain);
  EXPECT_EQ(allocationsIn(chain, 200), 0);

  Mechanism loops;
  buildLoops(loops);
  EXPECT_EQ(allocationsIn(loops, 200), 0);

  // the joint formulation (joint_stepper.h) on a chain with an effort and a spring
  Mechanism joint;
  models::pendulumChain(joint, 20, 0.5, 1.0, 0.3);
  SpringDamper spring;
  spring.name = "tie";
  spring.body_i = 2, spring.body_j = 7, spring.k = 50.0, spring.c = 0.2;
  joint.addSpring(spring);
  IntegratorOptions io;
  io.formulation = "joint";
  joint.setIntegrator(io);
  joint.build();
  joint.assemble();
  joint.setJointEffort(4, 0, 0.5);
  ASSERT_STREQ(joint.formulation(), "joint");
  joint.step(1e-3);  // (the first step after an input changed computes its stage 1)
  EXPECT_EQ(allocationsIn(joint, 200), 0);

  // ... with a coupler and damping, stiff on the last joint (h c / I about 10 at 1 ms):
  // the implicit step subject to the closures (JointStepper::implicitDamping); and Coulomb
  // friction, sliding on one joint and holding another (JointStepper::frictionFor)
  Mechanism damped;
  models::pendulumChain(damped, 6, 0.5, 1.0, 0.3);
  for (int k = 0; k < 6; ++k) damped.setJointDamping(k, 0, k == 5 ? 1000.0 : 0.1);
  damped.setJointFriction(1, 0, 0.05);
  damped.setJointFriction(4, 0, 50.0);
  damped.addCoupler("mimic", 3, 0, 2, 0, 0.5, 0.0);
  damped.setIntegrator(io);
  damped.build();
  damped.assemble();
  ASSERT_STREQ(damped.formulation(), "joint");
  damped.step(1e-3);
  EXPECT_EQ(allocationsIn(damped, 200), 0);
}

}  // namespace
}  // namespace mechanism_sim
