// Integrator settings of the generator tests: a method, a tolerance per integral and enough
// QMC points that its estimate is a useful check.
#pragma once

#include "lgp/datasets/integrator.hpp"

namespace lgp::datasets::test {

inline IntegratorOptions method(IntegratorKind k, double tol) {
  IntegratorOptions o;
  o.kind = k;
  o.abs_tol = tol;
  o.qmc_points = 1 << 15;
  return o;
}

}  // namespace lgp::datasets::test
