// Levenberg-Marquardt constant fitting: the residuals are the Scorer's, linear-in-constants
// programs reach their optimum in one Gauss-Newton step (plus the step that confirms it),
// nonlinear ones converge from bad starts, and non-finite trial points never leak into the
// constants.
#include "lgp/search/levenberg_marquardt.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "lgp/core/rng.hpp"
#include "lgp/core/variation.hpp"
#include "lgp/eval/objectives.hpp"

namespace lgp {
namespace {

// x in [lo, hi]; outputs filled by the caller.
Table inputsTable(int rows, double lo, double hi, int outputs, uint64_t seed) {
  Table t;
  Rng rng(seed);
  t.input_names = {"x"};
  t.inputs.resize(1);
  for (int r = 0; r < rows; ++r) t.inputs[0].push_back(rng.uniform(lo, hi));
  for (int o = 0; o < outputs; ++o) {
    t.output_names.push_back("y" + std::to_string(o));
    t.outputs.emplace_back(rows, 0.0);
  }
  return t;
}

// c0 x + c1 x^2 + c2
Program quadratic(float c0, float c1, float c2) {
  Program p;
  p.constants = {c0, c1, c2};
  p.code = {{Op::Mul, {inputOperand(0), constOperand(0)}},
            {Op::Square, {inputOperand(0)}},
            {Op::Mad, {regOperand(1), constOperand(1), regOperand(0)}},
            {Op::Add, {regOperand(2), constOperand(2)}}};
  p.outputs = {3};
  return p;
}

void expectRelativelyNear(const std::vector<float>& got, const std::vector<double>& want,
                          double rel) {
  ASSERT_EQ(got.size(), want.size());
  for (size_t i = 0; i < got.size(); ++i)
    EXPECT_NEAR(got[i], want[i], rel * std::fabs(want[i])) << "constant " << i;
}

TEST(LevenbergMarquardt, ConfigValidates) {
  EXPECT_TRUE(LevenbergMarquardtConfig{}.validate());
  EXPECT_FALSE((LevenbergMarquardtConfig{0, 1e-10}).validate());
  EXPECT_FALSE((LevenbergMarquardtConfig{10, -1}).validate());
}

TEST(LevenbergMarquardt, LinearInConstantsReachesTheOptimumInOneStep) {
  Table t = inputsTable(500, -2, 2, 1, 1);
  for (size_t r = 0; r < t.rows(); ++r) {
    const double x = t.inputs[0][r];
    t.outputs[0][r] = 1.5 * x - 0.7 * x * x + 0.3;
  }
  Dataset ds(t, 256);
  ConstantFitter fitter(ds, ErrorConfig{});
  Program p = quadratic(10, 10, -10);
  const ConstantFitResult res = fitter.fit(p, {});
  EXPECT_TRUE(res.improved);
  EXPECT_LE(res.iterations, 2);
  EXPECT_LT(res.sse_after, 1e-9 * res.sse_before);
  EXPECT_EQ(res.non_finite, 0);
  expectRelativelyNear(p.constants, {1.5, -0.7, 0.3}, 1e-4);
}

TEST(LevenbergMarquardt, WeightsAreHonoured) {
  // Rows with weight 0 carry garbage targets; the other weights vary. The optimum is still the
  // generating coefficients, and only if zero-weight rows are ignored.
  Table t = inputsTable(700, -2, 2, 1, 2);
  Rng rng(3);
  for (size_t r = 0; r < t.rows(); ++r) {
    const double x = t.inputs[0][r];
    const bool bad = r % 5 == 0;
    t.outputs[0][r] = 1.5 * x - 0.7 * x * x + 0.3 + (bad ? 100.0 : 0.0);
    t.weights.push_back(bad ? 0.0 : rng.uniform(0.1, 3.0));
  }
  Dataset ds(t, 64);
  ConstantFitter fitter(ds, ErrorConfig{});
  Program p = quadratic(-3, 4, 2);
  const ConstantFitResult res = fitter.fit(p, {});
  EXPECT_TRUE(res.improved);
  EXPECT_LE(res.iterations, 2);
  expectRelativelyNear(p.constants, {1.5, -0.7, 0.3}, 1e-4);
}

TEST(LevenbergMarquardt, ChannelsReachTheOptimumInOneStep) {
  // A = 0.8 x - 0.2, B = -0.5 x^2 + 1.2 x, measured only through A + B and 0.04 A + B.
  Table t = inputsTable(400, -2, 2, 2, 4);
  for (size_t r = 0; r < t.rows(); ++r) {
    const double x = t.inputs[0][r];
    t.outputs[0][r] = 0.8 * x - 0.2;
    t.outputs[1][r] = -0.5 * x * x + 1.2 * x;
  }
  Program p;
  p.constants = {3, 3, 3, 3};
  p.code = {{Op::Mad, {inputOperand(0), constOperand(0), constOperand(1)}},  // A = c0 x + c1
            {Op::Square, {inputOperand(0)}},
            {Op::Mul, {inputOperand(0), constOperand(3)}},
            {Op::Mad, {regOperand(1), constOperand(2), regOperand(2)}}};  // B = c2 x^2 + c3 x
  p.outputs = {0, 3};
  ErrorConfig ec;
  ec.channels = {{"F0=1", {1.0, 1.0}}, {"F0=0.04", {0.04, 1.0}}};
  Dataset ds(t, 128);
  ConstantFitter fitter(ds, ec);
  LevenbergMarquardtConfig lm;
  lm.objective = LmObjective::LeastSquares;  // rmse over two channels is reweighted otherwise
  const ConstantFitResult res = fitter.fit(p, lm);
  EXPECT_TRUE(res.improved);
  EXPECT_LE(res.iterations, 2);
  expectRelativelyNear(p.constants, {0.8, -0.2, -0.5, 1.2}, 1e-4);
}

TEST(LevenbergMarquardt, LinearScalingFitsTheScaledModel) {
  // y = 2 (x^2 + 0.5 x) + 1; the program x^2 + c0 x. Under linear scaling a (x^2 + c0 x) + b
  // is bilinear in (a, c0), so Gauss-Newton is not exact in one step: a few iterations.
  Table t = inputsTable(500, -2, 2, 1, 5);
  for (size_t r = 0; r < t.rows(); ++r) {
    const double x = t.inputs[0][r];
    t.outputs[0][r] = 2 * (x * x + 0.5 * x) + 1;
  }
  Program p;
  p.constants = {4};
  p.code = {{Op::Square, {inputOperand(0)}},
            {Op::Mad, {inputOperand(0), constOperand(0), regOperand(0)}}};
  p.outputs = {1};
  ErrorConfig ec;
  ec.linear_scaling = true;
  Dataset ds(t, 256);
  ConstantFitter fitter(ds, ec);
  const ConstantFitResult res = fitter.fit(p, {});
  EXPECT_TRUE(res.improved);
  EXPECT_LE(res.iterations, 10);
  expectRelativelyNear(p.constants, {0.5}, 1e-4);
  // The Scorer's closed-form scaling then fits exactly.
  Scorer s(ds, ec, 256);
  EXPECT_LT(s.error(p), 1e-5);
  EXPECT_NEAR(s.scales()[0].a, 2.0f, 1e-4);
  EXPECT_NEAR(s.scales()[0].b, 1.0f, 1e-4);
}

TEST(LevenbergMarquardt, LinearScalingOfALinearProgram) {
  // a (c0 x + c1 x^2 + c2) + b: the scale is redundant with the constants (a rank-deficient
  // Jacobian), which the solver handles; the model reaches the data.
  Table t = inputsTable(500, -2, 2, 1, 6);
  for (size_t r = 0; r < t.rows(); ++r) {
    const double x = t.inputs[0][r];
    t.outputs[0][r] = 1.5 * x - 0.7 * x * x + 0.3;
  }
  ErrorConfig ec;
  ec.linear_scaling = true;
  Dataset ds(t, 256);
  ConstantFitter fitter(ds, ec);
  Program p = quadratic(10, 10, -10);
  const ConstantFitResult res = fitter.fit(p, {});
  EXPECT_TRUE(res.improved);
  EXPECT_LT(res.sse_after, 1e-9 * res.sse_before);
  Scorer s(ds, ec, 256);
  EXPECT_LT(s.error(p), 1e-5);
}

// Residuals on the original scale through every inverse transform: y = T^-1(0.5 x + 1.5), the
// program c0 x + c1 (predicting T(y)) started at (0.2, 2.5).
TEST(LevenbergMarquardt, ConvergesThroughEveryInverseTransform) {
  for (TargetTransform tr : {TargetTransform::Log, TargetTransform::Sqrt, TargetTransform::Rcp}) {
    SCOPED_TRACE(std::string(toString(tr)));
    Table t = inputsTable(300, -1, 1, 1, 7);
    for (size_t r = 0; r < t.rows(); ++r)
      t.outputs[0][r] = invertTransform(tr, 0.5 * t.inputs[0][r] + 1.5);
    Program p;
    p.constants = {0.2f, 2.5f};
    p.code = {{Op::Mad, {inputOperand(0), constOperand(0), constOperand(1)}}};
    p.outputs = {0};
    ErrorConfig ec;
    ec.transforms = {tr};
    Dataset ds(t, 64);
    ConstantFitter fitter(ds, ec);
    const ConstantFitResult res = fitter.fit(p, {30, 1e-12});
    EXPECT_TRUE(res.improved);
    // Exact derivatives give Gauss-Newton's quadratic convergence on this zero-residual
    // problem (5 to 7 iterations); a wrong chain rule through the inverse converges linearly.
    EXPECT_LE(res.iterations, 10);
    expectRelativelyNear(p.constants, {0.5, 1.5}, 1e-4);
  }
}

TEST(LevenbergMarquardt, NonlinearProgramConvergesFromABadStart) {
  // y = exp2(0.8 x) * 1.7, started with the wrong sign and a tiny amplitude.
  Table t = inputsTable(300, -2, 2, 1, 8);
  for (size_t r = 0; r < t.rows(); ++r) t.outputs[0][r] = std::exp2(0.8 * t.inputs[0][r]) * 1.7;
  Program p;
  p.constants = {-1.0f, 0.1f};
  p.code = {{Op::Mul, {inputOperand(0), constOperand(0)}},
            {Op::Exp2, {regOperand(0)}},
            {Op::Mul, {regOperand(1), constOperand(1)}}};
  p.outputs = {2};
  Dataset ds(t, 64);
  ConstantFitter fitter(ds, ErrorConfig{});
  const ConstantFitResult res = fitter.fit(p, {50, 1e-12});
  EXPECT_TRUE(res.improved);
  expectRelativelyNear(p.constants, {0.8, 1.7}, 1e-4);
}

TEST(LevenbergMarquardt, NonFiniteTrialStepsAreRejected) {
  // square(c0 x) with x ~ 1e18 overflows float once c0 x > 1.8e19. For y = (5 x)^2 from
  // c0 = 1, the Gauss-Newton step (c0 ~ 13) overflows on the largest rows: that trial must be
  // rejected, and the fit still reach c0 = 5.
  Table t = inputsTable(200, 1e18, 2e18, 1, 9);
  for (size_t r = 0; r < t.rows(); ++r) t.outputs[0][r] = std::pow(5 * t.inputs[0][r], 2);
  Program p;
  p.constants = {1.0f};
  p.code = {{Op::Mul, {inputOperand(0), constOperand(0)}}, {Op::Square, {regOperand(0)}}};
  p.outputs = {1};
  Dataset ds(t, 64);
  ConstantFitter fitter(ds, ErrorConfig{});
  const ConstantFitResult res = fitter.fit(p, {50, 1e-12});
  EXPECT_GT(res.non_finite, 0);
  EXPECT_TRUE(std::isfinite(p.constants[0]));
  EXPECT_TRUE(res.improved);
  EXPECT_TRUE(std::isfinite(res.sse_after));
  expectRelativelyNear(p.constants, {5.0}, 1e-4);
}

TEST(LevenbergMarquardt, ProgramWithoutConstantsIsLeftAlone) {
  Table t = inputsTable(50, -1, 1, 1, 10);
  Program p;
  p.constants = {2.0f};  // present but not effective
  p.code = {{Op::Square, {inputOperand(0)}}, {Op::Mul, {inputOperand(0), constOperand(0)}}};
  p.outputs = {0};
  Dataset ds(t, 64);
  ConstantFitter fitter(ds, ErrorConfig{});
  const Program before = p;
  const ConstantFitResult res = fitter.fit(p, {});
  EXPECT_FALSE(res.improved);
  EXPECT_EQ(res.evaluations, 0);
  EXPECT_EQ(res.iterations, 0);
  EXPECT_EQ(p, before);
}

// Random programs over every operator on a two-output table with channels, a transform and
// weights, fitted by plain least squares: sse_before is the Scorer's weighted SSE (so the residuals
// are the Scorer's), the constants stay finite, change only when the sum went down, and then the
// Scorer agrees. (Trial steps rarely overflow here; NonFiniteTrialStepsAreRejected forces that
// path.)
TEST(LevenbergMarquardt, RandomProgramsKeepFiniteConstantsAndMatchTheScorer) {
  Table t = inputsTable(300, -3, 3, 2, 12);
  t.input_names = {"x", "z"};
  t.inputs.emplace_back();
  Rng rng(13);
  for (size_t r = 0; r < t.rows(); ++r) {
    const double x = t.inputs[0][r];
    t.inputs[1].push_back(rng.uniform(0.1, 2));
    t.outputs[0][r] = std::sin(1.3 * x) + 0.5 * t.inputs[1][r];
    t.outputs[1][r] = std::exp(0.3 * x) * t.inputs[1][r];
    t.weights.push_back(r % 7 == 0 ? 0.0 : rng.uniform(0.5, 2));
  }
  ErrorConfig ec;
  ec.channels = {{"A+B", {1.0, 1.0}}, {"A-B/2", {1.0, -0.5}}};
  ec.transforms = {TargetTransform::None, TargetTransform::Log};
  Dataset ds(t, 64);
  ConstantFitter fitter(ds, ec);
  Scorer scorer(ds, ec, 64);
  ProgramShape shape;
  shape.num_inputs = 2;
  shape.num_outputs = 2;
  shape.max_length = 16;
  shape.num_constants = 4;
  shape.output_mode = OutputMode::Designated;
  const InitConfig init{3, 16, -3, 3};
  int improved = 0;
  for (int trial = 0; trial < 300; ++trial) {
    Rng prng(500 + trial);
    Program p = randomProgram(shape, init, prng);
    const Program before = p;
    const auto sse = [&](const Program& q) {
      double s = 0;
      for (const OutputMetrics& m : scorer.channelMetrics(q)) s += m.rmse * m.rmse;
      return s * ds.weightSum();
    };
    const double scorer_before = sse(p);
    const ConstantFitResult res = fitter.fit(p, {10, 1e-10, LmObjective::LeastSquares});
    for (float c : p.constants) ASSERT_TRUE(std::isfinite(c)) << "trial " << trial;
    if (res.evaluations > 0 && std::isfinite(scorer_before)) {
      EXPECT_NEAR(res.sse_before, scorer_before, 1e-5 * scorer_before + 1e-9) << trial;
    }
    if (!res.improved) {
      EXPECT_EQ(p, before) << "trial " << trial;
      continue;
    }
    ++improved;
    EXPECT_LT(res.sse_after, res.sse_before);
    ASSERT_TRUE(std::isfinite(res.sse_after));
    const double scorer_after = sse(p);
    EXPECT_NEAR(res.sse_after, scorer_after, 1e-5 * scorer_after + 1e-9) << trial;
  }
  EXPECT_GT(improved, 100);
}

}  // namespace
}  // namespace lgp
