// bench_factor: the step's linear algebra against the library baselines (issue 7, item 4).
// For harness mechanisms (bench/harness_models.h) at their assembled state, H =
// M + kappa Phi_q^T W Phi_q (loops) or the tree KKT matrix [M J^T; J 0] (chains, "-kkt")
// is built exactly as the stepper builds it (evaluateAt, rowWeights, PenaltyForm::assemble
// with ConstraintSolver::kKappa, or TreeKktSolver::assembleKKT), then one numeric factorization and one solve are timed
// per iteration with
//   BlockCholesky      the core's 6x6 block Cholesky (factorize(0, false) + solve; on the
//                      KKT matrix its signed L S L^T in the tree order);
//   EigenLDLT          Eigen's SimplicialLDLT, AMD order (KKT: the tree order), pattern
//                      analysed once;
//   CholmodSupernodal  CHOLMOD's supernodal LL^T, analysed once (default orderings);
//   CholmodSimplicial  CHOLMOD's simplicial LDL^T, analysed once (KKT: the tree order);
//   SparseLDLT         the core's scalar up-looking LDL^T (the step's former factorization,
//                      now used by assembly), AMD order from Eigen.
// Every iteration first copies H's values into the library's own storage (the block array,
// or the values of a compressed-column matrix), standing in for the assembly that would
// write them there; `copy` times that copy alone for the block storage. The pattern is H's
// full 6x6 block pattern (what a fixed-pattern assembly writes). Counters: nnz_L (stored
// entries of the factor), rel_residual |H x - b| / |b| of the solve.
// After the runs a summary table gives CPU ns per factorization + solve.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include <unistd.h>

#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <benchmark/benchmark.h>

#include "harness_models.h"
#include "core/absolute/solver.h"
#if __has_include("mechanism_sim/core/sparse_ldlt.h")
#include "core/linalg/sparse_ldlt.h"
#define HAVE_SPARSE_LDLT 1
#endif
#ifdef MECHANISM_SIM_HAVE_CHOLMOD
#include <cholmod.h>
#endif

namespace ms = mechanism_sim;
using SpMat = Eigen::SparseMatrix<double, Eigen::ColMajor, int>;

namespace {

// The matrix of one case at its assembled state, as the stepper's block storage holds it
// before factorization and as compressed columns (lower triangle, and both triangles): H,
// or with `kkt` the tree KKT matrix [M J^T; J 0] (bodies and tree joints as block rows,
// TreeKktSolver::assembleKKT), whose libraries get the stepper's elimination order (any other
// order may meet a joint's zero block first).
struct Problem {
  std::string name;
  bool kkt = false;
  std::unique_ptr<ms::MechanismModel> model;
  ms::SolverStats stats;
  ms::Evaluation ev;
  std::unique_ptr<ms::ConstraintSolver> solver;
  ms::BlockCholesky* ch = nullptr;
  std::vector<ms::BlockCholesky::Block> blocks;
  SpMat lower, full, lower_p, full_p;  // _p: in elimination order (kkt)
  Eigen::VectorXd b_p;
  std::vector<int> order;  // pivot k -> row (kkt)
  Eigen::VectorXd b;
  int n = 0;

