// Burley and Oren-Nayar directional albedo: the generators' closed forms against independent
// integrals (the exact polynomial moments of reference.hpp, the zh generator, and a 2-D
// adaptive quadrature of the BRDF written out here) and their limits.
#include "lgp/datasets/diffuse_albedo.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <utility>
#include <vector>

#include "lgp/datasets/quadrature.hpp"
#include "lgp/datasets/zh.hpp"
#include "reference.hpp"

using namespace lgp::datasets;

namespace {
constexpr double kPi = std::numbers::pi;

// The Oren-Nayar BRDF as MaterialX writes it (mx_oren_nayar_diffuse), integrated over l in
// (theta_l, phi) with the kinks (phi = pi/2 where s changes sign, theta_l = theta_v where the
// max switches) on the partition.
double orenNayarQuadrature(double mu, double r) {
  const double s2 = r * r;
  const double A = 1.0 - 0.5 * s2 / (s2 + 0.33), B = 0.45 * s2 / (s2 + 0.09);
  const double sv = std::sqrt(1.0 - mu * mu);
  auto f = [&](const std::array<double, 2>& p, std::array<double, 1>& o) {
    const double st = std::sin(p[0]), nl = std::cos(p[0]);
    const double lv = st * sv * std::cos(p[1]) + nl * mu;
    const double s = lv - nl * mu;
    const double stinv = s > 0.0 ? s / std::max(nl, mu) : 0.0;
    o[0] = 2.0 * (A + B * stinv) / kPi * nl * st;  // x2: phi in [0, pi]
  };
  std::vector<double> th = {0.0, 0.5 * kPi};
  if (mu > 0.0 && mu < 1.0) th.push_back(std::acos(mu));
  std::sort(th.begin(), th.end());
  std::vector<Box<2>> boxes;
  for (size_t i = 0; i + 1 < th.size(); ++i)
    for (auto [a, b] : {std::pair{0.0, 0.5 * kPi}, std::pair{0.5 * kPi, kPi}})
      boxes.push_back({{th[i], a}, {th[i + 1], b}});
  AdaptiveOptions ao;
  ao.abs_tol = 1e-12;
  ao.max_evals = 20000000;
  return adaptive<2, 1>(f, std::span<const Box<2>>(boxes), ao).value[0];
}
}  // namespace

TEST(DiffuseAlbedo, BurleyIsTheExactZerothMoment) {
  for (double mu : {0.0, 1e-6, 0.1, 0.5, 0.9, 1.0})
    for (double r : {0.0, 0.25, 0.5, 1.0}) {
      const double exact = static_cast<double>(ref::zhMoments(std::acos(mu), r, false)[0]);
      const AlbedoValue b = burleyAlbedo(mu, r);
      EXPECT_NEAR(b.E, exact, 1e-14) << mu << " " << r;
      EXPECT_LE(std::abs(b.E - exact), b.error + 1e-15);
      // and the zh generator's own (adaptive) M0 = ZH0 / Y00
      IntegratorOptions o;
      o.abs_tol = 1e-9;
      EXPECT_NEAR(zhPoint(mu, r, Diffuse::Disney, o).zh0 / 0.28209479177387814, b.E, 1e-8);
    }
}

TEST(DiffuseAlbedo, BurleyLimits) {
  // r = 0: F_D90 = 1/2 everywhere; 2 int x (1 - x)^5 dx = 1/21 gives 41/42 - (41/84)(1 - mu)^5,
  // the value Hill's fit has at r = 0.
  for (double mu : {0.0, 0.3, 1.0})
    EXPECT_NEAR(burleyAlbedo(mu, 0.0).E, 41.0 / 42.0 - 41.0 / 84.0 * std::pow(1.0 - mu, 5), 1e-15);
  // at normal view the retro-reflection of rough surfaces raises the albedo above Lambert's
  EXPECT_GT(burleyAlbedo(1.0, 1.0).E, 1.0);
  EXPECT_LT(burleyAlbedo(0.0, 0.0).E, 0.5);
}

TEST(DiffuseAlbedo, OrenNayarAgainstQuadrature) {
  for (double mu : {0.05, 0.3, 0.5, 0.8, 0.99})
    for (double r : {0.1, 0.5, 1.0}) {
      const double q = orenNayarQuadrature(mu, r);
      const AlbedoValue on = orenNayarAlbedo(mu, r);
      EXPECT_NEAR(on.E, q, 1e-10) << mu << " " << r;
    }
}

TEST(DiffuseAlbedo, OrenNayarLimits) {
  for (double r : {0.0, 0.3, 1.0}) {
    const double s2 = r * r;
    const double A = 1.0 - 0.5 * s2 / (s2 + 0.33), B = 0.45 * s2 / (s2 + 0.09);
    EXPECT_NEAR(orenNayarAlbedo(1.0, r).E, A, 1e-15) << r;            // no retro-reflection term
    EXPECT_NEAR(orenNayarAlbedo(0.0, r).E, A + 0.5 * B, 1e-15) << r;  // its largest
    EXPECT_NEAR(orenNayarAlbedo(1e-9, r).E, A + 0.5 * B, 1e-8) << r;  // continuous there
  }
  EXPECT_EQ(orenNayarAlbedo(0.4, 0.0).E, 1.0);  // sigma = 0 is Lambert
}
