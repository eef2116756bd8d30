// dfg: the split-sum environment BRDF (Karis 2013, "Real Shading in Unreal Engine 4").
//
// For a view cosine mu = n.v and GGX roughness alpha,
//   integral over the hemisphere of f_spec(l, v) (n.l) dl = F0 * A + F90 * B,
//   A = integral of D G2 (1 - Fc) / (4 (n.l)(n.v)) (n.l) dl,
//   B = integral of D G2 Fc / (4 (n.l)(n.v)) (n.l) dl,   Fc = (1 - v.h)^5,
// and E = A + B (the directional albedo with F = 1). A and B do not depend on F0 or F90.
//
// Computation. With l = 2 (v.h) h - v and dl = 4 (v.h) dh, and GGX importance sampling of h
// (pdf D (n.h); CDF u = tan^2(theta_h) / (alpha^2 + tan^2(theta_h)), phi = 2 pi u2):
//   E = (1/pi) integral over theta_h, phi in [0, pi] of W du dphi,
//   W = G2 (v.h) / ((n.v)(n.h)),   restricted to n.l > 0.
// n.l > 0 holds for every phi when theta_h < pi/4 - theta_v/2 and for |phi| < phi_max(theta_h)
// with cos(phi_max) = -cot(theta_v) cot(2 theta_h) up to theta_h = pi/4 + theta_v/2; the
// integral is split there, so the Gauss rules never straddle the n.l = 0 kink, and the
// partial piece uses a smoothstep substitution that removes the square-root endpoints.
// G2 / (n.v) falls to zero within ~min(alpha, n.v) of the n.l = 0 edges (a band the CDF
// squeezes to ~alpha^3), so the initial partition adds geometric breakpoints at
// min(alpha, n.v) 2^k from those edges; and, in the full-circle piece, at theta_h = alpha 2^k,
// since the CDF also squeezes the far tail (theta_h >> alpha, where the Fresnel weight and G2
// vary) into 1 - u ~ (alpha / theta_h)^2. Without those, the estimate of a 41 x 41 table on
// [0.02, 1]^2 (r = 0.02, mu = 0.167) was 4.4e-7 against a true error of 2.3e-6.
// The QMC integrator instead samples (u, u2) over the whole square (an independent check).
//
// Limits: alpha = 0 is the mirror limit taken at fixed mu: E = 1, A = 1 - (1 - mu)^5,
// B = (1 - mu)^5. mu = 0 is the continuous limit mu -> 0 (G2 / (n.v) -> 2 / alpha there).
#pragma once

#include "lgp/datasets/brdf.hpp"
#include "lgp/datasets/integrator.hpp"

namespace lgp::datasets {

struct DfgValue {
  double A = 0, B = 0, E = 0;              // E = A + B
  double err_A = 0, err_B = 0, err_E = 0;  // estimated absolute integration errors
  uint64_t evals = 0;
  bool converged = true;
};

// split_fresnel = false computes only E (no Fresnel weight is evaluated; A and B are 0).
DfgValue dfgPoint(double mu, double alpha, Visibility vis, bool split_fresnel,
                  const IntegratorOptions& opt, Counters* counters = nullptr);

}  // namespace lgp::datasets
