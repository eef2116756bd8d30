// normalization: energy normalization N of the smoothed representative-point sphere light
// (Karis 2013, "Real Shading in Unreal Engine 4").
//
// The exact integral computed
// ---------------------------
// Light placement: a uniform sphere light of radiance L_e whose centre direction c is the
// surface normal n (normal incidence; no incidence angles are averaged), subtending the cone
// half-angle theta_s in [0, pi/2). Surface: GGX specular f_spec with F = 1 (Fresnel is shaded
// separately), roughness alpha, the scene's G2.
//
// True reflected energy (radiant exitance, i.e. outgoing radiance weighted by n.v):
//   P_true = integral_{v in H} integral_{l in cone(c, theta_s)} f(l, v) L_e (n.l) (n.v) dl dv
//          = L_e integral_{cone} (n.l) E(n.l) dl            (reciprocity, E = directional albedo)
//          = 2 pi L_e integral_{cos theta_s}^{1} E(mu) mu dmu.
// Representative-point energy: the light is replaced by a point light in the direction
// l_rep(v) with the same irradiance at normal incidence, E_perp = pi sin^2(theta_s) L_e:
//   P_rep  = pi sin^2(theta_s) L_e integral_{v in H} f(l_rep(v), v) (n.l_rep) (n.v) dv
//          = pi sin^2(theta_s) L_e 2 pi integral_0^1 g(mu_v) mu_v dmu_v,   g = f (n.l_rep)
// (azimuthally symmetric because c = n). Representative point (Karis 2013) with the
// light centre at unit distance, L = c, sourceRadius R = sin(theta_s), reflection ray r of v:
//   centerToRay = (L.r) r - L,
//   l_rep = normalize(L + centerToRay * softmin(1, R / |centerToRay|)),
//   softmin(x, y) = (x^s + y^s)^(1/s), s = -3 by default (s -> -inf is Karis' hard min).
// Normalization:
//   N(alpha, theta_s) = P_true / P_rep
//     = [2 integral_{cos theta_s}^1 E(mu) mu dmu] / [2 pi sin^2(theta_s) integral_0^1 g mu_v
//     dmu_v].
// Limits: N -> 1 as theta_s -> 0 (both sides tend to sin^2(theta_s) E(1)); N(theta_s = 0) = 1.
// N -> 0 as alpha -> 0 at a fixed theta_s > 0: P_rep then grows like a delta lobe aimed at the
// representative point, while P_true stays bounded; the table uses that limit,
// N(alpha = 0, theta_s > 0) = 0.
// Integrators: Gauss/adaptive use the 1-D forms above (E from dfg.hpp at Gauss nodes).
// QMC instead estimates P_true as the 4-D double integral (uniform cone x cosine hemisphere)
// and P_rep with 3-D vectors over the hemisphere: an independent check of the reduction.
#pragma once

#include "lgp/datasets/brdf.hpp"
#include "lgp/datasets/integrator.hpp"

namespace lgp::datasets {

struct NormalizationValue {
  double N = 1, error = 0;
  double p_true = 0, p_rep = 0;  // P_true / (L_e sin^2 theta_s) and P_rep / (L_e sin^2 theta_s)
  uint64_t evals = 0;
  bool converged = true;
};

NormalizationValue normalizationPoint(double alpha, double theta_s, Visibility vis,
                                      double softmin_s, const IntegratorOptions& opt,
                                      Counters* counters = nullptr);

// l_rep for view v and light centre c (unit vectors), cone half-angle theta_s (3-D form).
void representativePoint(const double v[3], const double n[3], const double c[3], double theta_s,
                         double softmin_s, double out[3]);

}  // namespace lgp::datasets
