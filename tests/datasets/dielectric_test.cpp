// dielectric: the exact Fresnel's closed values, F_avg's reciprocity, and the reflection and
// transmission albedo of rough GGX against their limits (alpha = 0, eta = 1), the QMC
// integrator and an independent half-vector quadrature (reference.hpp).
#include "lgp/datasets/dielectric.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "integrator_options.hpp"
#include "reference.hpp"

using namespace lgp::datasets;

namespace {
IntegratorOptions method(IntegratorKind k, double tol = 5e-8) {
  return test::method(k, tol);
}
constexpr auto kCorr = Visibility::SmithCorrelated;
double lambdaOf(double mu, double a) {
  return 0.5 * (std::sqrt(a * a + (1.0 - a * a) * mu * mu) / mu - 1.0);
}
}  // namespace

TEST(Dielectric, FresnelClosedValues) {
  for (double eta : {1.2, 1.5, 2.4}) {
    const double f0 = std::pow((eta - 1.0) / (eta + 1.0), 2);
    EXPECT_NEAR(fresnelDielectric(1.0, eta), f0, 1e-15) << eta;
    EXPECT_EQ(fresnelDielectric(0.0, eta), 1.0);
    // Brewster: r_p = 0 where tan(theta) = eta, so F = r_s^2 / 2 = ((eta^2 - 1)/(eta^2 + 1))^2 / 2
    const double cb = 1.0 / std::sqrt(1.0 + eta * eta);
    EXPECT_NEAR(fresnelDielectric(cb, eta), 0.5 * std::pow((eta * eta - 1) / (eta * eta + 1), 2),
                1e-15);
  }
  EXPECT_NEAR(fresnelDielectric(0.3, 1.0), 0.0, 1e-30);
  // Hardening round 4, F8: eta = 1 is no interface, F = 0 down to grazing; 1 - (1 - mu^2) / 1
  // cancelled to 0 below mu ~ 1e-8 and read as total internal reflection (F = 1).
  for (double mu : {0.0, 1e-300, 1e-12, 1e-9, 5e-9, 1e-8, 1e-4})
    EXPECT_EQ(fresnelDielectric(mu, 1.0), 0.0) << mu;
  // Next to eta = 1 total internal reflection starts at mu = sqrt(1 - eta^2) (4.5e-8 for
  // eta = 1 - 1e-15).
  EXPECT_LT(fresnelDielectric(5e-8, 1.0 - 1e-15), 1.0);
  EXPECT_EQ(fresnelDielectric(4e-8, 1.0 - 1e-15), 1.0);
  // eta < 1: total internal reflection below the critical cosine sqrt(1 - eta^2)
  EXPECT_EQ(fresnelDielectric(0.5, 0.8), 1.0);
  EXPECT_LT(fresnelDielectric(0.7, 0.8), 1.0);
}

TEST(Dielectric, FresnelAverage) {
  const auto o = method(IntegratorKind::Adaptive, 1e-12);
  EXPECT_EQ(fresnelAverageDielectric(1.0, o).value, 0.0);
  for (double eta : {1.001, 1.05, 1.33, 1.5, 2.0, 3.0}) {
    const FavgValue f = fresnelAverageDielectric(eta, o);
    const FavgValue b = fresnelAverageDielectric(1.0 / eta, o);
    // Reciprocity (Kulla and Conty 2017): what enters from outside leaves from inside, with
    // the eta^2 of radiance: 1 - F_avg(eta) = eta^2 (1 - F_avg(1/eta)).
    EXPECT_NEAR(1.0 - f.value, eta * eta * (1.0 - b.value), 1e-12) << eta;
    // an independent quadrature in theta, long double
    const auto r = ref::fresnelAverage(eta, 1e-15L, ref::gk21());
    ASSERT_TRUE(r.converged);
    EXPECT_NEAR(f.value, static_cast<double>(r.value[0]), f.error + 1e-14) << eta;
    EXPECT_LE(f.error, 1e-12);
    EXPECT_TRUE(f.converged && b.converged);
  }
  // F_avg grows with the contrast; 1.5 is the familiar 0.0918 of glass
  EXPECT_NEAR(fresnelAverageDielectric(1.5, o).value, 0.0917780, 1e-7);
}

