// Error metrics, transforms, cost and discontinuity; non-finite programs are worst.
#include <gtest/gtest.h>

#include <cmath>

#include "lgp/eval/discontinuity.hpp"
#include "lgp/eval/objectives.hpp"
#include "lgp/search/pareto.hpp"

namespace lgp {
namespace {

constexpr auto X = inputOperand;
constexpr auto C = constOperand;
constexpr auto R = regOperand;

Table line(int n) {
  Table t;
  t.input_names = {"x"};
  t.output_names = {"y"};
  t.inputs = {{}};
  t.outputs = {{}};
  for (int i = 0; i < n; ++i) {
    t.inputs[0].push_back(i / double(n));
    t.outputs[0].push_back(1 + 2 * i / double(n));
  }
  return t;
}

Program affine(float a, float b) {  // a*x + b
  Program p;
  p.code = {Instr{Op::Mad, {X(0), C(0), C(1)}}};
  p.constants = {a, b};
  p.outputs = {0};
  return p;
}

TEST(Objectives, MetricsOfAConstantOffset) {
  const Table t = line(100);
  Dataset ds(t, 32);
  ErrorConfig cfg;
  Scorer s(ds, cfg, 32);
  EXPECT_NEAR(s.error(affine(2, 1)), 0.0, 1e-7);
  const auto m = s.metrics(affine(2, 1.5f));
  EXPECT_NEAR(m[0].rmse, 0.5, 1e-6);
  EXPECT_NEAR(m[0].max_abs, 0.5, 1e-6);
  EXPECT_NEAR(m[0].mae, 0.5, 1e-6);
  // r2 = 1 - SSE / SST with every residual 0.5: about 0.25 on this line, computed here from
  // the table.
  double mean = 0, sst = 0;
  for (double y : t.outputs[0]) mean += y / t.rows();
  for (double y : t.outputs[0]) sst += (y - mean) * (y - mean);
  const double r2 = 1 - t.rows() * 0.25 / sst;
  EXPECT_NEAR(r2, 0.25, 0.01);
  EXPECT_NEAR(m[0].r2, r2, 1e-5);
  const auto ref = referenceMetrics(affine(2, 1.5f), t, cfg);
  EXPECT_NEAR(ref[0].rmse, 0.5, 1e-12);
  cfg.metric = ErrorMetric::MaxAbs;
  Scorer s2(ds, cfg, 32);
  EXPECT_NEAR(s2.error(affine(2, 1.25f)), 0.25, 1e-6);
}

TEST(Objectives, WeightsApply) {
  Table t = line(64);
  t.weights.assign(64, 0.0);
  t.weights[10] = 1.0;  // only row 10 counts
  Dataset ds(t, 16);
  ErrorConfig cfg;
  Scorer s(ds, cfg, 16);
  Program p = affine(0, 0);  // predicts 0: error at row 10 = y[10]
  EXPECT_NEAR(s.error(p), t.outputs[0][10], 1e-6);
}

TEST(Objectives, ErrorOfTransformedFitIsMeasuredOnTheOriginal) {
  // y = exp(2x + 1); the program fits log y exactly with a*x + b, error measured on y.
  Table t = line(50);
  for (size_t r = 0; r < t.rows(); ++r) t.outputs[0][r] = std::exp(2 * t.inputs[0][r] + 1);
  Dataset ds(t, 16);
  ErrorConfig cfg;
  cfg.transforms = {TargetTransform::Log};
  Scorer s(ds, cfg, 16);
  EXPECT_LT(s.error(affine(2, 1)), 1e-5);
  EXPECT_NEAR(s.error(affine(2, 1.1f)), referenceMetrics(affine(2, 1.1f), t, cfg)[0].rmse, 1e-5);
  EXPECT_GT(s.error(affine(2, 1.1f)), 0.5);  // an error on the original scale, not in log space
  EXPECT_DOUBLE_EQ(invertTransform(TargetTransform::Log, applyTransform(TargetTransform::Log, 3.0)),
                   3.0);
  EXPECT_DOUBLE_EQ(
      invertTransform(TargetTransform::Sqrt, applyTransform(TargetTransform::Sqrt, 3.0)), 3.0);
  EXPECT_DOUBLE_EQ(invertTransform(TargetTransform::Rcp, applyTransform(TargetTransform::Rcp, 3.0)),
                   3.0);
}

TEST(Objectives, NonFiniteOutputIsWorstAndNeverEntersTheArchive) {
  const Table t = line(40);
  Dataset ds(t, 16);
  Scorer s(ds, ErrorConfig{}, 16);
  // r0 = exp2(c0) = 2^126; r1 = r0 * r0 = inf; r2 = r1 - r1 = NaN
  Program p;
  p.code = {Instr{Op::Exp2, {C(0)}}, Instr{Op::Mul, {R(0), R(0)}}, Instr{Op::Sub, {R(1), R(1)}}};
  p.constants = {200.0f};
  p.outputs = {2};
  const double e = s.error(p);
  EXPECT_TRUE(std::isinf(e));
  EXPECT_FALSE(std::isnan(e));
  p.outputs = {1};  // +inf output
  EXPECT_TRUE(std::isinf(s.error(p)));
  Archive a;
  EXPECT_FALSE(a.insert(p, Objectives{e, 1, 0}));
  const auto m = s.metrics(p);
  EXPECT_TRUE(std::isinf(m[0].rmse));
  // Division by zero and log of a negative are protected: finite.
  Program q;
  q.code = {Instr{Op::Sub, {X(0), X(0)}}, Instr{Op::Div, {X(0), R(0)}}, Instr{Op::Log, {C(0)}},
            Instr{Op::Add, {R(1), R(2)}}};
  q.constants = {-5.0f};
  q.outputs = {3};
  EXPECT_TRUE(std::isfinite(s.error(q)));
}

TEST(Objectives, CostAndDiscontinuityCountEffectiveOpcodesOnly) {
  Program p;
  p.code = {Instr{Op::Exp2, {X(0)}}, Instr{Op::Max, {X(0), X(0)}},  // intron
            Instr{Op::Abs, {R(0)}}, Instr{Op::Mad, {R(2), X(0), X(0)}}};
  p.constants = {};
  p.outputs = {3};
  auto price = [](const CostModel& m, Op op) { return m.cost[static_cast<int>(op)]; };
  auto guard = [](const CostModel& m, Op op) { return m.guard[static_cast<int>(op)]; };
  // Without a domain the exp2's clamp may be reached, so its guard is priced; the intron is not.
  const auto generic = CostModel::preset(CostTarget::GpuGeneric);
  EXPECT_EQ(generic.programCost(p), price(generic, Op::Exp2) + guard(generic, Op::Exp2) +
                                        price(generic, Op::Abs) + price(generic, Op::Mad));
  const auto cpu = CostModel::preset(CostTarget::Cpu);
  EXPECT_EQ(cpu.programCost(p), price(cpu, Op::Exp2) + price(cpu, Op::Abs) + price(cpu, Op::Mad));
  // On x0 in [0, 1] the clamp is never reached and abs of a positive value goes: exp2 + mad.
  const auto onUnit = CostModel::preset(CostTarget::GpuGeneric, {Interval{0.0, 1.0, false}});
  EXPECT_EQ(onUnit.programCost(p), price(generic, Op::Exp2) + price(generic, Op::Mad));
  EXPECT_EQ(DiscontinuityModel::defaults().programDiscontinuity(p), 1);  // abs only
  EXPECT_EQ(generic.transformCost({TargetTransform::Log, TargetTransform::None}),
            price(generic, Op::Exp));
}

// A product read only by adds and subtractions compiles into each of them (fused multiply-adds),
// so it goes and they are priced as mads; a product read by anything else, stored as an output,
// or the second product of the same sum stays.
TEST(Objectives, ProductInsideASumIsPricedAsTheMadItCompilesTo) {
  const auto m = CostModel::preset(CostTarget::GpuGeneric, {Interval{0.0, 1.0, false}});
  auto price = [&](Op op) { return m.cost[static_cast<int>(op)]; };
  Program p;  // x0*x1 + x0 and x1 - x0*x2: two fused pairs
  p.code = {Instr{Op::Mul, {X(0), X(1)}}, Instr{Op::Add, {R(0), X(0)}},
            Instr{Op::Mul, {X(0), X(2)}}, Instr{Op::Sub, {X(1), R(2)}},
            Instr{Op::Add, {R(1), R(3)}}};
  p.outputs = {4};
  EXPECT_DOUBLE_EQ(m.programCost(p), 2 * price(Op::Mad) + price(Op::Add));
  Program q;  // t + t*x0 with t = x0*x1: t is read by a product too and stays; t*x0 fuses
  q.code = {Instr{Op::Mul, {X(0), X(1)}}, Instr{Op::Mul, {R(0), X(0)}},
            Instr{Op::Add, {R(0), R(1)}}};
  q.outputs = {2};
  EXPECT_DOUBLE_EQ(m.programCost(q), price(Op::Mul) + price(Op::Mad));
  Program u;  // (x0*x1)^2: a product read by a square stays
  u.code = {Instr{Op::Mul, {X(0), X(1)}}, Instr{Op::Mul, {R(0), R(0)}}};
  u.outputs = {1};
  EXPECT_DOUBLE_EQ(m.programCost(u), 2 * price(Op::Mul));
  Program r;  // x0*x1 + x1*x2: one product fuses, the other stays a mul
  r.code = {Instr{Op::Mul, {X(0), X(1)}}, Instr{Op::Mul, {X(1), X(2)}},
            Instr{Op::Add, {R(0), R(1)}}};
  r.outputs = {2};
  EXPECT_DOUBLE_EQ(m.programCost(r), price(Op::Mad) + price(Op::Mul));
  Program b;  // (x0*x1 + x0)*(x0*x1 - x2): the product fuses into both sums
  b.code = {Instr{Op::Mul, {X(0), X(1)}}, Instr{Op::Add, {R(0), X(0)}},
            Instr{Op::Sub, {R(0), X(2)}}, Instr{Op::Mul, {R(1), R(2)}}};
  b.outputs = {3};
  EXPECT_DOUBLE_EQ(m.programCost(b), 2 * price(Op::Mad) + price(Op::Mul));
  Program o;  // the product is also an output: it must be stored, nothing fuses
  o.code = {Instr{Op::Mul, {X(0), X(1)}}, Instr{Op::Add, {R(0), X(0)}}};
  o.outputs = {0, 1};
  EXPECT_DOUBLE_EQ(m.programCost(o), price(Op::Mul) + price(Op::Add));
}

}  // namespace
}  // namespace lgp
