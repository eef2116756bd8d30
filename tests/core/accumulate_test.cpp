// The Scorer's float error accumulation agrees with a double computation on the same float
// predictions within fastErrorBound; constant programs take a shortcut that gives the full
// path's error; scoring does not allocate once warm.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdlib>
#include <new>

#include "lgp/core/rng.hpp"
#include "lgp/core/variation.hpp"
#include "lgp/eval/objectives.hpp"

// Counts this thread's allocations through the global operator new (the Scorer's buffers all
// come from there), so that a test can assert that a loop allocates nothing.
namespace {
thread_local long g_allocations = 0;
}
void* operator new(std::size_t n) {
  ++g_allocations;
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
// GCC cannot see that the replaced operator new above is malloc.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
void operator delete(void* p) noexcept {
  std::free(p);
}
void operator delete(void* p, std::size_t) noexcept {
  std::free(p);
}
// The nothrow forms too (std::stable_sort's buffer comes from them): left to the runtime, they
// allocate with its new and the delete above frees with free (ASan: alloc-dealloc-mismatch in
// every test of this binary).
void* operator new(std::size_t n, const std::nothrow_t&) noexcept {
  ++g_allocations;
  return std::malloc(n ? n : 1);
}
void operator delete(void* p, const std::nothrow_t&) noexcept {
  std::free(p);
}
#pragma GCC diagnostic pop

namespace lgp {
namespace {

constexpr auto X = inputOperand;
constexpr auto C = constOperand;
constexpr auto R = regOperand;

// Two float-exact inputs in [0.5, 2]; outputs A = scale * x0 * x1 and B = scale * (x0 + 0.3)
// in double, so a float program computing them is off by rounding only.
Table makeTable(int rows, double scale, bool weighted, uint64_t seed) {
  Rng rng(seed);
  Table t;
  t.input_names = {"x0", "x1"};
  t.output_names = {"A", "B"};
  t.inputs.assign(2, {});
  t.outputs.assign(2, {});
  for (int r = 0; r < rows; ++r) {
    const double a = static_cast<float>(rng.uniform(0.5, 2.0));
    const double b = static_cast<float>(rng.uniform(0.5, 2.0));
    t.inputs[0].push_back(a);
    t.inputs[1].push_back(b);
    t.outputs[0].push_back(scale * a * b);
    t.outputs[1].push_back(scale * (a + 0.3));
    if (weighted) t.weights.push_back(rng.chance(0.1) ? 0.0 : rng.uniform(0.0, 3.0));
  }
  return t;
}

struct DoubleMetrics {
  double rmse = 0, mae = 0, mean_rel = 0, max_abs = 0;
  bool finite = true;
};

// The reference: every sum in double over the float predictions.
DoubleMetrics doubleMetrics(const std::vector<float>& pred, const Table& t, int o,
                            double rel_floor) {
  DoubleMetrics m;
  double sw = 0, sse = 0, sae = 0, srel = 0;
  for (size_t r = 0; r < t.rows(); ++r) {
    if (!std::isfinite(pred[r])) m.finite = false;
    const double w = t.weights.empty() ? 1.0 : t.weights[r];
    const double y = t.outputs[o][r];
    const double d = static_cast<double>(pred[r]) - y;
    sw += w;
    sse += w * d * d;
    sae += w * std::fabs(d);
    srel += w * std::fabs(d) / std::max(std::fabs(y), rel_floor);
    m.max_abs = std::max(m.max_abs, std::fabs(d));
  }
  m.rmse = std::sqrt(sse / sw);
  m.mae = sae / sw;
  m.mean_rel = srel / sw;
  return m;
}

double maxAbs(const std::vector<double>& v) {
  double m = 0;
  for (double x : v) m = std::max(m, std::fabs(x));
  return m;
}

Program twoOutputs(std::vector<Instr> code, std::vector<float> constants, uint8_t a, uint8_t b) {
  Program p;
  p.code = std::move(code);
  p.constants = std::move(constants);
  p.outputs = {a, b};
  return p;
}

// Checks every metric of `p` against the double reference, and error() against metrics().
void checkProgram(const Program& p, const Table& t, int block, const std::string& what) {
  Dataset ds(t, block);
  ErrorConfig cfg;
  Scorer s(ds, cfg, block);
  const auto fast = s.metrics(p);
  Interpreter interp(block);
  const auto pred = interp.evaluate(p, ds);
  for (int o = 0; o < 2; ++o) {
    const DoubleMetrics ref = doubleMetrics(pred[o], t, o, cfg.rel_floor);
    if (!ref.finite) {
      EXPECT_TRUE(std::isinf(fast[o].rmse)) << what;
      continue;
    }
    const double y = maxAbs(t.outputs[o]);
    auto near = [&](ErrorMetric m, double got, double want) {
      const double bound = fastErrorBound(m, want, y, block, cfg.rel_floor);
      EXPECT_LE(std::fabs(got - want), bound)
          << what << " output " << o << " " << toString(m) << ": " << got << " vs " << want;
    };
    near(ErrorMetric::Rmse, fast[o].rmse, ref.rmse);
    near(ErrorMetric::Mae, fast[o].mae, ref.mae);
    near(ErrorMetric::MeanRel, fast[o].mean_rel, ref.mean_rel);
    near(ErrorMetric::MaxAbs, fast[o].max_abs, ref.max_abs);
  }
  // error() sums exactly as metrics() does, whatever the metric.
  for (ErrorMetric m :
       {ErrorMetric::Rmse, ErrorMetric::Mae, ErrorMetric::MeanRel, ErrorMetric::MaxAbs}) {
    ErrorConfig c;
    c.metric = m;
    Scorer sm(ds, c, block);
    EXPECT_EQ(sm.error(p), combineError(fast, c)) << what << " " << toString(m);
  }
}

TEST(Accumulate, FastMetricsAgreeWithDoubleWithinTheBound) {
  ProgramShape shape;
  shape.num_inputs = 2;
  shape.num_outputs = 2;
  shape.max_length = 12;
  InitConfig init{3, 12, -2, 2};
  for (double scale : {1.0, 1e30, 1e-30, 3e5}) {
    for (bool weighted : {false, true}) {
      for (int block : {16, 48, 256}) {
        const Table t = makeTable(1000, scale, weighted, 11);
        const std::string what = "scale " + std::to_string(scale) + (weighted ? " weighted" : "") +
                                 " block " + std::to_string(block);
        const float k = static_cast<float>(scale);
        // Equal to the target up to float rounding: a tiny error that must not be lost.
        const Program exact =
            twoOutputs({Instr{Op::Mul, {X(0), X(1)}}, Instr{Op::Mul, {R(0), C(0)}},
                        Instr{Op::Add, {X(0), C(1)}}, Instr{Op::Mul, {R(2), C(0)}}},
                       {k, 0.3f}, 1, 3);
        checkProgram(exact, t, block, what + " exact");
        // Some 2^60 times the target: float squares overflow, the block is summed in double.
        const Program far = twoOutputs({Instr{Op::Mul, {X(0), C(0)}}, Instr{Op::Mul, {X(1), C(1)}}},
                                       {k * 1e25f > 1e37f ? 3e38f : k * 1e25f, 0.5f * k}, 0, 1);
        checkProgram(far, t, block, what + " far");
        for (int trial = 0; trial < 20; ++trial) {
          Rng rng(1000 + trial);
          Program p = randomProgram(shape, init, rng);
          // Bring the program to the target's scale.
          p.code.push_back(Instr{Op::Mul, {R(p.outputs[0]), C(0)}});
          p.code.push_back(Instr{Op::Mul, {R(p.outputs[1]), C(0)}});
          p.constants[0] = k;
          p.outputs = {static_cast<uint8_t>(p.code.size() - 2),
                       static_cast<uint8_t>(p.code.size() - 1)};
          checkProgram(p, t, block, what + " random " + std::to_string(trial));
        }
      }
    }
  }
}

TEST(Accumulate, NearZeroErrorIsKept) {
  const Table t = makeTable(777, 1.0, false, 5);
  Dataset ds(t, 64);
  Scorer s(ds, ErrorConfig{}, 64);
  const Program p =
      twoOutputs({Instr{Op::Mul, {X(0), X(1)}}, Instr{Op::Add, {X(0), C(0)}}}, {0.3f}, 0, 1);
  const auto fast = s.metrics(p);
  const auto pred = Interpreter(64).evaluate(p, ds);
  for (int o = 0; o < 2; ++o) {
    const double ref = doubleMetrics(pred[o], t, o, 1e-6).rmse;
    EXPECT_GT(ref, 0) << o;
    EXPECT_LT(ref, 1e-6) << o;
    EXPECT_NEAR(fast[o].rmse, ref, 1e-3 * ref) << o;
  }
  // Exactly the target: zero.
  Table u = t;
  u.outputs[1] = u.inputs[0];
  Dataset du(u, 64);
  Scorer su(du, ErrorConfig{}, 64);
  const Program id =
      twoOutputs({Instr{Op::Mul, {X(0), X(1)}}, Instr{Op::Add, {X(0), C(0)}}}, {0.0f}, 0, 1);
  EXPECT_EQ(su.metrics(id)[1].rmse, 0.0);
  EXPECT_EQ(su.metrics(id)[1].max_abs, 0.0);
}

// A constant program and its twin that reads an input to add an exact zero: same outputs on
// every row, but the twin takes the full interpreter path.
struct Twins {
  Program constant, full;
};
Twins constantTwins(float a, float b, float c) {
  Twins t;
  t.constant =
      twoOutputs({Instr{Op::Add, {C(0), C(1)}}, Instr{Op::Exp2, {C(2)}}}, {a, b, c, 0.0f}, 0, 1);
  t.full = twoOutputs(
      {Instr{Op::Add, {C(0), C(1)}}, Instr{Op::Exp2, {C(2)}}, Instr{Op::Mul, {X(0), C(3)}},
       Instr{Op::Add, {R(0), R(2)}}, Instr{Op::Add, {R(1), R(2)}}},
      {a, b, c, 0.0f}, 3, 4);
  return t;
}

TEST(Accumulate, ConstantProgramsGiveTheFullPathsError) {
  const Table t = makeTable(600, 2.0, true, 3);
  const int block = 64;
  Dataset ds(t, block);
  const double y = std::max(maxAbs(t.outputs[0]), maxAbs(t.outputs[1]) + maxAbs(t.outputs[0]));
  for (const auto& [a, b, c] : {std::tuple{1.0f, 0.5f, 0.25f}, std::tuple{-3.0f, 0.1f, 1.5f},
                                std::tuple{0.0f, 0.0f, -8.0f}}) {
    const Twins tw = constantTwins(a, b, c);
    for (ErrorMetric m :
         {ErrorMetric::Rmse, ErrorMetric::Mae, ErrorMetric::MeanRel, ErrorMetric::MaxAbs}) {
      for (TargetTransform tr : {TargetTransform::None, TargetTransform::Log}) {
        for (bool scaling : {false, true}) {
          for (int channels = 0; channels < 3; ++channels) {
            ErrorConfig cfg;
            cfg.metric = m;
            cfg.transforms = {tr, TargetTransform::None};
            cfg.linear_scaling = scaling;
            if (channels == 1) cfg.channels = {{"A+B", {1.0, 1.0}}};
            if (channels == 2) cfg.channels = {{"A", {1.0, 0.0}}, {"A-B/2", {1.0, -0.5}}};
            const std::string what = std::string(toString(m)) + " " + std::string(toString(tr)) +
                                     (scaling ? " scaled" : "") + " channels " +
                                     std::to_string(channels) + " a " + std::to_string(a);
            Scorer sc(ds, cfg, block), sf(ds, cfg, block);
            const double ec = sc.error(tw.constant), ef = sf.error(tw.full);
            EXPECT_TRUE(sc.bound().constant) << what;
            EXPECT_FALSE(sf.bound().constant) << what;
            ASSERT_TRUE(std::isfinite(ef)) << what;
            if (m == ErrorMetric::Mae || m == ErrorMetric::MeanRel)
              EXPECT_EQ(ec, ef) << what;  // the same accumulation over the same values
            else
              EXPECT_LE(std::fabs(ec - ef), fastErrorBound(m, ef, y, block)) << what;
            for (size_t o = 0; o < 2; ++o) {
              EXPECT_EQ(sc.scales()[o].a, sf.scales()[o].a) << what;
              EXPECT_EQ(sc.scales()[o].b, sf.scales()[o].b) << what;
            }
            const auto mc = sc.channelMetrics(tw.constant), mf = sf.channelMetrics(tw.full);
            ASSERT_EQ(mc.size(), mf.size());
            for (size_t k = 0; k < mc.size(); ++k) {
              EXPECT_LE(std::fabs(mc[k].rmse - mf[k].rmse),
                        fastErrorBound(ErrorMetric::Rmse, mf[k].rmse, y, block))
                  << what;
              EXPECT_LE(std::fabs(mc[k].max_abs - mf[k].max_abs),
                        fastErrorBound(ErrorMetric::MaxAbs, mf[k].max_abs, y, block))
                  << what;
              EXPECT_EQ(mc[k].mae, mf[k].mae) << what;
              EXPECT_EQ(mc[k].mean_rel, mf[k].mean_rel) << what;
              EXPECT_NEAR(mc[k].r2, mf[k].r2, 1e-5) << what;
            }
          }
        }
      }
    }
  }
}

TEST(Accumulate, ScoringDoesNotAllocateOnceWarm) {
  const Table t = makeTable(500, 1.0, false, 9);
  Dataset ds(t, 64);
  ProgramShape shape;
  shape.num_inputs = 2;
  shape.num_outputs = 2;
  shape.max_length = 24;
  InitConfig init{2, 24, -2, 2};
  std::vector<Program> progs;
  for (int i = 0; i < 50; ++i) {
    Rng rng(500 + i);
    progs.push_back(randomProgram(shape, init, rng));
  }
  progs.push_back(constantTwins(1, 2, 3).constant);
  for (bool scaling : {false, true}) {
    ErrorConfig cfg;
    cfg.linear_scaling = scaling;
    Scorer s(ds, cfg, 64);
    for (const auto& p : progs) s.error(p);  // warm: every buffer at its largest
    const long before = g_allocations;
    double sum = 0;
    for (int rep = 0; rep < 3; ++rep)
      for (const auto& p : progs) {
        sum += s.error(p);
        sum += static_cast<double>(s.bound().effective.size());
      }
    EXPECT_EQ(g_allocations - before, 0) << (scaling ? "scaled" : "plain");
    EXPECT_FALSE(std::isnan(sum));
  }
}

}  // namespace
}  // namespace lgp
