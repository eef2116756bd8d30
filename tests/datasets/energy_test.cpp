#include "lgp/datasets/energy.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "lgp/datasets/dfg.hpp"
#include "lgp/datasets/generate.hpp"
#include "lgp/datasets/quadrature.hpp"

using namespace lgp::datasets;

TEST(Energy, FavgClosedForm) {
  for (double f0 : {0.0, 0.04, 0.5, 1.0})
    for (double f90 : {1.0, 0.5}) {
      EXPECT_NEAR(fresnelAverageNumeric(f0, f90), fresnelAverageClosed(f0, f90), 1e-15);
      EXPECT_NEAR(fresnelAverageClosed(f0, 1.0), f0 + (1.0 - f0) / 21.0, 1e-16);
    }
}

TEST(Energy, EavgAgainstIndependentQuadrature) {
  // Independent: Gauss-Legendre directly in mu (no sqrt substitution) over QMC-free E values.
  IntegratorOptions o;
  o.abs_tol = 1e-7;
  for (double alpha : {0.1, 0.5, 1.0}) {
    const EavgValue e = eAvg(alpha, Visibility::SmithCorrelated, o);
    double s = 0;
    const int n = 200;  // composite midpoint in mu
    for (int i = 0; i < n; ++i) {
      const double mu = (i + 0.5) / n;
      s += 2.0 * mu * dfgPoint(mu, alpha, Visibility::SmithCorrelated, false, o).E / n;
    }
    EXPECT_NEAR(e.value, s, 2e-5) << alpha;
    EXPECT_LT(e.error, 1e-6);
    EXPECT_GT(e.value, 0.0);
    EXPECT_LE(e.value, 1.0);
  }
  EXPECT_EQ(eAvg(0.0, Visibility::SmithCorrelated, o).value, 1.0);
  // E_avg decreases with roughness (more energy lost to single scattering)
  EXPECT_GT(eAvg(0.2, Visibility::SmithCorrelated, o).value,
            eAvg(0.8, Visibility::SmithCorrelated, o).value);
}

TEST(Energy, MultipleScatteringFactors) {
  // Turquin 2019: f_ss (1 + F0 (1 - E) / E) has albedo E + F0 (1 - E) for F0 = 1: exactly 1.
  for (double e : {0.3, 0.7, 1.0}) EXPECT_NEAR(e * (1.0 + msTurquin(e, 0).value), 1.0, 1e-15);
  EXPECT_EQ(msTurquin(1.0, 0.0).value, 0.0);
  EXPECT_NEAR(msTurquin(0.5, 1e-6).error, 4e-6, 1e-18);  // d/dE = -1/E^2
  EXPECT_EQ(msLobe(1.0, 0, 1.0, 0).value, 0.0);          // alpha = 0
}

// The white furnace with the table's own columns: E(mu_o) plus the Kulla-Conty lobe
// f_ms = ms_lobe(n.l) ms_lobe(n.v) integrated over l gives 1, i.e.
// 2 pi int_0^1 ms_lobe(mu) mu dmu ms_lobe(mu_o) = 1 - E(mu_o). The light directions are the
// table's mu column, at Gauss-Legendre nodes in x = sqrt(mu) (an independent rule: E_avg is
// integrated with 24 nodes on its own panels).
TEST(Energy, KullaContyLobeClosesTheFurnace) {
  const GaussRule& g = gaussLegendre(40);
  nlohmann::json mus = nlohmann::json::array();
  for (double x : g.x) mus.push_back(x * x);
  nlohmann::json j = {{"material", {{"fresnel", "none"}}},
                      {"outputs", {"E", "E_avg", "ms_lobe"}},
                      {"grid", {{"mu", {{"values", mus}}}, {"r", {{"values", {0.5, 0.8, 1.0}}}}}},
                      {"accuracy", {{"abs_error", 1e-8}}}};
  auto s = parseScene(j, "furnace");
  ASSERT_TRUE(s) << s.error();
  auto t = generate(*s);
  ASSERT_TRUE(t) << t.error();
  const size_t n = g.x.size();
  for (size_t ir = 0; ir < 3; ++ir) {
    double integral = 0;  // 2 pi int ms_lobe(mu) mu dmu = 2 pi int ms_lobe(x^2) x^2 2x dx
    for (size_t i = 0; i < n; ++i)
      integral += 2.0 * std::numbers::pi * g.w[i] * t->table.outputs[2][ir * n + i] * 2.0 * g.x[i] *
                  g.x[i] * g.x[i];
    for (size_t i = 0; i < n; i += 7) {
      const size_t row = ir * n + i;
      const double e = t->table.outputs[0][row];
      EXPECT_NEAR(e + integral * t->table.outputs[2][row], 1.0, 2e-6) << ir << " " << i;
    }
  }
}
