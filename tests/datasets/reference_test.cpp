// The generators' error estimates against independent references (reference.hpp) at named hard
// points: low roughness (the sharp GGX lobe), grazing view (mu -> 0), small lights
// (theta_s -> 0) and mu -> 1 for zh. At each point the reference is first shown converged
// (two Gauss-Kronrod rules, each to its own tolerance, agree to far below the tolerance under
// test), then the generator's distance to it must be within its own estimate, and the estimate
// within the tolerance asked for (so it is not absurdly loose either).
#include "reference.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "lgp/datasets/dfg.hpp"
#include "lgp/datasets/energy.hpp"
#include "lgp/datasets/normalization.hpp"
#include "lgp/datasets/quadrature.hpp"
#include "lgp/datasets/zh.hpp"

using namespace lgp::datasets;

namespace {
constexpr auto kCorr = Visibility::SmithCorrelated;

// What `lgp data` asks of one integral for a 1e-6 table: half the entry tolerance.
IntegratorOptions tableOptions(IntegratorKind k = IntegratorKind::Adaptive, double tol = 5e-7) {
  IntegratorOptions o;
  o.kind = k;
  o.abs_tol = tol;
  return o;
}

double d(ref::R x) {
  return static_cast<double>(x);
}
}  // namespace

TEST(Reference, GaussKronrodRulesAreExactToTheirDegree) {
  // G7-K15: K exact to degree 22, G to 13; G10-K21: K to 31, G to 19. On [0, 1]: 1/(d+1).
  struct Case {
    const ref::GkRule* g;
    int kdeg, gdeg;
  } cases[] = {{&ref::gk15(), 22, 13}, {&ref::gk21(), 31, 19}};
  for (const auto& c : cases)
    for (int deg = 0; deg <= c.kdeg; ++deg) {
      ref::Vec<1> kr{}, ga{};
      uint64_t evals = 0;
      auto f = [&](ref::R x, ref::Vec<1>& o) { o[0] = std::pow(x, deg); };
      ref::gkInterval<1>(f, 0, 1, *c.g, kr, ga, evals);
      const ref::R exact = ref::R(1) / (deg + 1);
      EXPECT_NEAR(d(kr[0]), d(exact), 1e-17) << "K, degree " << deg;
      if (deg <= c.gdeg) {
        EXPECT_NEAR(d(ga[0]), d(exact), 1e-17) << "G, degree " << deg;
      }
    }
  // adaptive, on a peak of width 1e-4 next to a kink: int_0^1 a / (pi ((x - 1/3)^2 + a^2))
  // + |x - 0.7| dx = (atan((2/3)/a) + atan((1/3)/a)) / pi + (0.7^2 + 0.3^2) / 2
  const ref::R a = 1e-4L;
  auto f = [&](ref::R x, ref::Vec<1>& o) {
    o[0] =
        a / (ref::kPi * ((x - 1 / ref::R(3)) * (x - 1 / ref::R(3)) + a * a)) + std::abs(x - 0.7L);
  };
  const ref::R exact =
      (std::atan((2 / ref::R(3)) / a) + std::atan((1 / ref::R(3)) / a)) / ref::kPi +
      (0.49L + 0.09L) / 2;
  for (const auto* g : {&ref::gk15(), &ref::gk21()}) {
    auto r = ref::adaptiveGk<1>(f, {0, 1}, 1e-15L, 0, *g);
    EXPECT_TRUE(r.converged);
    EXPECT_NEAR(d(r.value[0]), d(exact), 1e-15);
  }
}

TEST(Reference, ClosedFormsAndCheckValues) {
  // E(mu = 1, alpha = 1) = 1 - ln 2 in closed form; the tables' check values.
  const auto e = ref::dfg(1, 1, false, 1e-13L, ref::gk15());
  EXPECT_NEAR(d(e.E), 1.0 - std::log(2.0), 1e-13);
  EXPECT_NEAR(d(ref::dfg(0.5, 0.25, false, 1e-12L, ref::gk15()).E), 0.85726, 5e-6);
  EXPECT_NEAR(d(ref::dfg(0.2, 0.5, false, 1e-12L, ref::gk15()).E), 0.78993, 5e-6);
  // Lambert in zonal harmonics: Y00 int cos/pi = Y00, Y10 int cos^2/pi = Y10 2/3, and
  // Y20 (3 int cos^3/pi - 1) = Y20 / 2
  const auto z = ref::zh(0.3, 0.7, true);
  EXPECT_NEAR(d(z.zh0), 0.28209479177387814, 1e-16);
  EXPECT_NEAR(d(z.zh1), 0.3257350079352799, 1e-15);
  EXPECT_NEAR(d(z.zh2), 0.15769578262626, 1e-13);
  EXPECT_NEAR(d(z.beta), 0.0, 1e-18);
}

