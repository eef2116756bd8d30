#include "lgp/datasets/quadrature.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

using namespace lgp::datasets;

TEST(Quadrature, GaussLegendreNodesAndWeights) {
  for (int n : {1, 2, 5, 16, 33, 64}) {
    const GaussRule& g = gaussLegendre(n);
    ASSERT_EQ(static_cast<int>(g.x.size()), n);
    double sw = 0;
    for (int i = 0; i < n; ++i) {
      EXPECT_GT(g.x[i], 0.0);
      EXPECT_LT(g.x[i], 1.0);
      if (i) {
        EXPECT_LT(g.x[i - 1], g.x[i]);
      }
      sw += g.w[i];
    }
    EXPECT_NEAR(sw, 1.0, 1e-14);
    // exact for polynomials of degree 2n - 1 on [0, 1]
    const int d = 2 * n - 1;
    double s = 0;
    for (int i = 0; i < n; ++i) s += g.w[i] * std::pow(g.x[i], d);
    EXPECT_NEAR(s, 1.0 / (d + 1), 1e-14) << "n=" << n;
  }
  EXPECT_NEAR(gaussLegendre(2).x[0], 0.5 - 0.5 / std::sqrt(3.0), 1e-16);
}

TEST(Quadrature, ProductGaussSmooth2D) {
  auto f = [](const std::array<double, 2>& p, std::array<double, 1>& o) {
    o[0] = std::exp(p[0]) * std::cos(p[1]);
  };
  const Box<2> b{{0.0, 0.0}, {1.0, 0.5 * std::numbers::pi}};
  auto e = gaussProduct<2, 1>(f, std::span<const Box<2>>(&b, 1), 8);
  EXPECT_NEAR(e.value[0], std::exp(1.0) - 1.0, 1e-13);
  EXPECT_LT(e.error[0], 1e-10);
}

TEST(Quadrature, AdaptiveReachesToleranceOnKinkAndPeak) {
  // |x - 1/3| kink and a narrow peak: int_0^1 int_0^1 |x - 1/3| + 1e-3/((y-0.7)^2 + 1e-6) dx dy
  auto f = [](const std::array<double, 2>& p, std::array<double, 1>& o) {
    o[0] = std::abs(p[0] - 1.0 / 3.0) + 1e-3 / ((p[1] - 0.7) * (p[1] - 0.7) + 1e-6);
  };
  const double exact = 5.0 / 18.0 + 1e-3 * 1e3 * (std::atan(0.3e3) + std::atan(0.7e3));
  const Box<2> b{{0.0, 0.0}, {1.0, 1.0}};
  AdaptiveOptions o;
  o.abs_tol = 1e-8;
  o.max_evals = 5000000;
  auto e = adaptive<2, 1>(f, std::span<const Box<2>>(&b, 1), o);
  EXPECT_TRUE(e.converged);
  EXPECT_LE(e.error[0], 1e-8);
  EXPECT_NEAR(e.value[0], exact, 1e-8);
}

TEST(Quadrature, QmcErrorEstimateCoversTheTruth) {
  auto f = [](const std::array<double, 2>& p, std::array<double, 1>& o) {
    o[0] = p[0] < p[1] ? 1.0 : 0.0;  // discontinuous: area 1/2
  };
  QmcOptions q;
  q.points = 4096;
  auto e = qmc<2, 1>(f, q);
  EXPECT_NEAR(e.value[0], 0.5, std::max(e.error[0], 1e-6));
  EXPECT_LT(e.error[0], 1e-2);
  EXPECT_EQ(e.evals, 4096u * 8u);
}

TEST(Quadrature, ManyBoxesSumWithoutDriftAndTheEstimateCoversRounding) {
  // 4096 boxes of an order-32/64 rule: every box is summed on its own and the boxes in
  // compensated arithmetic, so the total stays within a few ulps; the estimate includes the
  // rounding floor, so it is never below what double precision can deliver.
  auto f = [](const std::array<double, 1>& p, std::array<double, 1>& o) { o[0] = std::exp(p[0]); };
  std::vector<Box<1>> boxes;
  for (int i = 0; i < 4096; ++i) boxes.push_back({{i / 4096.0}, {(i + 1) / 4096.0}});
  auto e = gaussProduct<1, 1>(f, std::span<const Box<1>>(boxes), 32);
  const double exact = std::exp(1.0) - 1.0;
  EXPECT_NEAR(e.value[0], exact, 4e-16);
  EXPECT_GE(e.error[0], kRoundoff * exact);
  EXPECT_LE(std::abs(e.value[0] - exact), e.error[0]);
  AdaptiveOptions o;
  o.abs_tol = 1e-13;
  auto a = adaptive<1, 1>(f, std::span<const Box<1>>(boxes), o);
  EXPECT_NEAR(a.value[0], exact, 4e-16);
  EXPECT_LE(std::abs(a.value[0] - exact), a.error[0]);
}

TEST(Quadrature, ScaledRegionEstimate) {
  // Never below the raw difference; grows where the rules differ by more than 1/c^3 of the
  // variation; unchanged (raw) once the region is resolved.
  EXPECT_EQ(detail::scaledError(0.0, 1.0), 0.0);
  EXPECT_EQ(detail::scaledError(1e-12, 1.0), 1e-12);
  EXPECT_EQ(detail::scaledError(1e-5, 1.0), 1e-5);  // below 1/c^3 = 1.25e-4: resolved
  EXPECT_GT(detail::scaledError(1e-2, 1.0), 5 * 1e-2);
  EXPECT_LE(detail::scaledError(0.5, 1.0), 1.0);
  EXPECT_EQ(detail::scaledError(1e-6, 0.0), 1e-6);
}
