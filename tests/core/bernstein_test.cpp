// Bernstein bounds (core/bernstein.hpp): they enclose every value of the polynomial on the
// box, are exact at the box's corners' extremes for a monotone polynomial, and tighten when
// the box shrinks.
#include <gtest/gtest.h>

#include <cmath>

#include "lgp/core/bernstein.hpp"

namespace lgp {
namespace {

double eval(const Polynomial& p, double x, double y) {
  double v = 0;
  for (const auto& [e, c] : p) v += c * std::pow(x, e[0]) * std::pow(y, e[1]);
  return v;
}

TEST(Bernstein, TheBoundEnclosesEveryValueOnTheBox) {
  // MaterialX's DFG denominator for B (tensor degree 2 in x and y): large coefficients of both
  // signs, so the bound is loose over the whole box and must still enclose it.
  const Polynomial q = {{{0, 0}, 1.0},    {{1, 0}, 0.2281}, {{0, 1}, 15.94},
                        {{1, 1}, -55.83}, {{2, 0}, 13.08},  {{0, 2}, 41.26},
                        {{2, 1}, 54.9},   {{1, 2}, 300.2},  {{2, 2}, -285.1}};
  for (const auto& [x0, x1, y0, y1] :
       {std::array<double, 4>{0, 1, 0, 1}, std::array<double, 4>{0.2, 0.3, 0.5, 0.75},
        std::array<double, 4>{-1, 0.5, 0.9, 1}}) {
    const Interval b = bernsteinRange(q, {{x0, x1, false}, {y0, y1, false}});
    ASSERT_FALSE(b.nan);
    double lo = INFINITY, hi = -INFINITY;
    for (int i = 0; i <= 50; ++i)
      for (int j = 0; j <= 50; ++j) {
        const double v = eval(q, x0 + (x1 - x0) * i / 50, y0 + (y1 - y0) * j / 50);
        lo = std::min(lo, v);
        hi = std::max(hi, v);
      }
    EXPECT_LE(b.lo, lo + 1e-9);
    EXPECT_GE(b.hi, hi - 1e-9);
  }
}

TEST(Bernstein, ExactForAMonotonePolynomialAndTighterOnSmallerBoxes) {
  // 1 + x + x*y on [0, 1]^2: increasing in both, range [1, 3]: the bound is exact.
  const Polynomial p = {{{0, 0}, 1.0}, {{1, 0}, 1.0}, {{1, 1}, 1.0}};
  const Interval b = bernsteinRange(p, {{0, 1, false}, {0, 1, false}});
  EXPECT_NEAR(b.lo, 1.0, 1e-12);
  EXPECT_NEAR(b.hi, 3.0, 1e-12);
  // (x - 0.5)^2 on [0, 1]: Bernstein coefficients 0.25, -0.25, 0.25 (a loose lower bound);
  // on [0.4, 0.6] it is within 0.01 of the true [0, 0.01].
  const Polynomial s = {{{0}, 0.25}, {{1}, -1.0}, {{2}, 1.0}};
  const Interval wide = bernsteinRange(s, {{0, 1, false}});
  EXPECT_NEAR(wide.lo, -0.25, 1e-12);
  EXPECT_NEAR(wide.hi, 0.25, 1e-12);
  const Interval tight = bernsteinRange(s, {{0.4, 0.6, false}});
  EXPECT_LE(tight.lo, 0.0);
  EXPECT_GT(tight.lo, -0.011);
  EXPECT_NEAR(tight.hi, 0.01, 1e-12);
  EXPECT_FALSE(bernsteinRange({}, {{0, 1, false}}).nan);
}

TEST(Bernstein, TooManyVariablesGiveNoBound) {
  // 1 + sum x_i over 30 variables: 2^30 coefficients, past the limit: the whole line.
  Polynomial p = {{std::vector<int>(30, 0), 1.0}};
  for (int i = 0; i < 30; ++i) {
    std::vector<int> e(30, 0);
    e[i] = 1;
    p[e] = 1.0;
  }
  const Interval b = bernsteinRange(p, std::vector<Interval>(30, Interval{0, 1, false}));
  EXPECT_TRUE(b.nan);
  EXPECT_FALSE(b.finite());
  // 20 variables (2^20 coefficients) are bounded: [1, 21].
  Polynomial q = {{std::vector<int>(20, 0), 1.0}};
  for (int i = 0; i < 20; ++i) {
    std::vector<int> e(20, 0);
    e[i] = 1;
    q[e] = 1.0;
  }
  const Interval c = bernsteinRange(q, std::vector<Interval>(20, Interval{0, 1, false}));
  EXPECT_FALSE(c.nan);
  EXPECT_NEAR(c.lo, 1.0, 1e-9);
  EXPECT_NEAR(c.hi, 21.0, 1e-9);
}

}  // namespace
}  // namespace lgp
