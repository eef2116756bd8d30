#include "lgp/search/differential_evolution.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <numeric>

namespace lgp {

Status DifferentialEvolutionConfig::validate() const {
  if (max_evaluations < 1) return Status::error("max_evaluations: must be >= 1");
  if (population != 0 && population < 3)
    return Status::error("population: must be 0 (automatic) or >= 3");
  if (!(f > 0 && f <= 2)) return Status::error("f: must be in (0, 2]");
  if (!(cr >= 0 && cr <= 1)) return Status::error("cr: must be in [0, 1]");
  if (!(p_best > 0 && p_best <= 1)) return Status::error("p_best: must be in (0, 1]");
  if (!(init_scale >= 0 && std::isfinite(init_scale)))
    return Status::error("init_scale: must be finite and >= 0");
  if (!(min_abs_step > 0 && std::isfinite(min_abs_step)))
    return Status::error("min_abs_step: must be finite and > 0");
  if (!(tolerance >= 0)) return Status::error("tolerance: must be >= 0");
  return Status::ok();
}

DifferentialEvolutionResult differentialEvolution(
    const std::function<double(const std::vector<double>&)>& f, const std::vector<double>& x0,
    const DifferentialEvolutionConfig& cfg, Rng& rng) {
  const int n = static_cast<int>(x0.size());
  const double inf = std::numeric_limits<double>::infinity();
  DifferentialEvolutionResult res;
  auto eval = [&](const std::vector<double>& x) {
    ++res.evaluations;
    const double v = f(x);
    return std::isfinite(v) ? v : inf;
  };
  // res holds the best point so far; it is replaced only by a strictly better finite value.
  res.x = x0;
  res.f = eval(x0);
  if (n == 0 || res.evaluations >= cfg.max_evaluations) return res;

  const bool dither = cfg.dither && cfg.f < 1;
  const int np = cfg.population > 0 ? std::max(cfg.population, 3) : std::clamp(5 * n, 8, 40);
  const auto unp = static_cast<uint32_t>(np);
  const int pool =
      std::clamp(static_cast<int>(std::ceil(cfg.p_best * np - 1e-9)), std::min(2, np), np);
  // Member k occupies pop[k * n, (k + 1) * n); all buffers are allocated once.
  std::vector<double> pop(static_cast<size_t>(np) * static_cast<size_t>(n));
  std::vector<double> fit(np, inf);
  std::vector<double> trial(n);
  std::vector<int> order(np);
  auto member = [&](int k) { return pop.data() + static_cast<size_t>(k) * n; };
  auto accept = [&](int k, double v) {
    std::copy(trial.begin(), trial.end(), member(k));
    fit[k] = v;
    if (v < res.f) {
      res.f = v;
      res.x = trial;  // same size: reuses the storage
    }
  };

  // Initial population: x0 itself, then Gaussian perturbations of it.
  std::copy(x0.begin(), x0.end(), member(0));
  fit[0] = res.f;
  for (int k = 1; k < np; ++k) {
    if (res.evaluations >= cfg.max_evaluations) return res;
    for (int j = 0; j < n; ++j) {
      const double sigma = std::max(cfg.init_scale * std::fabs(x0[j]), cfg.min_abs_step);
      trial[j] = x0[j] + sigma * rng.normal();
    }
    accept(k, eval(trial));
  }

  while (res.evaluations < cfg.max_evaluations) {
    // p-best pool: the `pool` best members (ties by index, so the order is fully specified).
    std::iota(order.begin(), order.end(), 0);
    std::partial_sort(order.begin(), order.begin() + pool, order.end(),
                      [&](int a, int b) { return fit[a] < fit[b] || (fit[a] == fit[b] && a < b); });
    const double lo = fit[order[0]];
    const double hi = *std::max_element(fit.begin(), fit.end());
    if (std::isfinite(hi) && hi - lo <= cfg.tolerance * (std::fabs(lo) + 1e-30)) break;
    for (int i = 0; i < np && res.evaluations < cfg.max_evaluations; ++i) {
      const double* xi = member(i);
      const double* xp = member(order[rng.below(static_cast<uint32_t>(pool))]);
      int r1 = i, r2 = i;
      while (r1 == i) r1 = static_cast<int>(rng.below(unp));
      while (r2 == i || r2 == r1) r2 = static_cast<int>(rng.below(unp));
      const double* x1 = member(r1);
      const double* x2 = member(r2);
      const double w = dither ? rng.uniform(cfg.f, 1.0) : cfg.f;
      const int jr = static_cast<int>(rng.below(static_cast<uint32_t>(n)));
      for (int j = 0; j < n; ++j)
        trial[j] =
            (j == jr || rng.chance(cfg.cr)) ? xi[j] + w * (xp[j] - xi[j] + x1[j] - x2[j]) : xi[j];
      const double ft = eval(trial);
      if (ft <= fit[i]) accept(i, ft);  // "no worse" lets members drift across plateaus
    }
  }
  return res;
}

}  // namespace lgp
