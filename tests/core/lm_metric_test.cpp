// Levenberg-Marquardt on the configured error (LmObjective::Configured): for max_abs, mae,
// mean_rel and a Max over channels, a table and program whose least-squares constants are
// measurably worse on that error than what the reweighted rounds reach; the result is never
// worse than the start, and the Scorer's error is what is reported.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <vector>

#include "lgp/search/levenberg_marquardt.hpp"
#include "test_tables.hpp"

namespace lgp {
namespace {

// c0 + c1 x + c2 x^2 (linear in its constants: least squares has one optimum).
Program quadratic(float c0, float c1, float c2) {
  Program p;
  p.constants = {c0, c1, c2};
  p.code = {{Op::Mul, {inputOperand(0), constOperand(2)}},
            {Op::Add, {regOperand(0), constOperand(1)}},
            {Op::Mad, {regOperand(1), inputOperand(0), constOperand(0)}}};
  p.outputs = {2};
  return p;
}

// c0 x + c1
Program line(float c0, float c1) {
  Program p;
  p.constants = {c0, c1};
  p.code = {{Op::Mad, {inputOperand(0), constOperand(0), constOperand(1)}}};
  p.outputs = {0};
  return p;
}

// 2 x + 1, with every tenth row 5 above it.
Table outlierTable() {
  Table t = test::sampledTable(400, 22, [](double x) { return 2 * x + 1; });
  for (size_t r = 0; r < t.rows(); r += 10) t.outputs[0][r] += 5;
  return t;
}

struct Outcome {
  double start, least_squares, configured;
};

// The Scorer's error at p, after a least-squares fit and after a fit on the configured error,
// both from p with the same iteration budget.
Outcome fitBoth(const Table& t, const ErrorConfig& ec, const Program& p, int iterations) {
  const Dataset ds(t, 64);
  Scorer scorer(ds, ec, 64);
  ConstantFitter fitter(ds, ec);
  Outcome out{};
  Program q = p;
  out.start = scorer.error(q);
  LevenbergMarquardtConfig lm;
  lm.max_iterations = iterations;
  lm.objective = LmObjective::LeastSquares;
  fitter.fit(q, lm);
  out.least_squares = scorer.error(q);
  Program r = p;
  lm.objective = LmObjective::Configured;
  const ConstantFitResult res = fitter.fit(r, lm);
  out.configured = scorer.error(r);
  EXPECT_TRUE(fitter.reweights(lm));
  EXPECT_EQ(res.error_after, out.configured);  // what the Scorer measures, not a surrogate
  EXPECT_EQ(res.error_before, out.start);
  EXPECT_LE(out.configured, out.start);
  std::printf("start %.6g  least squares %.6g  configured %.6g (%d rounds, %d evaluations)\n",
              out.start, out.least_squares, out.configured, res.rounds, res.evaluations);
  return out;
}

// exp(x) on [-1, 1] by a quadratic: the minimax error (equioscillation) is about 0.045, the
// least-squares quadratic's largest error about 0.05-0.06 at the ends.
TEST(LmMetric, MaxAbsApproachesTheMinimaxFit) {
  const Table t = test::sampledTable(400, 21, [](double x) { return std::exp(x); });
  ErrorConfig ec;
  ec.metric = ErrorMetric::MaxAbs;
  const Outcome o = fitBoth(t, ec, quadratic(1, 1, 0.5f), 30);
  EXPECT_LT(o.configured, 0.9 * o.least_squares);
}

// A line with 10 % of the rows 5 above it: least squares is pulled up by the outliers, the L1
// fit goes through the other 90 %.
TEST(LmMetric, MaeIgnoresOutliersLikeTheL1Fit) {
  const Table t = outlierTable();
  ErrorConfig ec;
  ec.metric = ErrorMetric::Mae;
  const Outcome o = fitBoth(t, ec, line(1, 0), 30);
  EXPECT_LT(o.configured, 0.8 * o.least_squares);
}

// exp(4 x) spans 0.018 to 55: least squares fits the large values and leaves the small ones
// with relative errors far above 1; the relative fit balances them.
TEST(LmMetric, MeanRelFitsTheRelativeError) {
  const Table t = test::sampledTable(400, 23, [](double x) { return std::exp(4 * x); });
  ErrorConfig ec;
  ec.metric = ErrorMetric::MeanRel;
  const Outcome o = fitBoth(t, ec, quadratic(1, 1, 1), 30);
  EXPECT_LT(o.configured, 0.5 * o.least_squares);
}

// Two outputs share c0 (A = c0 x, B = c0 x^2 + c1 with targets x and 3 x^2): least squares
// (c0 = 1.42) leaves B's rmse near 0.46, twice A's; OutputCombine::Max wants them equal
// (c0 = 1.68, both near 0.39: 0.86 of least squares').
TEST(LmMetric, MaxOverChannelsLowersTheWorstChannel) {
  Table t = test::sampledTable(300, 24, [](double x) { return x; });
  t.output_names.push_back("B");
  t.outputs.push_back({});
  for (double x : t.inputs[0]) t.outputs[1].push_back(3 * x * x);
  Program p;
  p.constants = {1, 0};
  p.code = {{Op::Mul, {inputOperand(0), constOperand(0)}},
            {Op::Square, {inputOperand(0)}},
            {Op::Mad, {regOperand(1), constOperand(0), constOperand(1)}}};
  p.outputs = {0, 2};
  ErrorConfig ec;
  ec.metric = ErrorMetric::Rmse;
  ec.combine = OutputCombine::Max;
  const Outcome o = fitBoth(t, ec, p, 30);
  EXPECT_LT(o.configured, 0.92 * o.least_squares);
}

// From the configured optimum a second fit finds nothing: it keeps the constants and says it
// has converged (what lets the search skip the Nelder-Mead polish).
TEST(LmMetric, AFitFromItsOwnResultConverges) {
  const Table t = outlierTable();
  ErrorConfig ec;
  ec.metric = ErrorMetric::Mae;
  const Dataset ds(t, 64);
  ConstantFitter fitter(ds, ec);
  Program p = line(1, 0);
  LevenbergMarquardtConfig lm;
  lm.max_iterations = 30;
  ASSERT_TRUE(fitter.fit(p, lm).improved);
  // Twice: the first refit may still find a crumb.
  fitter.fit(p, lm);
  const Program before = p;
  const ConstantFitResult again = fitter.fit(p, lm);
  EXPECT_GT(again.rounds, 0);  // reweighted, not plain least squares
  EXPECT_FALSE(again.improved);
  EXPECT_TRUE(again.converged);
  EXPECT_EQ(p, before);
}

TEST(LmMetric, RmseOfOneChannelIsPlainLeastSquares) {
  const Table t = test::sampledTable(100, 25, [](double x) { return 2 * x + 1; });
  const Dataset ds(t, 64);
  ConstantFitter fitter(ds, ErrorConfig{});
  EXPECT_FALSE(fitter.reweights({}));
  Program p = line(0, 0);
  const ConstantFitResult res = fitter.fit(p, {});
  EXPECT_TRUE(res.improved);
  EXPECT_EQ(res.rounds, 0);
  EXPECT_TRUE(std::isnan(res.error_after));
}

// Under linear scaling the Scorer fits the scales by least squares: so does LM, whatever the
// metric (reweighted rounds with scales tuned to max_abs lost there, see docs).
TEST(LmMetric, LinearScalingStaysLeastSquares) {
  const Table t = test::sampledTable(100, 26, [](double x) { return std::exp(x); });
  ErrorConfig ec;
  ec.metric = ErrorMetric::MaxAbs;
  ec.linear_scaling = true;
  const Dataset ds(t, 64);
  ConstantFitter fitter(ds, ec);
  EXPECT_FALSE(fitter.reweights({}));
  ec.linear_scaling = false;
  EXPECT_TRUE(ConstantFitter(ds, ec).reweights({}));
}

TEST(LmMetric, ConfigValidatesRounds) {
  LevenbergMarquardtConfig lm;
  lm.max_rounds = 0;
  EXPECT_FALSE(lm.validate());
}

}  // namespace
}  // namespace lgp
