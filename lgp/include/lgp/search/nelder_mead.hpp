// Nelder-Mead downhill simplex (Nelder & Mead 1965) with restarts, used to refine the
// constants of promising programs. Derivative-free, so it works on RMSE/max-abs directly.
#pragma once

#include <functional>
#include <vector>

#include "lgp/core/rng.hpp"
#include "lgp/core/status.hpp"

namespace lgp {

struct NelderMeadConfig {
  int max_evaluations = 300;   // objective evaluations per call, all restarts included
  int restarts = 2;            // fresh simplices around the best point after convergence
  double initial_step = 0.25;  // simplex edge: step * max(|x_i|, 0.1) per coordinate
  double tolerance = 1e-9;     // stop when (f_worst - f_best) <= tol * (|f_best| + 1e-30)
  // Standard coefficients: reflection, expansion, contraction, shrink.
  double alpha = 1.0, gamma = 2.0, rho = 0.5, sigma = 0.5;
  Status validate() const;
};

struct NelderMeadResult {
  std::vector<double> x;
  double f = 0;
  int evaluations = 0;
};

// Minimises f from x0. Non-finite values are treated as +inf (worse than anything finite).
// Each restart perturbs the simplex directions randomly (rng) to avoid a planar simplex.
NelderMeadResult nelderMead(const std::function<double(const std::vector<double>&)>& f,
                            std::vector<double> x0, const NelderMeadConfig& cfg, Rng& rng);

}  // namespace lgp
