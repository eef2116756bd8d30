// Interpreter throughput benchmark (prints figures; never a test).
//
// Measures the block interpreter (Interpreter::evalBlock over a Dataset) in row-ops/s, i.e.
// effective opcode evaluations x rows per second, on two fixed programs:
//   arith  20 effective opcodes of add/sub/mul/mad/min/max over 2 inputs and constants
//   trans  20 effective opcodes, 10 of them exp2/log2/exp/log/pow/sin/cos/sqrt/rsqrt
// and compares, in the same run, against
//   scalar    the naive per-row interpreter (evaluateScalarRows: switch per opcode per row)
//   compiled  the same expression hand-written as one fused loop over rows calling
//             sem::apply<Op, float> inline (same vectorised math, same protected semantics,
//             intermediates in registers): what an ahead-of-time compiler would produce; also
//             2- and 4-way interleaved variants (see fused<>), since the plain loop is
//             latency-bound on the transcendental program.
// Then prints per-operator kernel throughput, two prototypes of suggested library fixes
// (two-pass pow, pair fusion), a block-size sweep on the arithmetic program and a summary
// against the targets (>= 5e9 / 1e9 row-ops/s per core, >= 0.5x compiled, >= 20x scalar).
//
// Method: every figure is the median of `--reps` repetitions; each repetition runs the
// measured work enough times to take about `--min-ms` milliseconds. By default time is the
// CPU time of the measuring thread (max over threads when multi-threaded), which leaves out
// time spent descheduled: on a loaded, shared machine it estimates the unloaded figure, where
// wall time would measure the other tenants (--clock wall gives wall time). Multi-threaded figures
// use OpenMP over blocks (interpreter; one Interpreter per thread, created outside the timing) or
// over row ranges (compiled). The outputs are checked: interpreter, compiled and scalar must
// agree bit for bit, since all three use sem::apply<Op, float> with -ffp-contract=off.
//
// Usage: interp_bench [--rows N] [--reps N] [--min-ms MS] [--threads N] [--clock cpu|wall]
//                     [--quick]
#include <benchmark/benchmark.h>
#include <omp.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "bench_util.hpp"
#include "lgp/core/program.hpp"
#include "lgp/core/table.hpp"
#include "lgp/eval/interpreter.hpp"
#include "lgp/eval/semantics.hpp"

