#include <gtest/gtest.h>

#include <cmath>

#include "lgp/search/nelder_mead.hpp"

namespace lgp {
namespace {

TEST(NelderMead, SolvesRosenbrock) {
  auto f = [](const std::vector<double>& x) {
    return 100 * std::pow(x[1] - x[0] * x[0], 2) + std::pow(1 - x[0], 2);
  };
  NelderMeadConfig cfg;
  cfg.max_evaluations = 4000;
  cfg.restarts = 3;
  cfg.tolerance = 1e-14;
  Rng rng(1);
  const auto r = nelderMead(f, {-1.2, 1.0}, cfg, rng);
  EXPECT_NEAR(r.x[0], 1.0, 1e-4);
  EXPECT_NEAR(r.x[1], 1.0, 1e-4);
  EXPECT_LT(r.f, 1e-8);
  EXPECT_LE(r.evaluations, cfg.max_evaluations + 4);
}

TEST(NelderMead, SolvesNoisyQuadratic) {
  // Deterministic pseudo-noise of amplitude 1e-6 on a 4-D quadratic with minimum at c.
  const std::vector<double> c = {0.5, -2.0, 3.0, 0.25};
  auto f = [&](const std::vector<double>& x) {
    double s = 0, h = 0;
    for (size_t i = 0; i < x.size(); ++i) {
      s += (i + 1) * (x[i] - c[i]) * (x[i] - c[i]);
      h += std::sin(1e4 * x[i] * (i + 3));
    }
    return s + 1e-6 * h;
  };
  NelderMeadConfig cfg;
  cfg.max_evaluations = 3000;
  cfg.restarts = 4;
  Rng rng(2);
  const auto r = nelderMead(f, {0, 0, 0, 0}, cfg, rng);
  for (size_t i = 0; i < c.size(); ++i) EXPECT_NEAR(r.x[i], c[i], 5e-3) << i;
}

TEST(NelderMead, NonFiniteValuesAreWorst) {
  auto f = [](const std::vector<double>& x) { return x[0] < 0 ? NAN : (x[0] - 1) * (x[0] - 1); };
  NelderMeadConfig cfg;
  cfg.max_evaluations = 500;
  Rng rng(3);
  const auto r = nelderMead(f, {0.1}, cfg, rng);
  EXPECT_NEAR(r.x[0], 1.0, 1e-3);
  EXPECT_TRUE(std::isfinite(r.f));
}

TEST(NelderMead, ConfigValidation) {
  NelderMeadConfig cfg;
  EXPECT_TRUE(cfg.validate());
  cfg.rho = 1.5;
  EXPECT_FALSE(cfg.validate());
}

}  // namespace
}  // namespace lgp