namespace {
struct DfgPoint {
  double r, mu;
};
// r = 0.02 and 0.0445 are where the estimate of the first generator failed (a 41 x 41 table on
// [0.02, 1]^2); 0.1 for a moderately sharp lobe; mu from grazing (down to 1e-4, where G2 / n.v
// has a boundary layer of width ~mu) to normal.
const DfgPoint kDfgHard[] = {
    {0.02, 0.02},    {0.02, 0.167}, {0.02, 0.5},   {0.02, 1.0}, {0.0445, 0.02},
    {0.0445, 0.167}, {0.0445, 0.5}, {0.0445, 1.0}, {0.1, 0.02}, {0.1, 0.167},
    {0.1, 0.5},      {0.1, 1.0},    {0.02, 1e-3},  {0.5, 1e-3}, {1.0, 1e-4},
};
}  // namespace

TEST(Reference, DfgEstimatesBoundTheTrueErrorAtHardPoints) {
  for (const auto p : kDfgHard) {
    const ref::R alpha = ref::R(p.r) * p.r;
    const auto r15 = ref::dfg(p.mu, alpha, false, 1e-12L, ref::gk15());
    const auto r21 = ref::dfg(p.mu, alpha, false, 1e-12L, ref::gk21());
    ASSERT_TRUE(r15.converged && r21.converged) << p.r << " " << p.mu;
    const double ref_err = d(std::max(std::abs(r15.A - r21.A), std::abs(r15.B - r21.B)));
    ASSERT_LT(ref_err, 1e-12) << "reference not converged at r=" << p.r << " mu=" << p.mu;
    const double slack = 1e-12;  // the reference's own uncertainty, bounded just above
    for (auto kind : {IntegratorKind::Adaptive, IntegratorKind::Gauss}) {
      const auto o = tableOptions(kind);
      const DfgValue g = dfgPoint(p.mu, d(alpha), kCorr, true, o);
      const double eA = std::abs(g.A - d(r15.A)), eB = std::abs(g.B - d(r15.B));
      const double eE = std::abs(g.E - d(r15.E));
      std::printf(
          "dfg %-8s r=%-6g mu=%-5g A=%.12f ref=%.12f |d|=%.1e est=%.1e  B |d|=%.1e est=%.1e\n",
          toString(kind), p.r, p.mu, g.A, d(r15.A), eA, g.err_A, eB, g.err_B);
      EXPECT_LE(eA, g.err_A + slack) << toString(kind) << " r=" << p.r << " mu=" << p.mu;
      EXPECT_LE(eB, g.err_B + slack) << toString(kind) << " r=" << p.r << " mu=" << p.mu;
      EXPECT_LE(eE, g.err_E + slack) << toString(kind) << " r=" << p.r << " mu=" << p.mu;
      if (kind == IntegratorKind::Adaptive) {
        EXPECT_TRUE(g.converged);
        EXPECT_LE(g.err_A, o.abs_tol);
        EXPECT_LE(g.err_B, o.abs_tol);
      } else {
        EXPECT_LE(g.err_A, 100 * o.abs_tol);  // fixed order 16/32: not tied to the tolerance
      }
    }
  }
  // the separable form too, at the worst point of the first generator
  const auto s = ref::dfg(0.167, 4e-4L, true, 1e-12L, ref::gk15());
  const DfgValue g = dfgPoint(0.167, 4e-4, Visibility::SchlickSmith, true, tableOptions());
  EXPECT_LE(std::abs(g.A - d(s.A)), g.err_A + 1e-12);
  EXPECT_LE(std::abs(g.B - d(s.B)), g.err_B + 1e-12);
}

TEST(Reference, DfgTightToleranceIsMet) {
  // at 1e-9 per integral the estimate must still cover the truth (no rounding floor hides it)
  for (const auto p : {DfgPoint{0.02, 0.167}, DfgPoint{0.0445, 0.5}, DfgPoint{0.3, 0.167}}) {
    const ref::R alpha = ref::R(p.r) * p.r;
    const auto r15 = ref::dfg(p.mu, alpha, false, 1e-13L, ref::gk15());
    const DfgValue g =
        dfgPoint(p.mu, d(alpha), kCorr, true, tableOptions(IntegratorKind::Adaptive, 1e-9));
    EXPECT_TRUE(g.converged);
    EXPECT_LE(std::abs(g.A - d(r15.A)), g.err_A + 1e-13) << p.r << " " << p.mu;
    EXPECT_LE(std::abs(g.B - d(r15.B)), g.err_B + 1e-13) << p.r << " " << p.mu;
    EXPECT_LE(g.err_A, 1e-9);
  }
}

