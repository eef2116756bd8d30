// sheen: directional albedo of the Charlie sheen BRDF (Estevez and Kulla 2017, "Production
// Friendly Microfacet Sheen BRDF") with the smoother visibility of Neubelt and Pettineo 2013
// ("Crafting a Next-Gen Material Pipeline for The Order: 1886"), F = G = 1, as MaterialX
// (mx_imageworks_sheen_brdf) and Filament's cloth model use it:
//
//   D(h)     = (2 + 1/alpha) sin(theta_h)^(1/alpha) / (2 pi)
//   f(l, v)  = D(h) / (4 (n.l + n.v - (n.l)(n.v)))
//   E(mu, r) = integral_H f(l, v) (n.l) dl
//
// It is also the split-sum DFG term of a cloth environment lookup (the sheen colour multiplies
// outside the integral; Filament's DFG LUT holds it with alpha = r^2, MaterialX's albedo with
// alpha = r). The visibility is not a masking function: E can exceed 1 at grazing view, and
// E(0, alpha) = (2 + 1/alpha) W(1/alpha + 2) / pi with W(n) = integral_0^{pi/2} sin^n grows
// like alpha^(-1/2). Closed forms used as checks: E(1, alpha) = 2^(-1/(2 alpha)) / (4 + 1/alpha)
// and that E(0, alpha), which sheenPoint returns at mu = 0. alpha = 0 is the limit E = 0
// (mu > 0).
//
// Computation: over the light direction l = (theta_l, phi_l), theta_l in [0, pi/2] and
// phi_l in [0, pi] (mirror symmetry doubles it), where the integrand is smooth; for a sharp
// lobe it is concentrated at the horizon next to the view's azimuth (where h is closest to
// the horizon), so the starting partition has geometric breakpoints at min(alpha, mu) 2^k
// from theta_l = pi/2 and from phi_l = 0 and pi. Adaptive (or Gauss) product rules; QMC
// samples l cosine-weighted over the whole hemisphere instead.
#pragma once

#include "lgp/datasets/integrator.hpp"

namespace lgp::datasets {

struct SheenValue {
  double E = 0, error = 0;
  uint64_t evals = 0;
  bool converged = true;
};

// The Charlie distribution D(h) from cos^2(theta_h): sin^(1/alpha) as exp(log1p(-cos^2) /
// (2 alpha)), exact for a sharp lobe, where sin^2 = 1 - cos^2 rounds to 1 long before
// sin^(1/alpha) is 1.
double charlieDFromCos2(double cos2h, double alpha);
// E(0, alpha) = (2 + 1/alpha) W(1/alpha + 2) / pi, every alpha > 0 (grows like
// 1 / sqrt(2 pi alpha)): what sheenPoint returns at mu = 0.
double sheenAtGrazing(double alpha);

SheenValue sheenPoint(double mu, double alpha, const IntegratorOptions& opt,
                      Counters* counters = nullptr);

}  // namespace lgp::datasets