namespace {

using lgp::Instr;
using lgp::Op;
using lgp::Operand;
using lgp::OperandKind;
using lgp::Program;

// ---------------------------------------------------------------------------------------------
// Benchmark programs. x(i) input column, c(i) constant slot, r(i) result of opcode i.

Operand x(int i) {
  return {OperandKind::Var, static_cast<uint8_t>(i)};
}
Operand c(int i) {
  return {OperandKind::Const, static_cast<uint8_t>(i)};
}
Operand r(int i) {
  return {OperandKind::Reg, static_cast<uint8_t>(i)};
}

Instr ins(Op op, Operand a, Operand b = {}, Operand cc = {}, Operand d = {}) {
  Instr in;
  in.op = op;
  in.args = {a, b, cc, d};
  return in;
}

constexpr float kC0 = 0.5f, kC1 = 1.5f, kC2 = -0.25f, kC3 = 2.0f, kC4 = 0.75f, kC5 = 0.125f;

Program arithProgram() {
  Program p;
  p.constants = {kC0, kC1, kC2, kC3, kC4, kC5};
  p.code = {
      ins(Op::Mul, x(0), x(1)),         // r0
      ins(Op::Mad, x(0), c(0), x(1)),   // r1
      ins(Op::Sub, r(0), r(1)),         // r2
      ins(Op::Add, r(2), c(1)),         // r3
      ins(Op::Max, r(3), x(0)),         // r4
      ins(Op::Min, r(4), c(3)),         // r5
      ins(Op::Mad, r(5), r(1), r(0)),   // r6
      ins(Op::Mul, r(6), c(2)),         // r7
      ins(Op::Add, r(7), x(1)),         // r8
      ins(Op::Sub, r(8), r(5)),         // r9
      ins(Op::Mad, r(9), r(9), c(4)),   // r10
      ins(Op::Min, r(10), r(3)),        // r11
      ins(Op::Max, r(11), c(2)),        // r12
      ins(Op::Mul, r(12), x(0)),        // r13
      ins(Op::Add, r(13), r(6)),        // r14
      ins(Op::Mad, r(14), c(5), r(2)),  // r15
      ins(Op::Sub, r(15), x(1)),        // r16
      ins(Op::Max, r(16), r(8)),        // r17
      ins(Op::Mul, r(17), r(17)),       // r18
      ins(Op::Add, r(18), r(12)),       // r19
  };
  p.outputs = {19};
  return p;
}

Program transProgram() {
  Program p;
  p.constants = {kC0, kC1};
  p.code = {
      ins(Op::Mad, x(0), c(0), x(1)),    // r0
      ins(Op::Exp2, r(0)),               // r1
      ins(Op::Add, r(1), x(0)),          // r2
      ins(Op::Log2, r(2)),               // r3
      ins(Op::Sin, r(3)),                // r4
      ins(Op::Mul, r(4), x(1)),          // r5
      ins(Op::Exp, r(5)),                // r6
      ins(Op::Cos, r(6)),                // r7
      ins(Op::Sqrt, r(2)),               // r8
      ins(Op::Pow, r(8), x(0)),          // r9
      ins(Op::Sub, r(9), r(7)),          // r10
      ins(Op::Mad, r(10), r(10), c(1)),  // r11
      ins(Op::Log, r(11)),               // r12
      ins(Op::Rsqrt, r(11)),             // r13
      ins(Op::Mul, r(12), r(13)),        // r14
      ins(Op::Add, r(14), r(6)),         // r15
      ins(Op::Max, r(15), r(4)),         // r16
      ins(Op::Exp2, r(16)),              // r17
      ins(Op::Mad, r(17), c(0), r(3)),   // r18
      ins(Op::Min, r(18), r(8)),         // r19
  };
  p.outputs = {19};
  return p;
}

// The same two programs, compiled natively: the expression written out once per row, calling
// sem::apply<Op, float> inline, constants as literals. T is float (one row) or Pack<K> (K
// independent rows, each operator applied to all K before the next operator).
template <int K>
struct Pack {
  std::array<float, K> v;
  Pack() = default;
  explicit Pack(float x) { v.fill(x); }
};

template <Op OP>
inline float ap(float a, float b = 0.0f, float cc = 0.0f) {
  return lgp::sem::apply<OP, float>(a, b, cc, 0.0f);
}
template <Op OP, int K>
inline Pack<K> ap(const Pack<K>& a, const Pack<K>& b = Pack<K>(0.0f),
                  const Pack<K>& cc = Pack<K>(0.0f)) {
  Pack<K> res;
#pragma GCC unroll 8
  for (int k = 0; k < K; ++k) res.v[k] = lgp::sem::apply<OP, float>(a.v[k], b.v[k], cc.v[k], 0.0f);
  return res;
}

struct ArithRow {
  template <class T>
  T operator()(T a, T b) const {
    const T r0 = ap<Op::Mul>(a, b);
    const T r1 = ap<Op::Mad>(a, T(kC0), b);
    const T r2 = ap<Op::Sub>(r0, r1);
    const T r3 = ap<Op::Add>(r2, T(kC1));
    const T r4 = ap<Op::Max>(r3, a);
    const T r5 = ap<Op::Min>(r4, T(kC3));
    const T r6 = ap<Op::Mad>(r5, r1, r0);
    const T r7 = ap<Op::Mul>(r6, T(kC2));
    const T r8 = ap<Op::Add>(r7, b);
    const T r9 = ap<Op::Sub>(r8, r5);
    const T r10 = ap<Op::Mad>(r9, r9, T(kC4));
    const T r11 = ap<Op::Min>(r10, r3);
    const T r12 = ap<Op::Max>(r11, T(kC2));
    const T r13 = ap<Op::Mul>(r12, a);
    const T r14 = ap<Op::Add>(r13, r6);
    const T r15 = ap<Op::Mad>(r14, T(kC5), r2);
    const T r16 = ap<Op::Sub>(r15, b);
    const T r17 = ap<Op::Max>(r16, r8);
    const T r18 = ap<Op::Mul>(r17, r17);
    return ap<Op::Add>(r18, r12);
  }
};

struct TransRow {
  template <class T>
  T operator()(T a, T b) const {
    const T r0 = ap<Op::Mad>(a, T(kC0), b);
    const T r1 = ap<Op::Exp2>(r0);
    const T r2 = ap<Op::Add>(r1, a);
    const T r3 = ap<Op::Log2>(r2);
    const T r4 = ap<Op::Sin>(r3);
    const T r5 = ap<Op::Mul>(r4, b);
    const T r6 = ap<Op::Exp>(r5);
    const T r7 = ap<Op::Cos>(r6);
    const T r8 = ap<Op::Sqrt>(r2);
    const T r9 = ap<Op::Pow>(r8, a);
    const T r10 = ap<Op::Sub>(r9, r7);
    const T r11 = ap<Op::Mad>(r10, r10, T(kC1));
    const T r12 = ap<Op::Log>(r11);
    const T r13 = ap<Op::Rsqrt>(r11);
    const T r14 = ap<Op::Mul>(r12, r13);
    const T r15 = ap<Op::Add>(r14, r6);
    const T r16 = ap<Op::Max>(r15, r4);
    const T r17 = ap<Op::Exp2>(r16);
    const T r18 = ap<Op::Mad>(r17, T(kC0), r3);
    return ap<Op::Min>(r18, r8);
  }
};

// The fused loop over rows. K = 1 is the plain loop: the compiler vectorises it with one SIMD
// vector of rows per iteration. On the transcendental program one iteration is a single
// dependent chain of ~450 instructions, longer than the out-of-order window, so it runs
// latency-bound. K > 1 evaluates K independent row streams (rows i, i + n/K, ...) per
// iteration with their instructions interleaved operator by operator, which is what the
// interpreter gets for free from its row blocks. n must be a multiple of K.
template <class Row, int K>
[[gnu::flatten]] void fused(const float* __restrict x0, const float* __restrict x1,
                            float* __restrict out, size_t n) {
  if constexpr (K == 1) {
#pragma omp simd
    for (size_t i = 0; i < n; ++i) out[i] = Row{}(x0[i], x1[i]);
  } else {
    // No `omp simd` here: it would turn the Pack locals into per-lane arrays in memory; -O3
    // vectorises this loop on its own (checked with -fopt-info-vec).
    const size_t q = n / K;
    for (size_t i = 0; i < q; ++i) {
      Pack<K> a, b;
#pragma GCC unroll 8
      for (int k = 0; k < K; ++k) {
        a.v[k] = x0[i + k * q];
        b.v[k] = x1[i + k * q];
      }
      const Pack<K> y = Row{}(a, b);
#pragma GCC unroll 8
      for (int k = 0; k < K; ++k) out[i + k * q] = y.v[k];
    }
  }
}

using CompiledFn = void (*)(const float*, const float*, float*, size_t);

struct Case {
  const char* name;
  Program prog;
  std::array<CompiledFn, 3> compiled;  // fused<Row, K> for K in kInterleave
  int eff_ops = 0;
};

// ---------------------------------------------------------------------------------------------
// Data and timing.

// Two inputs on (0, 1): a cell-centred grid flattened row by row, as the search tables are.
lgp::Table makeTable(size_t rows) {
  lgp::Table t;
  t.input_names = {"mu", "r"};
  t.output_names = {"y"};
  t.inputs.assign(2, std::vector<double>(rows));
  t.outputs.assign(1, std::vector<double>(rows, 0.0));
  const size_t side = static_cast<size_t>(std::ceil(std::sqrt(static_cast<double>(rows))));
  for (size_t k = 0; k < rows; ++k) {
    t.inputs[0][k] = (static_cast<double>(k % side) + 0.5) / static_cast<double>(side);
    t.inputs[1][k] = (static_cast<double>(k / side) + 0.5) / static_cast<double>(side);
  }
  return t;
}

struct Options {
  size_t rows = 65536;
  int reps = 7;
  double min_ms = 60;
  int threads = 0;        // 0 = omp_get_max_threads()
  bool cpu_clock = true;  // time by thread CPU time (default) or by wall clock
};
Options g_opt;

double seconds(std::chrono::steady_clock::time_point a, std::chrono::steady_clock::time_point b) {
  return std::chrono::duration<double>(b - a).count();
}

// CPU time of the calling thread: unlike wall time it does not count the time the thread
// spends descheduled, so on a shared, loaded machine it estimates the unloaded run time.
// Median seconds per pass of fn(passes) over g_opt.reps repetitions, each calibrated to take
// about g_opt.min_ms (passes per repetition fixed after a warm-up). fn runs all its passes in
// one go, so a multi-threaded fn forks once per repetition and needs no barrier between
// passes. fn returns the largest CPU time any of its threads spent on the passes, or a
// negative value for "single-threaded, measure me"; --clock picks wall or that CPU time.
double medianSeconds(const std::function<double(int)>& fn) {
  auto once = [&](int passes) {
    const auto w0 = std::chrono::steady_clock::now();
    const double c0 = lgp::bench::threadCpuSeconds();
    double cpu = fn(passes);
    const double c1 = lgp::bench::threadCpuSeconds();
    const double wall = seconds(w0, std::chrono::steady_clock::now());
    if (cpu < 0) cpu = c1 - c0;
    return g_opt.cpu_clock ? cpu : wall;
  };
  once(1);  // warm-up: page faults, caches, thread pool start
  int passes = 1;
  for (;;) {
    const double s = once(passes);
    if (s * 1e3 >= g_opt.min_ms || passes >= (1 << 20)) break;
    passes = s <= 0 ? passes * 16
                    : std::max(passes + 1, static_cast<int>(passes * (g_opt.min_ms * 1.2e-3 / s)));
  }
  std::vector<double> t(g_opt.reps);
  for (int k = 0; k < g_opt.reps; ++k) t[k] = once(passes) / passes;
  std::sort(t.begin(), t.end());
  return t[t.size() / 2];
}

// `passes` evaluations of every block of ds with bp on `threads` threads, one Interpreter
// each; every thread owns a fixed contiguous range of blocks.
double interpretAll(const lgp::BoundProgram& bp, const lgp::Dataset& ds,
                    std::vector<lgp::Interpreter>& interps, int threads, int passes) {
  const long nb = static_cast<long>(ds.numBlocks());
  double cpu = 0;
#pragma omp parallel num_threads(threads) if (threads > 1) reduction(max : cpu)
  {
    const double c0 = lgp::bench::threadCpuSeconds();
    lgp::Interpreter& in = interps[omp_get_thread_num()];
    for (int p = 0; p < passes; ++p) {
#pragma omp for schedule(static) nowait
      for (long b = 0; b < nb; ++b) {
        const auto& outs = in.evalBlock(bp, ds, static_cast<size_t>(b));
        benchmark::DoNotOptimize(outs.data());
      }
      benchmark::ClobberMemory();
    }
    cpu = lgp::bench::threadCpuSeconds() - c0;
  }
  return cpu;
}

// The same for a compiled loop, over chunks of 1024 rows (the interpreter's split).
double compiledAll(CompiledFn fn, const lgp::Dataset& ds, float* out, int threads, int passes) {
  const size_t n = ds.paddedRows();
  const long chunks = static_cast<long>((n + 1023) / 1024);
  double cpu = 0;
#pragma omp parallel num_threads(threads) if (threads > 1) reduction(max : cpu)
  {
    const double c0 = lgp::bench::threadCpuSeconds();
    for (int p = 0; p < passes; ++p) {
      if (threads == 1) {
        fn(ds.input(0), ds.input(1), out, n);
      } else {
#pragma omp for schedule(static) nowait
        for (long k = 0; k < chunks; ++k) {
          const size_t lo = static_cast<size_t>(k) * 1024, len = std::min<size_t>(1024, n - lo);
          fn(ds.input(0) + lo, ds.input(1) + lo, out + lo, len);
        }
      }
      benchmark::DoNotOptimize(out);
      benchmark::ClobberMemory();
    }
    cpu = lgp::bench::threadCpuSeconds() - c0;
  }
  return cpu;
}

// Largest |a - b| over rows (NaN-aware: NaN vs non-NaN counts as infinite).
double maxDiff(const float* a, const float* b, size_t n) {
  double m = 0;
  for (size_t i = 0; i < n; ++i) {
    if (std::isnan(a[i]) != std::isnan(b[i])) return INFINITY;
    if (!std::isnan(a[i])) m = std::max(m, std::fabs(static_cast<double>(a[i]) - b[i]));
  }
  return m;
}

// Compiled variants measured for each case: the plain fused loop (K = 1) and interleaved ones.
constexpr int kNumCompiled = 3;
constexpr std::array<int, kNumCompiled> kInterleave = {1, 2, 4};

struct CaseResult {
  double interp1 = 0, interpN = 0, scalar1 = 0;  // row-ops/s
  std::array<double, kNumCompiled> comp1{}, compN{};
  double compiled1() const { return comp1[0]; }  // the plain fused loop
  double compiledN() const { return compN[0]; }
  double best1() const { return *std::max_element(comp1.begin(), comp1.end()); }
  double bestN() const { return *std::max_element(compN.begin(), compN.end()); }
};

CaseResult runCase(const Case& cs, const lgp::Table& table, int block, int threads) {
  const lgp::Dataset ds(table, block);
  const size_t rows = ds.rows();
  lgp::BoundProgram bp, bp_plain;
  bp.bind(cs.prog, ds.numInputs());
  bp_plain.fuse = false;  // baseline: one kernel per opcode
  bp_plain.bind(cs.prog, ds.numInputs());
  std::vector<lgp::Interpreter> interps;
  for (int t = 0; t < threads; ++t) interps.emplace_back(block);

  // Correctness: all paths must agree exactly.
  const auto interp_out = interps[0].evaluate(cs.prog, ds)[0];
  std::vector<float> comp_out(ds.paddedRows());
  double d_comp = 0;
  for (int v = 0; v < kNumCompiled; ++v) {
    std::fill(comp_out.begin(), comp_out.end(), NAN);
    compiledAll(cs.compiled[v], ds, comp_out.data(), 1, 1);
    d_comp = std::max(d_comp, maxDiff(interp_out.data(), comp_out.data(), rows));
  }
  std::vector<std::vector<float>> scalar_out;
  lgp::evaluateScalarRows(cs.prog, ds, scalar_out);
  const double d_scal = maxDiff(interp_out.data(), scalar_out[0].data(), rows);
  size_t nonfinite = 0;
  for (float v : interp_out) nonfinite += !std::isfinite(v);

  const double work = static_cast<double>(cs.eff_ops) * static_cast<double>(rows);
  CaseResult res;
  res.interp1 = work / medianSeconds([&](int n) { return interpretAll(bp, ds, interps, 1, n); });
  const double plain1 =
      work / medianSeconds([&](int n) { return interpretAll(bp_plain, ds, interps, 1, n); });
  std::printf(
      "  pair fusion: %zu kernel calls for %zu opcodes; 1 thread %.3e row-ops/s fused vs "
      "%.3e unfused (%.2fx)\n",
      bp.steps.size(), bp_plain.steps.size(), res.interp1, plain1, res.interp1 / plain1);
  res.interpN =
      work / medianSeconds([&](int n) { return interpretAll(bp, ds, interps, threads, n); });
  for (int v = 0; v < kNumCompiled; ++v) {
    res.comp1[v] = work / medianSeconds([&](int n) {
                     return compiledAll(cs.compiled[v], ds, comp_out.data(), 1, n);
                   });
    res.compN[v] = work / medianSeconds([&](int n) {
                     return compiledAll(cs.compiled[v], ds, comp_out.data(), threads, n);
                   });
  }
  res.scalar1 = work / medianSeconds([&](int n) {
                  for (int p = 0; p < n; ++p) {
                    lgp::evaluateScalarRows(cs.prog, ds, scalar_out);
                    benchmark::DoNotOptimize(scalar_out.data());
                    benchmark::ClobberMemory();
                  }
                  return -1.0;
                });

  std::printf("\n== %s: %d effective ops, %zu rows, block %d ==\n", cs.name, cs.eff_ops, rows,
              block);
  std::printf(
      "  check: max|interp-compiled| = %g, max|interp-scalar| = %g, non-finite rows = %zu\n",
      d_comp, d_scal, nonfinite);
  std::printf("  %-38s %12s %12s %16s\n", "row-ops/s", "1 thread", "all threads",
              "all thr per core");
  auto line = [&](const char* name, double one, double all) {
    std::printf("  %-38s %12.3e %12.3e %16.3e\n", name, one, all, all / threads);
  };
  char name[64];
  std::snprintf(name, sizeof name, "interpreter (block %d)", block);
  line(name, res.interp1, res.interpN);
  for (int v = 0; v < kNumCompiled; ++v) {
    if (kInterleave[v] == 1)
      std::snprintf(name, sizeof name, "compiled fused loop");
    else
      std::snprintf(name, sizeof name, "compiled fused loop, %d-way interleaved", kInterleave[v]);
    line(name, res.comp1[v], res.compN[v]);
  }
  std::printf("  %-38s %12.3e %12s\n", "scalar per-row interpreter", res.scalar1, "-");
  std::printf(
      "  ratios (1 thread): interp/scalar = %.1fx, interp/compiled = %.3f, "
      "interp/best compiled = %.3f\n",
      res.interp1 / res.scalar1, res.interp1 / res.compiled1(), res.interp1 / res.best1());
  std::printf(
      "  ratios (%d threads): interp/compiled = %.3f, interp/best compiled = %.3f; "
      "interp scaling %.2fx\n",
      threads, res.interpN / res.compiledN(), res.interpN / res.bestN(), res.interpN / res.interp1);
  return res;
}

// Throughput of each operator's kernel alone (kernelFor(op) over one L1-resident block of
// 256 rows, called repeatedly): the per-opcode cost the interpreter pays, 1 thread. Operands:
// a in [0.1, 2.1), b in [-2, 2), c in [0, 1), d = b (inside every domain, no denormals).
void perOpTable() {
  constexpr int kN = 256;
  alignas(64) static float a[kN], b[kN], cc[kN], out[kN];
  for (int i = 0; i < kN; ++i) {
    a[i] = 0.1f + 2.0f * static_cast<float>(i) / kN;
    b[i] = -2.0f + 4.0f * static_cast<float>((i * 37) % kN) / kN;
    cc[i] = static_cast<float>((i * 101) % kN) / kN;
  }
  std::printf("\n== per-operator kernel throughput (1 thread, %d-row block in L1) ==\n", kN);
  std::printf("  %-9s %12s %12s %14s\n", "op", "row-ops/s", "ns/block", "vs add");
  double add_rate = 0;
  for (const auto& info : lgp::allOps()) {
    const lgp::Kernel k = lgp::kernelFor(info.op);
    const double sec = medianSeconds([&](int passes) {
      for (int p = 0; p < passes; ++p) {
        k(out, a, b, cc, b, kN);
        benchmark::DoNotOptimize(out);
        benchmark::ClobberMemory();
      }
      return -1.0;
    });
    const double rate = kN / sec;
    if (info.op == Op::Add) add_rate = rate;
    std::printf("  %-9.*s %12.3e %12.1f %13.1fx\n", static_cast<int>(info.name.size()),
                info.name.data(), rate, sec * 1e9, add_rate / rate);
  }
}

void parseArgs(int argc, char** argv) {
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&] { return lgp::bench::optionValue(argc, argv, i); };
    if (a == "--rows")
      g_opt.rows = std::strtoull(next(), nullptr, 10);
    else if (a == "--reps")
      g_opt.reps = std::atoi(next());
    else if (a == "--min-ms")
      g_opt.min_ms = std::atof(next());
    else if (a == "--threads")
      g_opt.threads = std::atoi(next());
    else if (a == "--quick") {
      g_opt.reps = 3;
      g_opt.min_ms = 20;
    } else {
      std::fprintf(stderr,
                   "usage: interp_bench [--rows N] [--reps N] [--min-ms MS] [--threads N] "
                   "[--clock cpu|wall] [--quick]\n");
      std::exit(2);
    }
  }
  g_opt.reps = std::max(1, g_opt.reps);
  g_opt.rows = std::max<size_t>(g_opt.rows, 2048);
}