TEST(Reference, ZhEstimatesBoundTheTrueErrorAtHardPoints) {
  // The reference is exact (polynomial moments); mu -> 1 is where beta's estimate is stretched.
  for (double mu : {0.0, 0.02, 0.167, 0.5, 0.99999, 1.0})
    for (double r : {0.0, 0.02, 0.5, 1.0}) {
      const ref::Zh z = ref::zh(mu, r, false);
      const IntegratorOptions o = tableOptions();
      const ZhValue g = zhPoint(mu, r, Diffuse::Disney, o);
      const double dz[6] = {std::abs(g.zh0 - d(z.zh0)),       std::abs(g.zh1 - d(z.zh1)),
                            std::abs(g.zh2 - d(z.zh2)),       std::abs(g.ratio1 - d(z.ratio1)),
                            std::abs(g.ratio2 - d(z.ratio2)), std::abs(g.beta - d(z.beta))};
      const double ez[6] = {g.err_zh0,    g.err_zh1,    g.err_zh2,
                            g.err_ratio1, g.err_ratio2, g.err_beta};
      const char* names[6] = {"ZH0", "ZH1", "ZH2", "ZH1/ZH0", "ZH2/ZH0", "beta"};
      for (int k = 0; k < 6; ++k) {
        EXPECT_LE(dz[k], ez[k] + 1e-15) << names[k] << " mu=" << mu << " r=" << r;
        EXPECT_LE(ez[k], 4 * o.abs_tol) << names[k] << " mu=" << mu << " r=" << r;
      }
    }
}

TEST(Reference, EavgEstimatesBoundTheTrueErrorAtLowRoughness) {
  // The reference integrates bidirectionally (over h, then v around h) and never forms E(mu).
  // Its two rules agree at r = 1 (where both are affordable), and at the hard points its own
  // K21 - G10 estimate is far below the generator's tolerance.
  const auto k15 = ref::eAvg(1, 1e-10L, ref::gk15());
  const auto k21 = ref::eAvg(1, 1e-10L, ref::gk21());
  ASSERT_TRUE(k15.converged && k21.converged);
  EXPECT_LT(std::abs(d(k15.value - k21.value)), 1e-13);
  IntegratorOptions o = tableOptions();
  for (double r : {0.02, 0.0445}) {
    const ref::R alpha = ref::R(r) * r;
    const auto e = ref::eAvg(alpha, 1e-9L, ref::gk21());
    ASSERT_TRUE(e.converged) << r;
    ASSERT_LT(d(e.error), 1e-9) << "reference not converged, r=" << r;
    const EavgValue g = eAvg(d(alpha), kCorr, o);
    const double diff = std::abs(g.value - d(e.value));
    std::printf("E_avg r=%-6g gen=%.12f ref=%.12f |d|=%.1e est=%.1e\n", r, g.value, d(e.value),
                diff, g.error);
    EXPECT_TRUE(g.converged);
    EXPECT_LE(diff, g.error + 1e-9) << "r=" << r;
    EXPECT_LE(g.error, o.abs_tol) << "r=" << r;
  }
}

TEST(Reference, NormalizationEstimatesBoundTheTrueErrorForSmallLights) {
  // theta_s -> 0 on a sharp lobe (r = 0.02: the light is smaller than the lobe at 1e-4 and
  // larger at 1e-3), and a moderate case. P_true over the light's polar angle with the dfg
  // reference for E; P_rep with the representative point as an angle in the plane.
  IntegratorOptions o = tableOptions(IntegratorKind::Adaptive, 5e-6);  // a 1e-5 table
  struct P {
    double r, ts;
  } pts[] = {{0.02, 1e-4}, {0.02, 1e-3}, {0.1, 0.5}};
  for (const auto p : pts) {
    const ref::R alpha = ref::R(p.r) * p.r;
    ref::R et = 0, e15 = 0, e21 = 0;
    bool ok = true;
    const ref::R pt = ref::pTrue(alpha, p.ts, 1e-10L, ref::gk15(), et, ok);
    const ref::R pr15 = ref::pRep(alpha, p.ts, -3, 1e-14L, ref::gk15(), e15, ok);
    const ref::R pr21 = ref::pRep(alpha, p.ts, -3, 1e-14L, ref::gk21(), e21, ok);
    ASSERT_TRUE(ok);
    ASSERT_LT(d(et / pt), 1e-10);  // K15 against its embedded G7: converged
    ASSERT_LT(d(std::abs(pr15 - pr21) / pr15), 1e-13);
    const double n_ref = d(pt / pr15);
    const NormalizationValue g = normalizationPoint(d(alpha), p.ts, kCorr, -3, o);
    const double diff = std::abs(g.N - n_ref);
    std::printf("N r=%-5g ts=%-6g gen=%.12g ref=%.12g |d|=%.1e est=%.1e\n", p.r, p.ts, g.N, n_ref,
                diff, g.error);
    EXPECT_TRUE(g.converged);
    EXPECT_LE(diff, g.error + 2e-10 * n_ref) << p.r << " " << p.ts;
    EXPECT_LE(g.error, o.abs_tol) << p.r << " " << p.ts;
  }
}
