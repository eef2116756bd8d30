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
#pragma once

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

}  // namespace lgp::datasets
