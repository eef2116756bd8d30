#include "lgp/datasets/energy.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "lgp/datasets/dfg.hpp"

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
