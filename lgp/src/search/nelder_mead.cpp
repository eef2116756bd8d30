#include "lgp/search/nelder_mead.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

namespace lgp {

Status NelderMeadConfig::validate() const {
  if (max_evaluations < 1) return Status::error("max_evaluations: must be >= 1");
  if (restarts < 0) return Status::error("restarts: must be >= 0");
  if (!(initial_step > 0)) return Status::error("initial_step: must be > 0");
  if (!(tolerance >= 0)) return Status::error("tolerance: must be >= 0");
  if (!(alpha > 0 && gamma > 1 && rho > 0 && rho < 1 && sigma > 0 && sigma < 1))
    return Status::error("coefficients: need alpha > 0, gamma > 1, 0 < rho < 1, 0 < sigma < 1");
  return Status::ok();
}

NelderMeadResult nelderMead(const std::function<double(const std::vector<double>&)>& f,
                            std::vector<double> x0, const NelderMeadConfig& cfg, Rng& rng) {
  using Vec = Eigen::VectorXd;
  const int n = static_cast<int>(x0.size());
  NelderMeadResult res;
  const double inf = std::numeric_limits<double>::infinity();
  std::vector<double> tmp(n);
  auto eval = [&](const Vec& x) {
    for (int i = 0; i < n; ++i) tmp[i] = x[i];
    ++res.evaluations;
    const double v = f(tmp);
    return std::isfinite(v) ? v : inf;
  };
  Vec best = Eigen::Map<Vec>(x0.data(), n);
  double fbest = eval(best);
  if (n == 0) {
    res.x = x0;
    res.f = fbest;
    return res;
  }
  double step_scale = 1.0;
  for (int restart = 0; restart <= cfg.restarts && res.evaluations < cfg.max_evaluations;
       ++restart) {
    // Simplex: best point plus one vertex per coordinate, each displaced along the axis and
    // slightly along a random direction so the simplex is never degenerate.
    std::vector<Vec> s(n + 1, best);
    std::vector<double> fs(n + 1, fbest);
    for (int i = 0; i < n; ++i) {
      Vec v = best;
      const double h = cfg.initial_step * step_scale * std::max(std::fabs(best[i]), 0.1);
      v[i] += rng.chance(0.5) ? h : -h;
      for (int j = 0; j < n; ++j)
        if (j != i) v[j] += 0.05 * h * rng.uniform(-1.0, 1.0);
      s[i + 1] = v;
      fs[i + 1] = eval(v);
    }
    std::vector<int> order(n + 1);
    while (res.evaluations < cfg.max_evaluations) {
      std::iota(order.begin(), order.end(), 0);
      std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return fs[a] < fs[b]; });
      const int lo = order[0], hi = order[n], nh = order[n - 1];
      if (std::isfinite(fs[hi]) && fs[hi] - fs[lo] <= cfg.tolerance * (std::fabs(fs[lo]) + 1e-30))
        break;
      Vec centroid = Vec::Zero(n);
      for (int k = 0; k < n; ++k) centroid += s[order[k]];
      centroid /= n;
      const Vec xr = centroid + cfg.alpha * (centroid - s[hi]);
      const double fr = eval(xr);
      if (fr < fs[lo]) {
        const Vec xe = centroid + cfg.gamma * (xr - centroid);
        const double fe = eval(xe);
        if (fe < fr) {
          s[hi] = xe;
          fs[hi] = fe;
        } else {
          s[hi] = xr;
          fs[hi] = fr;
        }
      } else if (fr < fs[nh]) {
        s[hi] = xr;
        fs[hi] = fr;
      } else {
        const bool outside = fr < fs[hi];
        const Vec xc = outside ? Vec(centroid + cfg.rho * (xr - centroid))
                               : Vec(centroid + cfg.rho * (s[hi] - centroid));
        const double fc = eval(xc);
        if (fc < (outside ? fr : fs[hi])) {
          s[hi] = xc;
          fs[hi] = fc;
        } else {
          for (int k = 1; k <= n; ++k) {
            const int idx = order[k];
            s[idx] = s[lo] + cfg.sigma * (s[idx] - s[lo]);
            fs[idx] = eval(s[idx]);
            if (res.evaluations >= cfg.max_evaluations) break;
          }
        }
      }
    }
    for (int k = 0; k <= n; ++k)
      if (fs[k] < fbest) {
        fbest = fs[k];
        best = s[k];
      }
    step_scale *= 0.5;  // later restarts probe closer to the incumbent
  }
  res.x.assign(best.data(), best.data() + n);
  res.f = fbest;
  return res;
}

}  // namespace lgp
