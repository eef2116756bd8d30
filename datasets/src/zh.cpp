#include "lgp/datasets/zh.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>

#include "lgp/datasets/quadrature.hpp"

namespace lgp::datasets {

namespace {
constexpr double kPi = std::numbers::pi;
constexpr double kY00 = 0.28209479177387814;
constexpr double kY10 = 0.4886025119029199;
constexpr double kY20 = 0.31539156525252005;

using Moments = std::array<double, 6>;  // M0, mx, mz, Mxx, Mxz, Mzz

struct Derived {
  double zh0, zh1, zh2, r1, r2, beta;
};

Derived derive(const Moments& m, double mu, double sv) {
  Derived d{};
  const double len = std::hypot(m[1], m[2]);
  const double dx = len > 0 ? m[1] / len : 0.0, dz = len > 0 ? m[2] / len : 1.0;
  d.zh0 = kY00 * m[0];
  d.zh1 = kY10 * len;
  d.zh2 = kY20 * (3.0 * (dx * dx * m[3] + 2.0 * dx * dz * m[4] + dz * dz * m[5]) - m[0]);
  d.r1 = d.zh0 != 0 ? d.zh1 / d.zh0 : 0.0;
  d.r2 = d.zh0 != 0 ? d.zh2 / d.zh0 : 0.0;
  const double k = m[2] != 0 ? m[1] / m[2] : 0.0;
  const double den = sv + k * (1.0 - mu);
  d.beta = den != 0 ? k / den : 0.0;
  return d;
}

Estimate<6> moments(double mu, double r, Diffuse model, const IntegratorOptions& opt) {
  const double sv = std::sqrt(std::max(0.0, 1.0 - mu * mu));
  auto cbrdf = [&](double lx, double ly, double lz) {
    (void)ly;
    return diffuseBrdf(lz, mu, lx * sv + lz * mu, r, model) * lz;
  };
  if (opt.kind == IntegratorKind::Qmc) {
    // cosine-weighted: l.z = sqrt(1 - u1), pdf = l.z / pi, full azimuth
    auto f = [&](const std::array<double, 2>& p, std::array<double, 6>& o) {
      const double lz = std::sqrt(1.0 - p[0]), s = std::sqrt(p[0]);
      const double phi = 2.0 * kPi * p[1];
      const double lx = s * std::cos(phi), ly = s * std::sin(phi);
      if (lz <= 0) return;
      const double c = cbrdf(lx, ly, lz) * kPi / lz;
      o = {c, c * lx, c * lz, c * lx * lx, c * lx * lz, c * lz * lz};
    };
    QmcOptions q;
    q.points = opt.qmc_points;
    q.shifts = opt.qmc_shifts;
    return qmc<2, 6>(f, q);
  }
  auto f = [&](const std::array<double, 2>& p, std::array<double, 6>& o) {
    const double th = p[0], phi = p[1];
    const double st = std::sin(th), lz = std::cos(th);
    const double lx = st * std::cos(phi), ly = st * std::sin(phi);
    const double c = 2.0 * cbrdf(lx, ly, lz) * st;  // x2: phi in [0, pi]
    o = {c, c * lx, c * lz, c * lx * lx, c * lx * lz, c * lz * lz};
  };
  const Box<2> box{{0.0, 0.0}, {0.5 * kPi, kPi}};
  std::span<const Box<2>> boxes(&box, 1);
  if (opt.kind == IntegratorKind::Gauss) return gaussProduct<2, 6>(f, boxes, opt.order);
  AdaptiveOptions ao;
  // Moments feed ratios: keep a margin. beta = k / (sin theta_v + k (1 - mu)) divides the error
  // of m_x by sin theta_v, so near mu = 1 the moments are resolved that much further (the
  // integrand is smooth: it costs little). Below sin theta_v = 1e-4 beta is the limit instead.
  ao.abs_tol = 0.25 * opt.abs_tol * (sv >= 1e-4 ? std::min(1.0, sv) : 1.0);
  ao.order = opt.adaptive_order;
  ao.max_evals = opt.max_evals;
  return adaptive<2, 6>(f, boxes, ao);
}
}  // namespace

ZhValue zhPoint(double mu, double r, Diffuse model, const IntegratorOptions& opt,
                Counters* counters) {
  mu = std::clamp(mu, 0.0, 1.0);
  ZhValue out;
  auto e = moments(mu, r, model, opt);
  double sv = std::sqrt(std::max(0.0, 1.0 - mu * mu));
  const Derived d = derive(e.value, mu, sv);
  out.zh0 = d.zh0;
  out.zh1 = d.zh1;
  out.zh2 = d.zh2;
  out.ratio1 = d.r1;
  out.ratio2 = d.r2;
  out.beta = d.beta;
  out.evals = e.evals;
  out.converged = e.converged;
  // Linearised error propagation from the moment errors (central differences).
  std::array<double, 6> err{};
  for (int k = 0; k < 6; ++k) {
    if (e.error[k] == 0) continue;
    Moments p = e.value, m = e.value;
    p[k] += e.error[k];
    m[k] -= e.error[k];
    const Derived a = derive(p, mu, sv), b = derive(m, mu, sv);
    const double h[6] = {a.zh0 - b.zh0, a.zh1 - b.zh1, a.zh2 - b.zh2,
                         a.r1 - b.r1,   a.r2 - b.r2,   a.beta - b.beta};
    for (int j = 0; j < 6; ++j) err[j] += 0.5 * std::abs(h[j]);
  }
  out.err_zh0 = err[0];
  out.err_zh1 = err[1];
  out.err_zh2 = err[2];
  out.err_ratio1 = err[3];
  out.err_ratio2 = err[4];
  out.err_beta = err[5];
  if (sv < 1e-4 && model == Diffuse::Disney) {
    // beta at mu -> 1: m_x and sin(theta_v) vanish together; take the limit numerically.
    const double t = 1e-4;
    IntegratorOptions g = opt;  // the moments are smooth: a high-order rule is exact enough
    g.kind = IntegratorKind::Gauss;
    g.order = 24;
    auto e2 = moments(std::cos(t), r, model, g);
    const Derived d2 = derive(e2.value, std::cos(t), std::sin(t));
    out.beta = d2.beta;
    out.err_beta = std::abs(e2.error[1] / e2.value[2]) / t + 1e-8;
    out.evals += e2.evals;
  }
  if (counters) counters->diffuse += out.evals;
  return out;
}

}  // namespace lgp::datasets
