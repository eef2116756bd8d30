// energy: Kulla-Conty energy compensation terms (Kulla & Conty 2017, "Revisiting Physically Based
// Shading at Imageworks").
//
//   E(mu, r)    = integral of f_spec(l, v) (n.l) dl with F = 1      (see dfg.hpp)
//   1 - E(mu, r)
//   E_avg(r)    = 2 integral_0^1 E(mu) mu dmu
//               = 4 integral_0^1 E(x^2) x^3 dx   (x = sqrt(mu): smooth near grazing)
// E_avg uses Gauss-Legendre in x with 16 and 24 nodes; its error estimate is the difference
// of the two plus the node errors of E weighted by the rule. When 4 sqrt(alpha) < 1/4 the
// grazing layer of E (mu ~ alpha) gets a panel [0, 4 sqrt(alpha)] of its own, with 8 and 12
// nodes.
//   F_avg       = 2 integral_0^1 F(mu) mu dmu = F0 + (F90 - F0) / 21 for Schlick (closed form,
//                 used as a check of the quadrature).
//
// The multiple-scattering factors built from E and E_avg:
//   ms_turquin  = (1 - E) / E: Turquin 2019 ("Practical multiple scattering compensation for
//                 microfacet models") scales the single-scattering lobe by 1 + F0 (1 - E) / E.
//   ms_lobe     = (1 - E(mu)) / sqrt(pi (1 - E_avg)): Kulla and Conty's lobe
//                 f_ms(l, v) = (1 - E(n.l))(1 - E(n.v)) / (pi (1 - E_avg)) is
//                 ms_lobe(n.l) ms_lobe(n.v), and integral_H f_ms (n.l) dl = 1 - E(n.v).
// Errors are propagated to first order; alpha = 0 (E = E_avg = 1) gives the limits 0.
#pragma once

#include <cmath>
#include <numbers>

#include "lgp/datasets/brdf.hpp"
#include "lgp/datasets/integrator.hpp"

namespace lgp::datasets {

struct EavgValue {
  double value = 0;
  double error = 0;
  uint64_t evals = 0;
  bool converged = true;
};

EavgValue eAvg(double alpha, Visibility vis, const IntegratorOptions& opt,
               Counters* counters = nullptr);

// 2 integral_0^1 F_schlick(mu) mu dmu by Gauss-Legendre (n nodes); equals F0 + (F90-F0)/21.
double fresnelAverageNumeric(double f0, double f90, int n = 8);
inline double fresnelAverageClosed(double f0, double f90) {
  return f0 + (f90 - f0) / 21.0;
}

struct DerivedValue {
  double value = 0, error = 0;
};
inline DerivedValue msTurquin(double E, double err_E) {
  if (!(E > 0.0)) return {0.0, 0.0};
  return {(1.0 - E) / E, err_E / (E * E)};
}
inline DerivedValue msLobe(double E, double err_E, double E_avg, double err_avg) {
  const double d = 1.0 - E_avg;
  if (!(d > 0.0)) return {0.0, 0.0};  // alpha = 0: E = E_avg = 1
  const double s = std::sqrt(std::numbers::pi * d);
  const double v = (1.0 - E) / s;
  return {v, err_E / s + 0.5 * std::abs(v) / d * err_avg};
}

}  // namespace lgp::datasets
