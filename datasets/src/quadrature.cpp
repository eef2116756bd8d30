#include "lgp/datasets/quadrature.hpp"

#include <map>
#include <memory>
#include <mutex>
#include <numbers>

namespace lgp::datasets {

namespace {
// Newton iteration on P_n from the three-term recurrence, starting at the Tricomi
// approximation of the k-th root; symmetric nodes are mirrored. Converges to ~1 ulp.
// P_n(x) and P_n'(x) from the three-term recurrence.
struct Legendre {
  double p, dp;
};
Legendre legendre(int n, double x) {
  double p0 = 1, p1 = x;
  for (int j = 2; j <= n; ++j) {
    const double p2 = ((2.0 * j - 1.0) * x * p1 - (j - 1.0) * p0) / j;
    p0 = p1;
    p1 = p2;
  }
  return {p1, n * (x * p1 - p0) / (x * x - 1.0)};
}

GaussRule computeRule(int n) {
  GaussRule g;
  g.x.assign(n, 0.0);
  g.w.assign(n, 0.0);
  for (int k = 0; k < (n + 1) / 2; ++k) {
    double x = std::cos(std::numbers::pi * (k + 0.75) / (n + 0.5));
    for (int it = 0; it < 100; ++it) {
      const Legendre l = legendre(n, x);
      const double dx = l.p / l.dp;
      x -= dx;
      if (std::abs(dx) < 1e-16) break;
    }
    const double dp = legendre(n, x).dp;  // derivative at the converged root
    const double w = 2.0 / ((1.0 - x * x) * dp * dp);
    // map [-1, 1] -> [0, 1]; node k is the k-th largest
    g.x[n - 1 - k] = 0.5 * (1.0 + x);
    g.w[n - 1 - k] = 0.5 * w;
    g.x[k] = 0.5 * (1.0 - x);
    g.w[k] = 0.5 * w;
  }
  return g;
}
}  // namespace

const GaussRule& gaussLegendre(int n) {
  static std::mutex mu;
  static std::map<int, std::unique_ptr<GaussRule>> cache;
  std::lock_guard<std::mutex> lock(mu);
  auto& slot = cache[n];
  if (!slot) slot = std::make_unique<GaussRule>(computeRule(std::clamp(n, 1, 256)));
  return *slot;
}

}  // namespace lgp::datasets
