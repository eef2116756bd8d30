// sheen: the Charlie directional albedo against its two closed forms (mu = 1 and mu = 0, every
// alpha), its limit alpha -> 0, the other integrators, and an independent quadrature over the
// half vector (reference.hpp) at interior points.
#include "lgp/datasets/sheen.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "integrator_options.hpp"
#include "reference.hpp"

using namespace lgp::datasets;

namespace {
IntegratorOptions method(IntegratorKind k, double tol = 5e-8) {
  return test::method(k, tol);
}
// E(1, alpha) = 2^(-1/(2 alpha)) / (4 + 1/alpha): only h with n.h > 1/sqrt(2) reflect into
// n.l > 0, and the integral in s = sin^2(theta_h) is elementary.
double atNormal(double a) {
  return std::pow(2.0, -0.5 / a) / (4.0 + 1.0 / a);
}
// E(0, alpha) = (2 + 1/alpha) W(1/alpha + 2) / pi, W(n) = int_0^{pi/2} sin^n: at grazing view
// the visibility cancels n.l and E = int_{v.h > 0} D (v.h) dh.
double atGrazing(double a) {
  const double n = 1.0 / a + 2.0;
  const double w = 0.5 * std::sqrt(std::numbers::pi) *
                   std::exp(std::lgamma(0.5 * (n + 1.0)) - std::lgamma(0.5 * n + 1.0));
  return (2.0 + 1.0 / a) * w / std::numbers::pi;
}
}  // namespace

TEST(Sheen, ClosedFormsAtNormalAndGrazingView) {
  for (double a : {0.005, 0.02, 0.1, 0.3, 0.7, 1.0}) {
    const SheenValue n = sheenPoint(1.0, a, method(IntegratorKind::Adaptive));
    const SheenValue g = sheenPoint(0.0, a, method(IntegratorKind::Adaptive));
    EXPECT_NEAR(n.E, atNormal(a), n.error + 1e-12) << a;
    EXPECT_NEAR(g.E, atGrazing(a), g.error + 1e-12) << a;
    EXPECT_LT(n.error, 5e-8);
    EXPECT_LT(g.error, 5e-8);
    EXPECT_TRUE(n.converged && g.converged);
  }
  EXPECT_NEAR(atNormal(1.0), 1.0 / (5.0 * std::sqrt(2.0)), 1e-15);
  EXPECT_NEAR(atGrazing(1.0), 2.0 / std::numbers::pi, 1e-15);  // (3/pi) W(3) = (3/pi)(2/3)
  // Not a masking function: above 1 at grazing view for a sharp sheen, growing like
  // alpha^(-1/2).
  EXPECT_GT(atGrazing(0.005), 5.0);
}

TEST(Sheen, SharpLimitAndMonotonicity) {
  EXPECT_EQ(sheenPoint(0.5, 0.0, method(IntegratorKind::Adaptive)).E, 0.0);
  EXPECT_TRUE(std::isinf(sheenPoint(0.0, 0.0, method(IntegratorKind::Adaptive)).E));
  // alpha -> 0 at mu > 0: the microfacets lie down and nothing is reflected above the horizon
  // (at mu = 0.5 the largest D reachable is ~(1 - 0.067)^(1/(2 alpha)))
  const SheenValue tiny = sheenPoint(0.5, 0.002, method(IntegratorKind::Adaptive));
  const SheenValue small = sheenPoint(0.5, 0.005, method(IntegratorKind::Adaptive));
  EXPECT_LT(tiny.E, 1e-8);
  EXPECT_LT(tiny.E, 1e-3 * small.E);
  EXPECT_LT(small.E, 1e-4);
  EXPECT_GE(tiny.E, 0.0);
  double prev = 0;
  for (double a : {0.02, 0.1, 0.3, 1.0}) {  // at mu = 0.5 rougher sheen reflects more
    const double e = sheenPoint(0.5, a, method(IntegratorKind::Adaptive)).E;
    EXPECT_GT(e, prev) << a;
    prev = e;
  }
}

TEST(Sheen, IntegratorsAgree) {
  for (double mu : {0.05, 0.3, 0.7})
    for (double a : {0.05, 0.3, 1.0}) {
      const SheenValue ad = sheenPoint(mu, a, method(IntegratorKind::Adaptive, 1e-9));
      const SheenValue ga = sheenPoint(mu, a, method(IntegratorKind::Gauss));
      const SheenValue qm = sheenPoint(mu, a, method(IntegratorKind::Qmc));
      EXPECT_NEAR(ga.E, ad.E, ga.error + 1e-8) << mu << " " << a;
      EXPECT_NEAR(qm.E, ad.E, qm.error + 1e-8) << mu << " " << a;
      EXPECT_LT(qm.error, 1e-3);
    }
}