  Problem(const std::string& label, const std::string& kase, int N, bool tree) : name(label), kkt(tree) {
    model = harness::loadCase(kase, N);
    const ms::System& sys = model->mechanism().system();
    const ms::State& s = model->mechanism().state();
    ev = ms::Evaluation(sys);
    ms::evaluateAt(sys, s, ev);
    ms::rowWeights(sys, ev, sys.all_constraints);
    if (kkt) {
      if (!ms::kktTopology(sys).tree) throw std::runtime_error(label + ": not a tree");
      auto tree = std::make_unique<ms::TreeKktSolver>(sys, ms::kktTopology(sys), stats);
      ch = &tree->kkt();
      tree->assembleKKT(sys, ev);  // as TreeKktSolver::factor does
      solver = std::move(tree);
    } else {
      solver = std::make_unique<ms::PenaltySolver>(sys, stats);
      ch = &solver->penalty().cholesky();
      solver->penalty().assemble(sys, ev, ms::ConstraintSolver::kKappa, 1.0, 0.0);  // as PenaltyForm::factor does
    }
    for (int a = 0; a < ch->size() + ch->offDiagonalBlocks(); ++a) blocks.push_back(ch->block(a));
    // the stored blocks: H(i, j) at its address
    std::vector<Eigen::Triplet<double>> t;
    for (const auto& e : ch->storedBlocks()) {
      const ms::BlockCholesky::Block& B = ch->block(e[2]);
      for (int r = 0; r < 6; ++r)
        for (int c = 0; c < 6; ++c) {
          t.emplace_back(6 * e[0] + r, 6 * e[1] + c, B(r, c));
          if (e[0] != e[1]) t.emplace_back(6 * e[1] + c, 6 * e[0] + r, B(r, c));
        }
    }
    n = 6 * ch->size();
    for (int k = 0; k < ch->size(); ++k)
      for (int r = 0; r < 6; ++r) order.push_back(6 * ch->pivot(k) + r);
    full.resize(n, n);
    full.setFromTriplets(t.begin(), t.end());  // explicit zeros inside blocks are kept
    lower = full.triangularView<Eigen::Lower>();
    lower.makeCompressed();
    b = Eigen::VectorXd::LinSpaced(n, 1.0, 2.0);
    if (kkt) {  // the same in elimination order: row order[i] becomes row i
      Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> P(n);
      for (int i = 0; i < n; ++i) P.indices()[order[i]] = i;
      full_p = full.twistedBy(P);
      lower_p = full_p.triangularView<Eigen::Lower>();
      lower_p.makeCompressed();
      b_p = P * b;
    }
  }