const char* passMiss(bool ok) {
  return ok ? "pass" : "MISS";
}

}  // namespace

int main(int argc, char** argv) {
  parseArgs(argc, argv);
  const int threads = g_opt.threads > 0 ? g_opt.threads : omp_get_max_threads();
  const int block = 256;  // the search default (EvalConfig::block_size)
  std::printf("interp_bench: rows=%zu reps=%d (median) min_ms=%.0f threads=%d block=%d clock=%s\n",
              g_opt.rows, g_opt.reps, g_opt.min_ms, threads, block,
              g_opt.cpu_clock ? "cpu (per-thread CPU time; max over threads)" : "wall");
  if (FILE* f = std::fopen("/proc/loadavg", "r")) {
    char buf[128] = {};
    if (std::fgets(buf, sizeof buf, f)) std::printf("load average at start: %s", buf);
    std::fclose(f);
  }
  const char* wait = std::getenv("OMP_WAIT_POLICY");
  std::printf(
      "OMP_WAIT_POLICY=%s (libgomp spins at barriers by default; on a loaded machine a\n"
      "  spinning thread can wait out a descheduled partner's time slice)\n",
      wait ? wait : "(unset)");

  std::vector<Case> cases = {
      {"arith", arithProgram(), {&fused<ArithRow, 1>, &fused<ArithRow, 2>, &fused<ArithRow, 4>}},
      {"trans", transProgram(), {&fused<TransRow, 1>, &fused<TransRow, 2>, &fused<TransRow, 4>}}};
  for (auto& cs : cases) {
    cs.eff_ops = static_cast<int>(lgp::effectiveIndices(cs.prog).size());
    if (cs.eff_ops != static_cast<int>(cs.prog.code.size()))
      std::printf("warning: %s has introns (%d of %zu effective)\n", cs.name, cs.eff_ops,
                  cs.prog.code.size());
  }

  const lgp::Table table = makeTable(g_opt.rows);
  const CaseResult ar = runCase(cases[0], table, block, threads);
  const CaseResult tr = runCase(cases[1], table, block, threads);

  perOpTable();

  // Block-size sweep on the arithmetic program, over a dataset of at least 128K rows so that
  // every block size has many blocks. Working set per block: (constants + registers) x block.
  const lgp::Table big = makeTable(std::max<size_t>(g_opt.rows, 131072));
  const Case& arith = cases[0];
  std::printf("\n== block-size sweep: arith, %zu rows ==\n", big.rows());
  std::printf("  %6s %12s %12s %14s %14s\n", "block", "scratch KiB", "1 thread", "all threads",
              "per core (all)");
  for (int bs : {64, 128, 256, 512, 1024, 2048}) {
    const lgp::Dataset ds(big, bs);
    lgp::BoundProgram bp;
    bp.bind(arith.prog, ds.numInputs());
    std::vector<lgp::Interpreter> interps;
    for (int t = 0; t < threads; ++t) interps.emplace_back(bs);
    const double work = static_cast<double>(arith.eff_ops) * static_cast<double>(ds.rows());
    const double t1 =
        work / medianSeconds([&](int n) { return interpretAll(bp, ds, interps, 1, n); });
    const double tn =
        work / medianSeconds([&](int n) { return interpretAll(bp, ds, interps, threads, n); });
    const double kib = (bp.num_slots - bp.num_inputs) * bs * 4.0 / 1024.0;
    std::printf("  %6d %12.1f %12.3e %14.3e %14.3e\n", bs, kib, t1, tn, tn / threads);
  }

  std::printf("\n== summary (row-ops/s; per core = 1-thread figure) ==\n");
  std::printf("  %-42s %12s %10s %6s\n", "metric", "measured", "target", "");
  auto row = [](const char* name, double v, double target, bool ratio) {
    if (ratio)
      std::printf("  %-42s %12.3f %10.2f %6s\n", name, v, target, passMiss(v >= target));
    else
      std::printf("  %-42s %12.3e %10.1e %6s\n", name, v, target, passMiss(v >= target));
  };
  row("arith interp row-ops/s per core", ar.interp1, 5e9, false);
  row("arith interp row-ops/s per core (all thr)", ar.interpN / threads, 5e9, false);
  row("trans interp row-ops/s per core", tr.interp1, 1e9, false);
  row("trans interp row-ops/s per core (all thr)", tr.interpN / threads, 1e9, false);
  row("arith interp/compiled fused (1 thread)", ar.interp1 / ar.compiled1(), 0.5, true);
  row("trans interp/compiled fused (1 thread)", tr.interp1 / tr.compiled1(), 0.5, true);
  row("arith interp/compiled fused (all threads)", ar.interpN / ar.compiledN(), 0.5, true);
  row("trans interp/compiled fused (all threads)", tr.interpN / tr.compiledN(), 0.5, true);
  row("arith interp/best compiled (1 thread)", ar.interp1 / ar.best1(), 0.5, true);
  row("trans interp/best compiled (1 thread)", tr.interp1 / tr.best1(), 0.5, true);
  row("arith interp/scalar (1 thread)", ar.interp1 / ar.scalar1, 20, true);
  row("trans interp/scalar (1 thread)", tr.interp1 / tr.scalar1, 20, true);
  std::printf("  (a MISS is reported, not asserted; timings on a shared machine are noisy)\n");
  return 0;
}
