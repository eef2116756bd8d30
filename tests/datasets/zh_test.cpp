#include "lgp/datasets/zh.hpp"

#include <gtest/gtest.h>

#include <cmath>

using namespace lgp::datasets;

namespace {
IntegratorOptions method(IntegratorKind k) {
  IntegratorOptions o;
  o.kind = k;
  o.abs_tol = 1e-8;
  o.qmc_points = 1 << 15;
  return o;
}
}  // namespace

TEST(Zh, LambertCheckValues) {
  for (double mu : {0.0, 0.3, 1.0}) {
    const ZhValue z = zhPoint(mu, 0.7, Diffuse::Lambert, method(IntegratorKind::Adaptive));
    EXPECT_NEAR(z.zh0, 0.2820948, 1e-7);
    EXPECT_NEAR(z.zh1, 0.3257350, 1e-7);
    EXPECT_NEAR(z.zh2, 0.1576958, 1e-7);
    EXPECT_NEAR(z.ratio1, 1.1547005, 1e-6);
    EXPECT_NEAR(z.ratio2, 0.5590170, 1e-6);
    EXPECT_NEAR(z.beta, 0.0, 1e-9);
  }
}

TEST(Zh, DisneyIndependentIntegratorsAgree) {
  for (double mu : {0.0, 0.2, 0.6, 1.0})
    for (double r : {0.0, 0.5, 1.0}) {
      const ZhValue a = zhPoint(mu, r, Diffuse::Disney, method(IntegratorKind::Adaptive));
      const ZhValue g = zhPoint(mu, r, Diffuse::Disney, method(IntegratorKind::Gauss));
      const ZhValue q = zhPoint(mu, r, Diffuse::Disney, method(IntegratorKind::Qmc));
      EXPECT_NEAR(a.zh0, g.zh0, 1e-7);
      EXPECT_NEAR(a.zh2, g.zh2, 1e-7);
      EXPECT_NEAR(a.beta, g.beta, 1e-6);
      EXPECT_NEAR(q.zh0, g.zh0, q.err_zh0 + 1e-9) << mu << " " << r;
      EXPECT_NEAR(q.zh1, g.zh1, q.err_zh1 + 1e-9) << mu << " " << r;
      EXPECT_NEAR(q.zh2, g.zh2, q.err_zh2 + 1e-9) << mu << " " << r;
      EXPECT_LT(q.err_zh2, 1e-3);
      for (double v : {a.zh0, a.zh1, a.zh2, a.ratio1, a.ratio2, a.beta})
        EXPECT_TRUE(std::isfinite(v));
    }
}

TEST(Zh, SeedShape) {
  // Iwanicki & Pesce 2015 (Disney diffuse in ZH): the ratios are close to their constant fits
  // 1.1564 and 0.5634, and beta is small except at grazing, rough.
  const auto o = method(IntegratorKind::Adaptive);
  for (double mu : {0.1, 0.5, 0.9})
    for (double r : {0.0, 0.5, 1.0}) {
      const ZhValue z = zhPoint(mu, r, Diffuse::Disney, o);
      EXPECT_NEAR(z.ratio1, 1.1564, 0.04);
      EXPECT_NEAR(z.ratio2, 0.5634, 0.06);
    }
  EXPECT_GT(zhPoint(0.0, 1.0, Diffuse::Disney, o).beta, 0.15);
  EXPECT_NEAR(zhPoint(0.5, 0.0, Diffuse::Disney, o).beta, 0.0, 1e-6);
  // beta at mu = 1 is the limit of mu -> 1
  const double b1 = zhPoint(1.0, 1.0, Diffuse::Disney, o).beta;
  const double b0 = zhPoint(std::cos(1e-3), 1.0, Diffuse::Disney, o).beta;
  EXPECT_NEAR(b1, b0, 1e-4);
}