  double residual(const Eigen::VectorXd& x) const { return (full * x - b).norm() / b.norm(); }
};

std::vector<std::unique_ptr<Problem>> g_problems;

void copyValues(const SpMat& from, SpMat& to) {
  std::copy(from.valuePtr(), from.valuePtr() + from.nonZeros(), to.valuePtr());
}

void BM_Copy(benchmark::State& state, Problem* p) {
  ms::BlockCholesky& ch = *p->ch;
  for (auto _ : state) {
    for (size_t a = 0; a < p->blocks.size(); ++a) ch.block(static_cast<int>(a)) = p->blocks[a];
    benchmark::ClobberMemory();
  }
}

void BM_BlockCholesky(benchmark::State& state, Problem* p) {
  ms::BlockCholesky& ch = *p->ch;
  Eigen::VectorXd x(p->n);
  for (auto _ : state) {
    for (size_t a = 0; a < p->blocks.size(); ++a) ch.block(static_cast<int>(a)) = p->blocks[a];
    if (ch.factorize(0.0, false) != 0) {
      state.SkipWithError("zero pivot");
      break;
    }
    x = p->b;
    ch.solve(x.data());
    benchmark::DoNotOptimize(x.data());
  }
  state.counters["nnz_L"] = 36.0 * ch.offDiagonalBlocks() + 21.0 * ch.size();
  state.counters["rel_residual"] = p->residual(x);
}

// Eigen's SimplicialLDLT: AMD order on H; on the tree KKT matrix the stepper's order (the
// matrix permuted to it once, NaturalOrdering: AMD may eliminate a joint's zero block first).
template <typename Ordering>
void runEigenLDLT(benchmark::State& state, const SpMat& lower, const SpMat& full, const Eigen::VectorXd& b) {
  SpMat A = lower;
  Eigen::SimplicialLDLT<SpMat, Eigen::Lower, Ordering> ldlt;
  ldlt.analyzePattern(A);
  Eigen::VectorXd x(b.size());
  for (auto _ : state) {
    copyValues(lower, A);
    ldlt.factorize(A);
    x = ldlt.solve(b);
    benchmark::DoNotOptimize(x.data());
  }
  if (ldlt.info() != Eigen::Success) state.SkipWithError("Eigen: factorization failed");
  state.counters["nnz_L"] = static_cast<double>(ldlt.matrixL().nestedExpression().nonZeros() + b.size());
  state.counters["rel_residual"] = (full * x - b).norm() / b.norm();
}

void BM_EigenLDLT(benchmark::State& state, Problem* p) {
  if (p->kkt) runEigenLDLT<Eigen::NaturalOrdering<int>>(state, p->lower_p, p->full_p, p->b_p);
  else runEigenLDLT<Eigen::AMDOrdering<int>>(state, p->lower, p->full, p->b);
}

#ifdef HAVE_SPARSE_LDLT
void BM_SparseLDLT(benchmark::State& state, Problem* p) {
  Eigen::AMDOrdering<int> amd;
  Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> P;
  amd(p->full, P);
  const std::vector<int> perm(P.indices().data(), P.indices().data() + p->n);
  const std::vector<int> Ap(p->full.outerIndexPtr(), p->full.outerIndexPtr() + p->n + 1);
  const std::vector<int> Ai(p->full.innerIndexPtr(), p->full.innerIndexPtr() + p->full.nonZeros());
  ms::SparseLDLT ldlt;
  ldlt.analyze(p->n, Ap, Ai, perm);
  std::vector<double> Ax(p->full.valuePtr(), p->full.valuePtr() + p->full.nonZeros());
  Eigen::VectorXd x(p->n);
  for (auto _ : state) {
    std::copy(p->full.valuePtr(), p->full.valuePtr() + p->full.nonZeros(), Ax.begin());
    if (ldlt.factorize(Ax.data(), 0.0, false) != 0) {
      state.SkipWithError("zero pivot");
      break;
    }
    x = p->b;
    ldlt.solve(x.data());
    benchmark::DoNotOptimize(x.data());
  }
  state.counters["rel_residual"] = p->residual(x);
}
#endif

#ifdef MECHANISM_SIM_HAVE_CHOLMOD
void BM_Cholmod(benchmark::State& state, Problem* p, int supernodal) {
  cholmod_common c;
  cholmod_start(&c);
  c.supernodal = supernodal;
  if (p->kkt) {  // simplicial LDL^T in the stepper's order (the matrix is permuted to it)
    c.nmethods = 1;
    c.method[0].ordering = CHOLMOD_NATURAL;
    c.postorder = false;
  }
  const SpMat& H = p->kkt ? p->lower_p : p->lower;
  const Eigen::VectorXd& rhs = p->kkt ? p->b_p : p->b;
  cholmod_sparse* A = cholmod_allocate_sparse(p->n, p->n, H.nonZeros(), 1, 1, -1, CHOLMOD_REAL, &c);
  std::copy(H.outerIndexPtr(), H.outerIndexPtr() + p->n + 1, static_cast<int*>(A->p));
  std::copy(H.innerIndexPtr(), H.innerIndexPtr() + H.nonZeros(), static_cast<int*>(A->i));
  double* Ax = static_cast<double*>(A->x);
  std::copy(H.valuePtr(), H.valuePtr() + H.nonZeros(), Ax);
  cholmod_factor* L = cholmod_analyze(A, &c);
  cholmod_dense* B = cholmod_allocate_dense(p->n, 1, p->n, CHOLMOD_REAL, &c);
  std::copy(rhs.data(), rhs.data() + p->n, static_cast<double*>(B->x));
  cholmod_dense *X = nullptr, *Y = nullptr, *E = nullptr;
  for (auto _ : state) {
    std::copy(H.valuePtr(), H.valuePtr() + H.nonZeros(), Ax);
    cholmod_factorize(A, L, &c);
    cholmod_solve2(CHOLMOD_A, L, B, nullptr, &X, nullptr, &Y, &E, &c);
    benchmark::DoNotOptimize(X->x);
  }
  if (c.status != CHOLMOD_OK || !X) {
    state.SkipWithError("CHOLMOD failed");
  } else {
    const Eigen::Map<const Eigen::VectorXd> x(static_cast<const double*>(X->x), p->n);
    state.counters["rel_residual"] = p->kkt ? (p->full_p * x - rhs).norm() / rhs.norm() : p->residual(x);
    state.counters["nnz_L"] = c.lnz;
    state.counters["supernodal"] = L->is_super;
  }
  cholmod_free_dense(&X, &c), cholmod_free_dense(&Y, &c), cholmod_free_dense(&E, &c);
  cholmod_free_dense(&B, &c);
  cholmod_free_factor(&L, &c);
  cholmod_free_sparse(&A, &c);
  cholmod_finish(&c);
}
#endif

// Console output as usual, and the real time per iteration of every run kept for the summary.
class SummaryReporter : public benchmark::ConsoleReporter {
 public:
  SummaryReporter() : ConsoleReporter(isatty(STDOUT_FILENO) ? OO_ColorTabular : OO_Tabular) {}
  void ReportRuns(const std::vector<Run>& runs) override {
    for (const Run& r : runs)
      if (r.run_type == Run::RT_Iteration && !r.error_occurred) {
        const std::string name = r.run_name.function_name;
        const size_t slash = name.find('/');
        ns_[name.substr(0, slash)][name.substr(slash + 1)].push_back(r.GetAdjustedCPUTime());
      }
    ConsoleReporter::ReportRuns(runs);
  }
  // Markdown: one row per case, median ns per library (and the factor against BlockCholesky).
  // CPU time: single-threaded code, and on a loaded machine it excludes the time other
  // processes held the core (the console table above has both).
  void summary(const std::vector<std::string>& cases, const std::vector<std::string>& libs) {
    std::printf("\nCPU ns per (value copy + numeric factorization + one solve); in parentheses: / BlockCholesky\n\n");
    std::printf("| case | n |");
    for (const auto& l : libs) std::printf(" %s |", l.c_str());
    std::printf("\n|---|---|");
    for (size_t i = 0; i < libs.size(); ++i) std::printf("---|");
    std::printf("\n");
    for (size_t k = 0; k < cases.size(); ++k) {
      const std::string& c = cases[k];
      if (ns_.find(c) == ns_.end()) continue;  // filtered out
      std::printf("| %s | %d |", c.c_str(), g_problems[k]->n);
      const double base = median(c, "BlockCholesky");
      for (const auto& l : libs) {
        const double t = median(c, l);
        if (std::isnan(t)) std::printf(" - |");
        else if (l == "BlockCholesky" || std::isnan(base)) std::printf(" %.0f |", t);
        else std::printf(" %.0f (%.2f) |", t, t / base);
      }
      std::printf("\n");
    }
  }

