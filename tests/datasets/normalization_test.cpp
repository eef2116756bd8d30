#include "lgp/datasets/normalization.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

using namespace lgp::datasets;

namespace {
IntegratorOptions method(IntegratorKind k) {
  IntegratorOptions o;
  o.kind = k;
  o.abs_tol = 1e-7;
  o.qmc_points = 1 << 15;
  return o;
}
constexpr auto kCorr = Visibility::SmithCorrelated;
}  // namespace

TEST(Normalization, TendsToOneForSmallLights) {
  const auto o = method(IntegratorKind::Adaptive);
  EXPECT_EQ(normalizationPoint(0.25, 0.0, kCorr, -3, o).N, 1.0);
  for (double r : {0.3, 0.6, 1.0}) {
    double prev_dev = 1.0;
    for (double ts : {0.1, 0.01, 1e-3, 1e-4}) {
      const double n = normalizationPoint(r * r, ts, kCorr, -3, o).N;
      const double dev = std::abs(n - 1.0);
      EXPECT_LT(dev, prev_dev + 1e-9) << r << " " << ts;
      prev_dev = dev;
    }
    EXPECT_LT(prev_dev, 2e-3) << r;
  }
}

TEST(Normalization, MonotoneAndSmoothInThetaS) {
  auto o = method(IntegratorKind::Adaptive);
  o.abs_tol = 1e-6;
  const std::vector<double> ts = {0.0, 0.01, 0.03, 0.1, 0.2, 0.3, 0.4, 0.5,
                                  0.6, 0.7,  0.8,  0.9, 1.0, 1.1, 1.2, 1.3};
  for (double r : {0.1, 0.3, 0.6, 1.0}) {
    std::vector<double> n;
    for (double t : ts) n.push_back(normalizationPoint(r * r, t, kCorr, -3, o).N);
    const double sign = n.back() > n.front() ? 1.0 : -1.0;
    for (size_t i = 1; i < n.size(); ++i) {
      ASSERT_TRUE(std::isfinite(n[i]));
      EXPECT_GT(sign * (n[i] - n[i - 1]), 0.0) << "r=" << r << " theta_s=" << ts[i];
    }
    // smooth: log N at midpoints is predicted by cubic interpolation of its neighbours
    // (a kink or a wiggle would not be)
    for (size_t i = 5; i + 2 < ts.size(); i += 3) {
      const double mid = 0.5 * (ts[i] + ts[i + 1]);
      const double cubic =
          (-std::log(n[i - 1]) + 9 * std::log(n[i]) + 9 * std::log(n[i + 1]) - std::log(n[i + 2])) /
          16.0;
      const double exact = std::log(normalizationPoint(r * r, mid, kCorr, -3, o).N);
      EXPECT_NEAR(exact, cubic, 2e-3) << "r=" << r << " theta_s=" << mid;
    }
  }
}

TEST(Normalization, TwoIndependentIntegratorsAgree) {
  // QMC evaluates the 4-D double integral (cone x hemisphere) without the reciprocity
  // reduction, and the representative point with 3-D vectors.
  for (double r : {0.4, 0.7, 1.0})
    for (double ts : {0.1, 0.4, 0.9}) {
      const auto a = normalizationPoint(r * r, ts, kCorr, -3, method(IntegratorKind::Adaptive));
      const auto g = normalizationPoint(r * r, ts, kCorr, -3, method(IntegratorKind::Gauss));
      const auto q = normalizationPoint(r * r, ts, kCorr, -3, method(IntegratorKind::Qmc));
      EXPECT_NEAR(a.N, g.N, g.error + 1e-6) << r << " " << ts;
      EXPECT_NEAR(a.N, q.N, q.error + 1e-6) << r << " " << ts;
      EXPECT_LT(q.error / q.N, 5e-3);
      EXPECT_LT(a.error, 1e-6);
    }
}

TEST(Normalization, HardCasesFinite) {
  auto o = method(IntegratorKind::Adaptive);
  o.abs_tol = 1e-5;
  for (double r : {0.0, 1e-3, 0.05, 1.0})
    for (double ts : {0.0, 1e-6, 0.5, 1.5}) {
      const auto v = normalizationPoint(r * r, ts, kCorr, -3, o);
      EXPECT_TRUE(std::isfinite(v.N) && std::isfinite(v.error)) << r << " " << ts;
      EXPECT_GE(v.N, 0.0);
    }
  EXPECT_EQ(normalizationPoint(0.0, 0.3, kCorr, -3, o).N, 0.0);  // documented alpha -> 0 limit
}

TEST(Normalization, RepresentativePointHardMinLimit) {
  // With a very negative s the soft minimum becomes Karis' clamp: inside the cone the
  // representative point is the reflection vector itself.
  const double n[3] = {0, 0, 1};
  const double th = 0.1;
  const double v[3] = {std::sin(th), 0, std::cos(th)};
  double l[3];
  representativePoint(v, n, n, 0.3, -200.0, l);
  EXPECT_NEAR(l[0], -std::sin(th), 1e-6);
  EXPECT_NEAR(l[2], std::cos(th), 1e-6);
  // outside the cone it is c + R * unit(centerToRay) (eq. 2b with the clamp at 1)
  const double v2[3] = {std::sin(1.0), 0, std::cos(1.0)};
  representativePoint(v2, n, n, 0.3, -200.0, l);
  const double R = std::sin(0.3);
  EXPECT_NEAR(std::atan2(-l[0], l[2]), std::atan2(R * std::cos(1.0), 1.0 - R * std::sin(1.0)),
              1e-6);
}
