// dfg: check values (docs/tables.md), limits, hard cases and cross-checks of independent
// integrators.
#include "lgp/datasets/dfg.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>
#include "integrator_options.hpp"

using namespace lgp::datasets;

namespace {
IntegratorOptions method(IntegratorKind k, double tol = 1e-8) {
  return test::method(k, tol);
}
constexpr auto kCorr = Visibility::SmithCorrelated;
}  // namespace

TEST(Dfg, CheckValuesFromTables) {
  struct P {
    double mu, alpha, e;
  } pts[] = {{1.0, 1.0, 0.30686}, {0.5, 1.0, 0.45069}, {0.5, 0.25, 0.85726}, {0.2, 0.5, 0.78993}};
  for (auto p : pts) {
    const DfgValue v = dfgPoint(p.mu, p.alpha, kCorr, true, method(IntegratorKind::Adaptive));
    // The check value 0.30686 is 1 - ln 2 = 0.3068528 rounded up; 1e-5 covers that, and the
    // closed form is checked to 1e-9 below.
    EXPECT_NEAR(v.E, p.e, 1e-5) << "mu=" << p.mu << " alpha=" << p.alpha;
    if (p.mu != 1.0) {
      EXPECT_NEAR(v.E, p.e, 5e-6) << "mu=" << p.mu << " alpha=" << p.alpha;
    }
    EXPECT_NEAR(v.A + v.B, v.E, 1e-15);
    EXPECT_LT(v.err_E, 1e-7);
    EXPECT_TRUE(v.converged);
  }
  // closed form at mu = 1, alpha = 1: E = 1 - ln 2
  const DfgValue v = dfgPoint(1.0, 1.0, kCorr, false, method(IntegratorKind::Adaptive, 1e-10));
  EXPECT_NEAR(v.E, 1.0 - std::log(2.0), 1e-9);
}

TEST(Dfg, GaussAdaptiveAndQmcAgree) {
  for (double mu : {0.05, 0.3, 0.7, 1.0})
    for (double alpha : {0.04, 0.3, 0.8}) {
      const DfgValue a = dfgPoint(mu, alpha, kCorr, true, method(IntegratorKind::Adaptive));
      const DfgValue g = dfgPoint(mu, alpha, kCorr, true, method(IntegratorKind::Gauss));
      const DfgValue q = dfgPoint(mu, alpha, kCorr, true, method(IntegratorKind::Qmc));
      // Every method's own estimate must cover its distance to the tight adaptive result.
      EXPECT_NEAR(g.A, a.A, g.err_A + 1e-7) << mu << " " << alpha;
      EXPECT_NEAR(g.B, a.B, g.err_B + 1e-7) << mu << " " << alpha;
      EXPECT_NEAR(q.A, a.A, q.err_A + 1e-7) << mu << " " << alpha;
      EXPECT_NEAR(q.B, a.B, q.err_B + 1e-7) << mu << " " << alpha;
      EXPECT_LT(q.err_A, 2e-3);
    }
}

TEST(Dfg, MirrorLimit) {
  for (double mu : {0.0, 0.1, 0.5, 1.0}) {
    const DfgValue z = dfgPoint(mu, 0.0, kCorr, true, method(IntegratorKind::Adaptive));
    EXPECT_EQ(z.E, 1.0);
    EXPECT_NEAR(z.B, std::pow(1.0 - mu, 5.0), 1e-15);
    // E -> 1 as alpha -> 0, approaching the alpha = 0 value continuously
    const DfgValue s = dfgPoint(mu, 1e-4, kCorr, true, method(IntegratorKind::Adaptive, 1e-7));
    if (mu >= 0.1) {
      EXPECT_NEAR(s.E, 1.0, 1e-4) << mu;
      EXPECT_NEAR(s.A, z.A, 1e-4) << mu;
    }
    EXPECT_TRUE(std::isfinite(s.E));
  }
}

TEST(Dfg, HardCasesAreFiniteAndBounded) {
  for (double mu : {0.0, 1e-9, 1e-4, 1.0 / 64, 0.5, 1.0})
    for (double alpha : {0.0, 1e-6, 1.0 / 4096, 0.01, 0.5, 1.0})
      for (auto vis : {Visibility::SmithCorrelated, Visibility::SchlickSmith}) {
        const DfgValue v = dfgPoint(mu, alpha, vis, true, method(IntegratorKind::Adaptive, 1e-6));
        ASSERT_TRUE(std::isfinite(v.A) && std::isfinite(v.B) && std::isfinite(v.err_E))
            << mu << " " << alpha;
        EXPECT_GE(v.A, -1e-6);
        EXPECT_GE(v.B, -1e-6);
        EXPECT_LE(v.A, 1.0 + 1e-6);
        EXPECT_LE(v.B, 1.0 + 1e-6);
        EXPECT_LE(v.E, 1.0 + 1e-6);
      }
  // mu = 0 is the continuous limit of mu -> 0
  const DfgValue z = dfgPoint(0.0, 0.5, kCorr, true, method(IntegratorKind::Adaptive, 1e-8));
  const DfgValue e = dfgPoint(1e-6, 0.5, kCorr, true, method(IntegratorKind::Adaptive, 1e-8));
  EXPECT_NEAR(z.E, e.E, 1e-4);
}

TEST(Dfg, CorrelatedVersusSeparable) {
  // At mu = 1, G1(v) = 1 in both forms, so G2 = G1(l) in both and they differ only by
  // Schlick's k = alpha/2 fit of the Smith G1(l): within 5 %.
  std::vector<double> gap_at_1;
  for (double alpha : {0.25, 0.5, 1.0}) {
    const auto o = method(IntegratorKind::Adaptive);
    const double c = dfgPoint(1.0, alpha, Visibility::SmithCorrelated, false, o).E;
    const double s = dfgPoint(1.0, alpha, Visibility::SchlickSmith, false, o).E;
    EXPECT_NEAR(c, s, 0.05 * c) << alpha;
    gap_at_1.push_back(std::abs(c - s));
  }
  // Elsewhere the separable product over-counts shadowing ((1+a)(1+b) >= 1+a+b): it is lower,
  // and the gap grows toward grazing.
  const double alphas[] = {0.25, 0.5, 1.0};
  for (int ia = 0; ia < 3; ++ia) {
    const double alpha = alphas[ia];
    double prev_gap = 0;
    for (double mu : {0.9, 0.5, 0.2, 0.05}) {
      const auto o = method(IntegratorKind::Adaptive);
      const double c = dfgPoint(mu, alpha, Visibility::SmithCorrelated, false, o).E;
      const double s = dfgPoint(mu, alpha, Visibility::SchlickSmith, false, o).E;
      EXPECT_LT(s, c) << mu << " " << alpha;
      EXPECT_GT(c - s, prev_gap - 1e-9) << mu << " " << alpha;
      prev_gap = c - s;
    }
    EXPECT_GT(prev_gap, 0.05 * alpha);
    EXPECT_GT(prev_gap, 3.0 * gap_at_1[ia]);  // grazing gap >> the mu = 1 gap
  }
}

TEST(Dfg, FresnelOffEvaluatesNoFresnel) {
  Counters c;
  dfgPoint(0.5, 0.5, kCorr, false, method(IntegratorKind::Adaptive), &c);
  EXPECT_GT(c.specular, 0u);
  EXPECT_EQ(c.fresnel, 0u);
  dfgPoint(0.5, 0.5, kCorr, true, method(IntegratorKind::Adaptive), &c);
  EXPECT_GT(c.fresnel, 0u);
}
