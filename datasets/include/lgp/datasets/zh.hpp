// zh: Disney-diffuse cosine-weighted BRDF in zonal harmonics (Burley 2012, "Physically-Based
// Shading at Disney").
//
// CBRDF(l) = f_d(l, v) max(0, n.l), baseColor = 1, with r the Disney roughness used as is:
//   f_d = (1/pi)(1 + (F_D90 - 1)(1 - n.l)^5)(1 + (F_D90 - 1)(1 - n.v)^5),
//   F_D90 = 0.5 + 2 r (l.h)^2,   (l.h)^2 = (1 + l.v) / 2;   Lambert: f_d = 1/pi.
// Moments over the hemisphere (frame n = z, v = (sin theta_v, 0, mu)):
//   M0 = integral CBRDF dl,  m = integral CBRDF l dl,  M2 = integral CBRDF l l^T dl.
// Lobe axis d = m / |m| (the optimal linear direction of the band-1 SH); beta solves
// d = normalize((1 - beta) n + beta v): beta = k / (sin theta_v + k (1 - mu)), k = m_x / m_z.
// At mu = 1 (sin theta_v < 1e-4) beta is the limit theta_v -> 0, evaluated at theta_v = 1e-4
// rad with a 48-point Gauss rule (the moments are smooth).
// Outputs, with real SH normalization Y00 = 0.2820948, Y10 = 0.4886025 cos,
// Y20 = 0.3153916 (3 cos^2 - 1):
//   ZH0 = Y00 M0,  ZH1 = 0.4886025 |m|,  ZH2 = 0.3153916 (3 d^T M2 d - M0),
//   ZH1/ZH0, ZH2/ZH0 and beta.
// Integrated in (theta_l, phi) over [0, pi/2] x [0, pi] (mirror symmetry in phi), where the
// integrand is smooth; QMC instead uses cosine-weighted hemisphere sampling.
// Lambert check: ZH0 = 0.2820948, ZH1 = 0.3257350, ZH2 = 0.1576958 (ratios 1.1547, 0.5590).
#pragma once

#include "lgp/datasets/brdf.hpp"
#include "lgp/datasets/integrator.hpp"

namespace lgp::datasets {

struct ZhValue {
  double zh0 = 0, zh1 = 0, zh2 = 0, ratio1 = 0, ratio2 = 0, beta = 0;
  double err_zh0 = 0, err_zh1 = 0, err_zh2 = 0, err_ratio1 = 0, err_ratio2 = 0, err_beta = 0;
  uint64_t evals = 0;
  bool converged = true;
};

ZhValue zhPoint(double mu, double r, Diffuse model, const IntegratorOptions& opt,
                Counters* counters = nullptr);

}  // namespace lgp::datasets
