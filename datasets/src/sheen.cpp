#include "lgp/datasets/sheen.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <vector>

#include "lgp/datasets/quadrature.hpp"

namespace lgp::datasets {

namespace {
constexpr double kPi = std::numbers::pi;

// f(l, v) (n.l) for l = (lx, ly, lz), v = (sv, 0, mu). 1 - (n.h)^2 is formed from the
// horizontal components of l + v, without cancellation at the lobe's peak.
double sheenCos(double lx, double ly, double lz, double sv, double mu, double alpha) {
  if (lz <= 0.0) return 0.0;
  const double hx = lx + sv, hz = lz + mu;
  const double hor = hx * hx + ly * ly;
  const double len2 = hor + hz * hz;
  if (!(len2 > 0.0)) return 0.0;  // l = -v: h undefined, a point of measure zero
  const double den = 4.0 * (lz + mu - lz * mu);
  return charlieDFromCos2(hz * hz / len2, alpha) * lz / den;
}

// Breakpoints from `to` at s 2^k (k = -2, -1, ...) inside [lo, hi], either side.
void graded(std::vector<double>& cuts, double to, double s, double lo, double hi) {
  for (int k = -2; k < 60; ++k) {
    const double d = std::ldexp(s, k);
    if (d >= 0.5 * (hi - lo)) break;
    if (to - d > lo) cuts.push_back(to - d);
    if (to + d < hi) cuts.push_back(to + d);
  }
}

// The lobe's scale next to the horizon is min(alpha, mu), never below 2^-30 sqrt(alpha): a
// sharp lobe is sqrt(alpha) wide in theta_l when mu is smaller than that, and the 60 graded
// breakpoints must reach it. theta_l = theta_v (with phi_l = pi, a box edge) is the mirror
// direction, where h = n and D ~ theta_h^(1/alpha) has a kink (1 <= 1/alpha < 2) or a
// singular higher derivative: a breakpoint there keeps the product rules converging fast.
std::vector<Box<2>> sheenBoxes(double mu, double alpha) {
  const double edge =
      std::max(mu > 0.0 ? std::min(alpha, mu) : alpha, std::ldexp(std::sqrt(alpha), -30));
  std::vector<double> th = {0.0, 0.5 * kPi}, ph = {0.0, kPi};
  if (const double tv = std::acos(mu); tv > 0.0 && tv < 0.5 * kPi) th.push_back(tv);
  graded(th, 0.5 * kPi, edge, 0.0, 0.5 * kPi);
  graded(ph, 0.0, edge, 0.0, kPi);
  graded(ph, kPi, edge, 0.0, kPi);
  for (auto* v : {&th, &ph}) {
    std::sort(v->begin(), v->end());
    v->erase(std::unique(v->begin(), v->end()), v->end());
  }
  std::vector<Box<2>> boxes;
  for (size_t i = 0; i + 1 < th.size(); ++i)
    for (size_t j = 0; j + 1 < ph.size(); ++j)
      boxes.push_back({{th[i], ph[j]}, {th[i + 1], ph[j + 1]}});
  return boxes;
}
}  // namespace

double charlieDFromCos2(double cos2h, double alpha) {
  const double inv = 1.0 / alpha;
  const double s = cos2h < 1.0 ? std::exp(0.5 * inv * std::log1p(-cos2h)) : 0.0;
  return (2.0 + inv) * s / (2.0 * kPi);
}

double sheenAtGrazing(double alpha) {
  // W(n) = (sqrt(pi) / 2) G(x) / G(x + 1/2), x = (n + 1) / 2, n = 1/alpha + 2. For large x
  // the difference of lgammas cancels: the asymptotic series of log(G(x) / G(x + 1/2)) instead
  // (terms to x^-7; the next is below 1e-15 for x >= 50). In logs throughout, so that 1/alpha
  // may overflow (a subnormal alpha) while E ~ 1 / sqrt(2 pi alpha) does not.
  const double log_x = std::log1p(3.0 * alpha) - std::log(2.0 * alpha);  // x = (1 + 3a) / 2a
  double log_ratio;
  if (log_x < std::log(50.0)) {
    const double x = std::exp(log_x);
    log_ratio = std::lgamma(x) - std::lgamma(x + 0.5);
  } else {
    const double t = 2.0 * alpha / (1.0 + 3.0 * alpha), t2 = t * t;
    log_ratio = -0.5 * log_x +
                t * (1.0 / 8 + t2 * (-1.0 / 192 + t2 * (1.0 / 640 + t2 * (-17.0 / 14336))));
  }
  // E = (2 + 1/alpha) W / pi, 2 + 1/alpha = (1 + 2 alpha) / alpha.
  return std::exp(std::log1p(2.0 * alpha) - std::log(alpha) + std::log(0.5 / std::sqrt(kPi)) +
                  log_ratio);
}

SheenValue sheenPoint(double mu, double alpha, const IntegratorOptions& opt, Counters* counters) {
  SheenValue out;
  mu = std::clamp(mu, 0.0, 1.0);
  if (alpha <= 0.0) {  // all microfacets at the horizon: nothing reaches n.l > 0 for mu > 0
    out.E = mu > 0.0 ? 0.0 : std::numeric_limits<double>::infinity();
    return out;
  }
  if (mu == 0.0) {  // the closed form, exact where quadrature misses a lobe sqrt(alpha) wide
    out.E = sheenAtGrazing(alpha);
    out.error = 1e-13 * out.E;
    return out;
  }
  const double sv = std::sqrt(std::max(0.0, 1.0 - mu * mu));
  Estimate<1> e;
  if (opt.kind == IntegratorKind::Qmc) {
    auto fq = [&](const std::array<double, 2>& p, std::array<double, 1>& o) {
      const double lz = std::sqrt(1.0 - p[0]), s = std::sqrt(p[0]), phi = 2.0 * kPi * p[1];
      if (lz <= 0.0) return;  // cosine-weighted: pdf = n.l / pi
      o[0] = kPi * sheenCos(s * std::cos(phi), s * std::sin(phi), lz, sv, mu, alpha) / lz;
    };
    QmcOptions q;
    q.points = opt.qmc_points;
    q.shifts = opt.qmc_shifts;
    e = qmc<2, 1>(fq, q);
  } else {
    auto f = [&](const std::array<double, 2>& p, std::array<double, 1>& o) {
      const double st = std::sin(p[0]), lz = std::cos(p[0]);
      o[0] = 2.0 * st * sheenCos(st * std::cos(p[1]), st * std::sin(p[1]), lz, sv, mu, alpha);
    };
    const std::vector<Box<2>> boxes = sheenBoxes(mu, alpha);
    if (opt.kind == IntegratorKind::Gauss) {
      e = gaussProduct<2, 1>(f, std::span<const Box<2>>(boxes), opt.order);
    } else {
      AdaptiveOptions ao;
      ao.abs_tol = opt.abs_tol;
      ao.order = opt.adaptive_order;
      ao.max_evals = opt.max_evals;
      e = adaptive<2, 1>(f, std::span<const Box<2>>(boxes), ao);
    }
  }
  out.E = e.value[0];
  out.error = e.error[0];
  out.evals = e.evals;
  out.converged = e.converged;
  if (counters) counters->sheen += e.evals;
  return out;
}

}  // namespace lgp::datasets