TEST(Dielectric, SmoothLimit) {
  for (double mu : {0.0, 0.3, 1.0})
    for (double eta : {1.0, 1.5, 3.0}) {
      const double F = fresnelDielectric(mu, eta);
      const auto a = method(IntegratorKind::Adaptive);
      const DielectricValue d =
          dielectricPoint(mu, 0.0, eta, kCorr, Transmission::Flux, true, true, a);
      EXPECT_EQ(d.refl, F);
      EXPECT_EQ(d.trans, 1.0 - F);
      const DielectricValue r =
          dielectricPoint(mu, 0.0, eta, kCorr, Transmission::Radiance, true, true, a);
      EXPECT_DOUBLE_EQ(r.trans, (1.0 - F) / (eta * eta));
      // and alpha -> 0 approaches it (away from grazing view)
      if (mu >= 0.3) {
        const DielectricValue s =
            dielectricPoint(mu, 1e-3, eta, kCorr, Transmission::Flux, true, true, a);
        EXPECT_NEAR(s.refl, F, 1e-4) << mu << " " << eta;
        EXPECT_NEAR(s.trans, 1.0 - F, 1e-4) << mu << " " << eta;
      }
    }
}

TEST(Dielectric, IndexOneIsTheModelsOwnLoss) {
  const auto o = method(IntegratorKind::Adaptive);
  for (double a : {0.1, 0.5, 1.0})
    for (double mu : {0.2, 0.5, 0.9}) {
      const double L = lambdaOf(mu, a);
      const DielectricValue c =
          dielectricPoint(mu, a, 1.0, kCorr, Transmission::Flux, true, true, o);
      EXPECT_EQ(c.refl, 0.0);  // F = 0
      EXPECT_NEAR(c.trans, (1.0 + L) / (1.0 + 2.0 * L), 1e-14);
      const DielectricValue s = dielectricPoint(mu, a, 1.0, Visibility::SmithSeparable,
                                                Transmission::Flux, true, true, o);
      EXPECT_NEAR(s.trans, 1.0 / (1.0 + L), 1e-14);
      // continuity: the integral just above eta = 1 tends to the closed form
      const DielectricValue n =
          dielectricPoint(mu, a, 1.0 + 1e-5, kCorr, Transmission::Flux, true, true, o);
      EXPECT_NEAR(n.refl + n.trans, c.trans, 2e-4) << a << " " << mu;
      EXPECT_LT(n.refl, 1e-4);
    }
}

TEST(Dielectric, EnergyBoundAndConventions) {
  const auto o = method(IntegratorKind::Adaptive);
  for (double mu : {0.0, 0.05, 0.4, 1.0})
    for (double a : {0.05, 0.4, 1.0})
      for (double eta : {1.1, 1.5, 2.5}) {
        const DielectricValue f =
            dielectricPoint(mu, a, eta, kCorr, Transmission::Flux, true, true, o);
        const DielectricValue r =
            dielectricPoint(mu, a, eta, kCorr, Transmission::Radiance, false, true, o);
        EXPECT_LE(f.refl + f.trans, 1.0 + 1e-7) << mu << " " << a << " " << eta;
        EXPECT_GE(f.refl, 0.0);
        EXPECT_NEAR(r.trans, f.trans / (eta * eta), f.err_trans + r.err_trans);
        EXPECT_EQ(r.refl, 0.0);  // not asked for
        EXPECT_TRUE(f.converged && r.converged);
      }
}

TEST(Dielectric, QmcAgrees) {
  for (double mu : {0.1, 0.5, 0.9})
    for (double a : {0.1, 0.5, 1.0}) {
      const DielectricValue d = dielectricPoint(mu, a, 1.5, kCorr, Transmission::Flux, true, true,
                                                method(IntegratorKind::Adaptive, 1e-9));
      const DielectricValue q = dielectricPoint(mu, a, 1.5, kCorr, Transmission::Flux, true, true,
                                                method(IntegratorKind::Qmc));
      EXPECT_NEAR(q.refl, d.refl, q.err_refl + 1e-8) << mu << " " << a;
      EXPECT_NEAR(q.trans, d.trans, q.err_trans + 1e-8) << mu << " " << a;
    }
}

TEST(Dielectric, AgainstTheHalfVectorReference) {
  for (auto vis : {Visibility::SmithCorrelated, Visibility::SmithSeparable})
    for (double mu : {0.02, 0.5, 1.0})
      for (double a : {0.02, 1.0})
        for (double eta : {1.02, 3.0}) {
          const ref::Vis rv =
              vis == Visibility::SmithCorrelated ? ref::Vis::Correlated : ref::Vis::Separable;
          const auto r = ref::dielectric(mu, a, eta, rv, 1e-10L, ref::gk21());
          ASSERT_TRUE(r.converged) << mu << " " << a << " " << eta;
          const DielectricValue d = dielectricPoint(mu, a, eta, vis, Transmission::Flux, true, true,
                                                    method(IntegratorKind::Adaptive, 5e-7));
          EXPECT_NEAR(d.refl, static_cast<double>(r.refl), d.err_refl)
              << mu << " " << a << " " << eta;
          EXPECT_NEAR(d.trans, static_cast<double>(r.trans), d.err_trans)
              << mu << " " << a << " " << eta;
          EXPECT_LE(d.err_refl + d.err_trans, 5e-7);
        }
}