 private:
  double median(const std::string& c, const std::string& l) {
    auto& v = ns_[c][l];
    if (v.empty()) return NAN;
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];
  }
  std::map<std::string, std::map<std::string, std::vector<double>>> ns_;
};

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  // H of the chains (their former factorization), the tree KKT matrix the chains now
  // factor, and H of the four-bars (loops keep it)
  struct Case {
    std::string label, kase;
    int N;
    bool kkt;
  };
  const std::vector<Case> cases = {{"chain50", "chain", 50, false},      {"chain200", "chain", 200, false},
                                   {"chain50-kkt", "chain", 50, true},   {"chain200-kkt", "chain", 200, true},
                                   {"fourbar10", "fourbar", 10, false}, {"fourbar50", "fourbar", 50, false}};
  std::vector<std::string> names, libs = {"BlockCholesky", "EigenLDLT"};
#ifdef MECHANISM_SIM_HAVE_CHOLMOD
  libs.push_back("CholmodSupernodal");
  libs.push_back("CholmodSimplicial");
#endif
#ifdef HAVE_SPARSE_LDLT
  libs.push_back("SparseLDLT");
#endif
  libs.push_back("copy");
  for (const Case& c : cases) {
    g_problems.emplace_back(new Problem(c.label, c.kase, c.N, c.kkt));
    Problem* p = g_problems.back().get();
    names.push_back(c.label);
    auto reg = [&](const std::string& lib, void (*fn)(benchmark::State&, Problem*)) {
      benchmark::RegisterBenchmark((c.label + "/" + lib).c_str(), fn, p);
    };
    reg("BlockCholesky", BM_BlockCholesky);
    reg("EigenLDLT", BM_EigenLDLT);
#ifdef MECHANISM_SIM_HAVE_CHOLMOD
    if (!c.kkt)  // supernodal CHOLMOD is LL^T: not for an indefinite matrix
      benchmark::RegisterBenchmark((c.label + "/CholmodSupernodal").c_str(), BM_Cholmod, p, CHOLMOD_SUPERNODAL);
    benchmark::RegisterBenchmark((c.label + "/CholmodSimplicial").c_str(), BM_Cholmod, p, CHOLMOD_SIMPLICIAL);
#endif
#ifdef HAVE_SPARSE_LDLT
    if (!c.kkt) reg("SparseLDLT", BM_SparseLDLT);  // its pivots must be positive
#endif
    reg("copy", BM_Copy);
  }
  SummaryReporter reporter;
  benchmark::RunSpecifiedBenchmarks(&reporter);
  reporter.summary(names, libs);
  benchmark::Shutdown();
  return 0;
}
