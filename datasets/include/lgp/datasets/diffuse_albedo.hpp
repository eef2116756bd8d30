// Directional albedo of two diffuse BRDFs, with baseColor = 1 and the roughness input r used
// as it is (not remapped), in the forms MaterialX's pbrlib evaluates them:
//
//   Burley (Burley 2012, "Physically-Based Shading at Disney"; mx_burley_diffuse):
//     f = (1/pi) (1 + (F_D90 - 1)(1 - n.l)^5) (1 + (F_D90 - 1)(1 - n.v)^5),
//     F_D90 = 0.5 + 2 r (l.h)^2 = 0.5 + r (1 + l.v)
//   Oren-Nayar, qualitative model (Oren and Nayar 1994; mx_oren_nayar_diffuse):
//     f = (A + B max(0, s) / max(n.l, n.v)) / pi,   s = l.v - (n.l)(n.v),
//     A = 1 - 0.5 sigma^2 / (sigma^2 + 0.33),  B = 0.45 sigma^2 / (sigma^2 + 0.09),  sigma = r
//
//   E(mu, r) = integral_H f(l, v) (n.l) dl
//
// Both are exact, not quadratures. Burley: f is a quadratic in l.v, whose azimuthal average
// leaves a polynomial of degree 8 in x = n.l, integrated by an 8-node Gauss-Legendre rule
// (exact to degree 15). Oren-Nayar: s / max(n.l, n.v) = cos(phi) sin(alpha) tan(beta) with
// alpha = max(theta_l, theta_v), beta = min; the azimuth gives 2, and the polar integral splits
// at theta_l = theta_v:
//   E = A + (2 B / pi) [ s_v (theta_v - s_v mu) / 2 + s_v mu (1 + s_v + s_v^2) / (3 (1 + s_v)) ],
//   s_v = sin(theta_v) (the second term is tan(theta_v) (1 - s_v^3) / 3, written without the
//   cancellation at grazing view). E(1) = A, E(0) = A + B / 2.
// The estimates are the rounding floor (64 eps |E|).
#pragma once

#include "lgp/datasets/integrator.hpp"

namespace lgp::datasets {

struct AlbedoValue {
  double E = 0, error = 0;
};

AlbedoValue burleyAlbedo(double mu, double r, Counters* counters = nullptr);
AlbedoValue orenNayarAlbedo(double mu, double r, Counters* counters = nullptr);

}  // namespace lgp::datasets