// Another variable (the half vector, with the n.l > 0 partition of dfg) and another rule
// (Gauss-Kronrod in long double): the generator's distance to it within its own estimate.
TEST(Sheen, AgainstTheHalfVectorReference) {
  for (double mu : {0.02, 0.2, 0.5, 0.9})
    for (double a : {0.01, 0.1, 0.5, 1.0}) {
      const auto r15 = ref::sheen(mu, a, 1e-12L, ref::gk15());
      const auto r21 = ref::sheen(mu, a, 1e-12L, ref::gk21());
      ASSERT_TRUE(r15.converged && r21.converged) << mu << " " << a;
      ASSERT_NEAR(static_cast<double>(r15.value[0]), static_cast<double>(r21.value[0]), 1e-10);
      const SheenValue s = sheenPoint(mu, a, method(IntegratorKind::Adaptive, 5e-7));
      EXPECT_NEAR(s.E, static_cast<double>(r21.value[0]), s.error) << mu << " " << a;
      EXPECT_LE(s.error, 5e-7);
    }
}

// Hardening round 4, F7: at mu = 0 a sharp lobe (sqrt(alpha) wide) fell between the quadrature
// nodes: E = 0 with estimate 0 and "converged", where the true value grows as
// 1 / sqrt(2 pi alpha); at alpha = 1e-20 sin^2(theta_h) rounded to 1 and E came out 67x too
// large. mu = 0 is the closed form now, and next to it the quadrature is either accurate within
// its own estimate or says it did not converge.
TEST(Sheen, GrazingViewHoldsForTinyAlpha) {
  for (double a : {5e-324, 1e-300, 1e-40, 1e-20, 1e-9, 1e-4, 0.005, 0.3, 1.0}) {
    const SheenValue g = sheenPoint(0.0, a, method(IntegratorKind::Adaptive));
    ASSERT_TRUE(std::isfinite(g.E)) << a;
    if (a >= 0.005) {
      EXPECT_NEAR(g.E, atGrazing(a), 1e-12 * atGrazing(a)) << a;
    }
    if (a <= 1e-9 && a >= 1e-300) {  // (a subnormal alpha is too coarse for the check)
      EXPECT_NEAR(g.E * std::sqrt(2.0 * std::numbers::pi * a), 1.0, 1e-3) << a;
    }
    EXPECT_GT(g.E, 0.0) << a;
  }
  // Next to mu = 0 a sharp lobe scales: sqrt(alpha) E(f sqrt(alpha), alpha) is one function of
  // f. At f = 1e-3 it is within 1 % of the closed form at f = 0, and at f = 0.1 and 1 it agrees
  // across twenty decades of alpha (before, E at alpha = 1e-20 came out 67x too large). Where
  // the absolute target is out of reach (E ~ 1e9) the integral says it did not converge.
  for (double f : {1e-3, 0.1, 1.0}) {
    double scaled_ref = 0;
    for (double a : {1e-6, 1e-12, 1e-20}) {
      const SheenValue s = sheenPoint(f * std::sqrt(a), a, method(IntegratorKind::Adaptive));
      const double scaled = s.E * std::sqrt(a);
      if (f == 1e-3) {
        EXPECT_NEAR(s.E, sheenAtGrazing(a), 0.01 * sheenAtGrazing(a)) << a;
      }
      if (a == 1e-6) scaled_ref = scaled;
      EXPECT_NEAR(scaled, scaled_ref, 1e-3 * scaled_ref) << f << " " << a;
      // "converged" exactly when the estimate meets the target
      EXPECT_EQ(s.converged, s.error <= 5e-8) << f << " " << a << " " << s.error;
    }
  }
}

// Hardening round 4, F14: for 1 <= 1/alpha < 2 the lobe has a kink at the mirror direction and
// six entries of the 32 x 32 sheen tables carried a true error above their own estimate (at mu
// 0.953, alpha 0.797: 9.4e-7 off, 3.9e-7 claimed). With a breakpoint there every estimate
// bounds the distance to the reference.
TEST(Sheen, EstimatesBoundTheErrorAtTheMirrorKink) {
  for (double mu : {0.953, 0.8, 0.6, 0.3})
    for (double a : {0.51, 0.65, 0.797, 0.9, 0.99}) {
      const auto ref = ref::sheen(mu, a, 1e-13L, ref::gk21());
      ASSERT_TRUE(ref.converged) << mu << " " << a;
      const SheenValue s = sheenPoint(mu, a, method(IntegratorKind::Adaptive, 5e-7));
      EXPECT_LE(std::abs(s.E - static_cast<double>(ref.value[0])), s.error) << mu << " " << a;
      EXPECT_LE(s.error, 5e-7);
    }
}
