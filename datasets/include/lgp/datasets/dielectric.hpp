// dielectric: a rough dielectric interface (GGX, Walter et al. 2007) with the exact
// unpolarised Fresnel reflectance, relative index eta = n_inside / n_outside, view outside.
//
//   F(mu, eta)   = (r_s^2 + r_p^2) / 2                               (brdf.hpp)
//   F_avg(eta)   = 2 integral_0^1 F(mu, eta) mu dmu                  (Kulla and Conty 2017)
//   E_refl       = integral_H D G2 F(v.h) / (4 (n.l)(n.v)) (n.l) dl
//   E_trans      = the transmitted part, through the microfacet normal h with the refracted
//                  direction l_t = -v / eta + ((v.h) / eta - cos_t) h (n.l_t < 0):
//                    flux:     integral D G2 (1 - F(v.h)) (v.h) / (n.v) dh   (smooth: 1 - F)
//                    radiance: the same over eta^2 (Walter's BTDF for an outside viewer with
//                              the outer index 1; smooth: (1 - F) / eta^2)
//   E_dielectric = E_refl + E_trans
//
// Both lobes are integrated over the half vector h in the GGX CDF variable (half_vector.hpp),
// the reflection over n.l > 0, the transmission over v.h > 0 (with eta >= 1 every such h
// refracts into n.l < 0); G2 is the scene's visibility with |n.l|. Limits: alpha = 0 gives
// E_refl = F(mu), E_trans = 1 - F(mu) (flux); eta = 1 gives F = 0, E_refl = 0 and
// E_trans = G2(v, -v) / G1(v) (correlated: (1 + Lambda(v)) / (1 + 2 Lambda(v)); separable:
// G1(v)), because every h then transmits straight on: the microfacet model's own loss. The
// generator uses that closed form at eta = 1 (where mu = 0 is a corner: the limits eta -> 1
// and mu -> 0 do not commute, since F(v.h -> 0) = 1 for every eta != 1).
// F_avg: adaptive in t with mu = mu_c + (1 - mu_c) t^2 (mu_c = sqrt(1 - eta^2) the critical
// cosine for eta < 1, else 0; F = 1 below it), which removes the square-root behaviour there,
// and geometric breakpoints where F turns over near eta = 1.
#pragma once

#include "lgp/datasets/brdf.hpp"
#include "lgp/datasets/integrator.hpp"

namespace lgp::datasets {

struct DielectricValue {
  double refl = 0, trans = 0;          // E_refl, E_trans
  double err_refl = 0, err_trans = 0;  // estimated absolute errors
  uint64_t evals = 0;
  bool converged = true;
};

// eta >= 1. want_refl / want_trans select the lobes that are integrated.
DielectricValue dielectricPoint(double mu, double alpha, double eta, Visibility vis,
                                Transmission tr, bool want_refl, bool want_trans,
                                const IntegratorOptions& opt, Counters* counters = nullptr);

struct FavgValue {
  double value = 0, error = 0;
  uint64_t evals = 0;
  bool converged = true;
};
FavgValue fresnelAverageDielectric(double eta, const IntegratorOptions& opt,
                                   Counters* counters = nullptr);

}  // namespace lgp::datasets
