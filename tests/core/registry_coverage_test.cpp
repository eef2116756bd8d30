// Registry coverage (structure, round 2): every entry of every registry is described
// everywhere it must be, and each description agrees with the definition it stands for. A new
// operator, metric or catalogue entry that misses a place fails here, naming it. The emitter's
// languages are covered by tests/emit/registry_coverage_test.cpp, the Python side by
// tests/python/test_emit.py.
//
// Operators (allOps): the interval rule contains every sampled value; the partial derivatives
// (eval/semantics.hpp) agree with central differences; the binary16 semantics stay within half
// rounding of the float32 ones; the double and float32 semantics agree; the table's facts are
// consistent (a piecewise operator has a branch the interval analysis can see, a commutative
// one commutes, the sign columns hold on sampled operands, the guard column agrees with the
// proof of an unreachable guard). Metrics (allMetrics): every name reads back, and the float32
// scorer, the double reference and the definition (metricsOf) agree on every metric, with row
// weights.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "lgp/core/half.hpp"
#include "lgp/core/interval.hpp"
#include "lgp/core/ops.hpp"
#include "lgp/eval/metrics.hpp"
#include "lgp/eval/objectives.hpp"
#include "lgp/eval/semantics.hpp"
#include "test_tables.hpp"

namespace lgp {
namespace {

// Operands where no guard, floor or clamp holds and no branch sits close: derivatives and
// half rounding are smooth there (a in [0.3, 1.7], b in [0.4, 1.6], c, d in [-1, 1]).
std::array<double, kMaxArity> genericPoint(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(0, 1);
  return {0.3 + 1.4 * u(rng), 0.4 + 1.2 * u(rng), -1 + 2 * u(rng), -1 + 2 * u(rng)};
}

double applyD(Op op, const std::array<double, kMaxArity>& x) {
  return sem::applyDynamic<double>(op, x[0], x[1], x[2], x[3]);
}

TEST(RegistryCoverage, EveryOperatorHasATableRowAndAName) {
  ASSERT_EQ(allOps().size(), static_cast<size_t>(kNumOps));
  for (int i = 0; i < kNumOps; ++i) {
    const OpInfo& info = allOps()[i];
    EXPECT_EQ(static_cast<int>(info.op), i) << info.name;
    EXPECT_EQ(opFromString(info.name), info.op) << info.name;
    EXPECT_GE(info.arity, 1);
    EXPECT_LE(info.arity, kMaxArity);
    for (std::string_view t : {info.infix, info.hlsl, info.glsl, info.cpp})
      for (int k = 0; k < info.arity; ++k)
        EXPECT_NE(t.find("{" + std::to_string(k) + "}"), std::string_view::npos)
            << info.name << ": a spelling leaves out operand " << k << ": " << t;
    for (int t = 0; t < kNumCostTargets; ++t) EXPECT_GE(info.cost[t], 0) << info.name;
    if (!info.guarded) {
      for (int t = 0; t < kNumCostTargets; ++t) EXPECT_EQ(info.guard_cost[t], 0) << info.name;
    }
  }
}

TEST(RegistryCoverage, DoubleAndFloatSemanticsAgree) {
  std::mt19937_64 rng(1);
  for (const auto& info : allOps())
    for (int s = 0; s < 50; ++s) {
      const auto x = genericPoint(rng);
      const double d = applyD(info.op, x);
      const float f =
          sem::applyDynamic<float>(info.op, static_cast<float>(x[0]), static_cast<float>(x[1]),
                                   static_cast<float>(x[2]), static_cast<float>(x[3]));
      EXPECT_NEAR(f, d, 1e-5 * std::max(1.0, std::fabs(d))) << info.name;
    }
}

TEST(RegistryCoverage, IntervalRulesHoldEverySampledValue) {
  std::mt19937_64 rng(2);
  std::uniform_real_distribution<double> u(0, 1);
  for (const auto& info : allOps())
    for (int s = 0; s < 400; ++s) {
      // Intervals over signs, zero and the guards' neighbourhoods, and points inside them.
      Interval iv[kMaxArity];
      std::array<double, kMaxArity> x{};
      for (int k = 0; k < kMaxArity; ++k) {
        const double scale = std::pow(10.0, -3 + 6 * u(rng));
        const double lo = (u(rng) - 0.5) * 2 * scale, hi = lo + u(rng) * scale;
        iv[k] = Interval{lo, hi, false};
        x[k] = lo + (hi - lo) * u(rng);
      }
      const Interval r = opInterval(info.op, iv);
      const float v =
          sem::applyDynamic<float>(info.op, static_cast<float>(x[0]), static_cast<float>(x[1]),
                                   static_cast<float>(x[2]), static_cast<float>(x[3]));
      if (std::isnan(v)) {
        EXPECT_TRUE(r.nan) << info.name << " gives NaN at a point its interval calls NaN-free";
        continue;
      }
      EXPECT_TRUE(v >= r.lo && v <= r.hi)
          << info.name << "(" << x[0] << ", " << x[1] << ", " << x[2] << ", " << x[3] << ") = " << v
          << " outside [" << r.lo << ", " << r.hi << "]";
    }
}

TEST(RegistryCoverage, PartialDerivativesMatchCentralDifferences) {
  std::mt19937_64 rng(3);
  for (const auto& info : allOps())
    for (int s = 0; s < 50; ++s) {
      auto x = genericPoint(rng);
      // Keep branches away from their switch: select's and min/max's operands apart.
      if (info.piecewise) x[1] = x[0] + (x[1] > x[0] ? 0.3 : -0.3);
      const double v = applyD(info.op, x);
      const auto p = sem::partialsDynamic<double>(info.op, v, x[0], x[1], x[2], x[3]);
      for (int k = 0; k < info.arity; ++k) {
        const double h = 1e-6 * std::max(1.0, std::fabs(x[k]));
        auto xp = x, xm = x;
        xp[k] += h;
        xm[k] -= h;
        const double fd = (applyD(info.op, xp) - applyD(info.op, xm)) / (2 * h);
        const double an = p.on[k] ? p.p[k] / p.den : 0.0;
        EXPECT_NEAR(an, fd, 1e-5 * std::max(1.0, std::fabs(fd)))
            << info.name << ": d/d operand " << k << " at (" << x[0] << ", " << x[1] << ", " << x[2]
            << ", " << x[3] << ")";
      }
    }
}

TEST(RegistryCoverage, HalfSemanticsStayWithinHalfRounding) {
  std::mt19937_64 rng(4);
  for (const auto& info : allOps())
    for (int s = 0; s < 50; ++s) {
      auto x = genericPoint(rng);
      // Operands exactly representable in binary16, so that only the op's rounding differs.
      for (double& v : x) v = roundToHalf(static_cast<float>(v));
      if (info.piecewise) x[1] = roundToHalf(static_cast<float>(x[0] + (x[1] > x[0] ? 0.3 : -0.3)));
      const double d = applyD(info.op, x);
      const float h = applyHalf(info.op, static_cast<float>(x[0]), static_cast<float>(x[1]),
                                static_cast<float>(x[2]), static_cast<float>(x[3]));
      // A few half ulps of the result and of the operands' scale (mad, lerp round twice).
      const double tol = 8 * 0x1p-11 * std::max({1.0, std::fabs(d), std::fabs(x[0] * x[1])});
      EXPECT_NEAR(h, d, tol) << info.name;
    }
}

TEST(RegistryCoverage, TableFactsAreConsistent) {
  std::mt19937_64 rng(5);
  for (const auto& info : allOps()) {
    if (info.commutative) {
      EXPECT_EQ(info.arity, 2) << info.name;
      for (int s = 0; s < 20; ++s) {
        auto x = genericPoint(rng);
        auto y = x;
        std::swap(y[0], y[1]);
        EXPECT_EQ(applyD(info.op, x), applyD(info.op, y)) << info.name;
      }
    }
    // A piecewise operator's branch is visible to the interval analysis: on an interval that
    // straddles it, branchMaySwitch says so.
    if (info.piecewise) {
      Interval wide[kMaxArity] = {{-1, 2, false}, {-1, 2, false}, {0, 1, false}, {0, 1, false}};
      EXPECT_TRUE(branchMaySwitch(info.op, wide)) << info.name;
    } else {
      Interval any[kMaxArity] = {{-1, 2, false}, {-1, 2, false}, {0, 1, false}, {0, 1, false}};
      EXPECT_FALSE(branchMaySwitch(info.op, any)) << info.name;
    }
  }
}

// The sign columns (ops.hpp OpNonNeg, OpZeroSign) that the simplifier's sign-of-zero rewrites
// trust hold on sampled operands: +0 and -0 at a blocking operand give the same bits, at a
// passing one the same value; a nonnegative result never has its sign bit set.
TEST(RegistryCoverage, SignColumnsHoldOnSampledOperands) {
  std::mt19937_64 rng(6);
  const float pool[] = {0.0f,  -0.0f, 1.0f,   -1.0f, 0.5f,   -2.5f,    3e-20f,   -3e-20f,
                        1e-3f, -7.0f, 200.0f, 1e30f, -1e30f, INFINITY, -INFINITY};
  auto draw = [&](bool nonneg) {
    float v = pool[rng() % std::size(pool)];
    return nonneg ? std::fabs(v) : v;
  };
  auto apply = [](Op op, const std::array<float, kMaxArity>& x) {
    return sem::applyDynamic<float>(op, x[0], x[1], x[2], x[3]);
  };
  auto same = [](float a, float b, bool bits) {
    if (std::isnan(a) || std::isnan(b)) return std::isnan(a) && std::isnan(b);
    return bits ? std::signbit(a) == std::signbit(b) && a == b : a == b;
  };
  for (const auto& info : allOps())
    for (int s = 0; s < 400; ++s) {
      for (int k = 0; k < info.arity; ++k) {
        std::array<float, kMaxArity> x{};
        for (float& v : x) v = draw(false);
        auto pos = x, neg = x;
        pos[k] = 0.0f;
        neg[k] = -0.0f;
        const float vp = apply(info.op, pos), vn = apply(info.op, neg);
        bool blocks = false, passes = false;
        switch (info.zero_sign) {
          case OpZeroSign::Blocks:
            blocks = true;
            break;
          case OpZeroSign::Passes:
            passes = true;
            break;
          case OpZeroSign::Reads:
            break;
          case OpZeroSign::DivisorReads:
            passes = k == 0;
            break;
          case OpZeroSign::BranchesPass:
            blocks = k < 2;
            passes = k >= 2;
            break;
        }
        if (blocks || passes) {
          EXPECT_TRUE(same(vp, vn, blocks))
              << info.name << ": operand " << k << " at +0 gives " << vp << ", at -0 " << vn;
        }
      }
      std::array<float, kMaxArity> x{};
      const bool all = info.nonneg == OpNonNeg::IfOperands;
      for (int k = 0; k < kMaxArity; ++k)
        x[k] = draw(all || (info.nonneg == OpNonNeg::IfBranches && k >= 2));
      const float v = apply(info.op, x);
      if (info.nonneg != OpNonNeg::Never && !std::isnan(v)) {
        EXPECT_FALSE(std::signbit(v)) << info.name << " (" << x[0] << ", " << x[1] << ", " << x[2]
                                      << ", " << x[3] << ") = " << v;
      }
    }
}

// An operator without a guard needs no proof; one with a guard is proven unguarded only where
// its operands say so (never on the whole line with NaN).
TEST(RegistryCoverage, GuardColumnAgreesWithTheProof) {
  Interval whole[kMaxArity], nan[kMaxArity];
  for (int k = 0; k < kMaxArity; ++k) {
    whole[k] = {-1e30, 1e30, false};
    nan[k] = {-1e30, 1e30, true};
  }
  for (const auto& info : allOps()) {
    EXPECT_EQ(info.guarded, info.guard != OpGuard::None && info.guard != OpGuard::NanOrder);
    EXPECT_EQ(info.piecewise, info.kink != OpKink::None);
    if (info.guard == OpGuard::None) {
      EXPECT_TRUE(provenUnguarded(info.op, nan)) << info.name;
    } else {
      EXPECT_FALSE(provenUnguarded(info.op, nan)) << info.name;
      if (info.guard != OpGuard::NanOrder && info.guard != OpGuard::NanToZero) {
        EXPECT_FALSE(provenUnguarded(info.op, whole)) << info.name;
      }
    }
  }
}

TEST(RegistryCoverage, EveryMetricReadsBackAndEveryPathAgrees) {
  for (const auto& m : allMetrics()) {
    EXPECT_EQ(errorMetricFromString(m.name), m.metric) << m.name;
    EXPECT_EQ(toString(m.metric), m.name);
  }
  // A weighted table and a program off by a row-dependent amount.
  Table t = test::gridTable(9);
  t.weights.clear();
  for (size_t r = 0; r < t.rows(); ++r) t.weights.push_back(0.25 + (r % 7) * 0.5);
  Program p;
  p.constants = {0.9f, 0.05f};
  p.code = {Instr{Op::Mad, {inputOperand(0), constOperand(0), constOperand(1)}}};
  p.outputs = {0};
  const auto ref = referenceMetrics(p, t, ErrorConfig{});
  const auto pred = evaluateReference(p, t)[0];
  const OutputMetrics def = metricsOf(pred.data(), t.outputs[0].data(), t.weights.data(), t.rows(),
                                      ErrorConfig{}.rel_floor);
  const Dataset ds(t, 64);
  for (const auto& m : allMetrics()) {
    ErrorConfig cfg;
    cfg.metric = m.metric;
    Scorer sc(ds, cfg, 64);
    const double fast = sc.error(p);
    const double want = def.*m.field;
    EXPECT_NEAR(ref[0].*m.field, want, 1e-12 * want) << m.name << ": the double reference";
    // The float32 scorer within its own stated bound (objectives.hpp fastErrorBound), with
    // the float32 rounding of the program's value on top.
    EXPECT_NEAR(fast, want, 1e-6 * std::max(want, 1e-3)) << m.name << ": the float32 scorer";
    EXPECT_NEAR(sc.metrics(p)[0].*m.field, want, 1e-6 * std::max(want, 1e-3))
        << m.name << ": Scorer::metrics";
  }
}

}  // namespace
}  // namespace lgp
