#include "lgp/datasets/normalization.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <vector>

#include "lgp/datasets/dfg.hpp"
#include "lgp/datasets/quadrature.hpp"

namespace lgp::datasets {

namespace {
constexpr double kPi = std::numbers::pi;

inline double dot3(const double a[3], const double b[3]) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
inline void normalize3(double a[3]) {
  const double l = std::sqrt(dot3(a, a));
  a[0] /= l;
  a[1] /= l;
  a[2] /= l;
}

// f_spec(l, v) (n.l) with n = z and F = 1. 1 - (n.h)^2 is taken as h_x^2 + h_y^2, which
// keeps its precision at the peak of a sharp lobe (where it is ~alpha^2).
inline double specCos(const double l[3], const double v[3], double alpha, Visibility vis) {
  const double nl = l[2], nv = v[2];
  if (nl <= 0 || nv <= 0) return 0.0;
  double h[3] = {l[0] + v[0], l[1] + v[1], l[2] + v[2]};
  normalize3(h);
  return specularBrdf(nl, nv, h[2], h[0] * h[0] + h[1] * h[1], alpha, vis) * nl;
}
}  // namespace

void representativePoint(const double v[3], const double n[3], const double c[3], double theta_s,
                         double s, double out[3]) {
  const double vn = dot3(v, n);
  const double r[3] = {2 * vn * n[0] - v[0], 2 * vn * n[1] - v[1], 2 * vn * n[2] - v[2]};
  const double lr = dot3(c, r);
  const double ctr[3] = {lr * r[0] - c[0], lr * r[1] - c[1], lr * r[2] - c[2]};
  const double len = std::sqrt(dot3(ctr, ctr));
  const double radius = std::sin(theta_s);
  // softmin(1, R/len) = (1 + (len/R)^(-s))^(1/s); finite at len = 0 (-> 1) and R = 0 (-> 0)
  double t;
  if (radius <= 0) {
    t = 0;
  } else {
    t = std::pow(1.0 + std::pow(len / radius, -s), 1.0 / s);
  }
  out[0] = c[0] + ctr[0] * t;
  out[1] = c[1] + ctr[1] * t;
  out[2] = c[2] + ctr[2] * t;
  normalize3(out);
}

NormalizationValue normalizationPoint(double alpha, double theta_s, Visibility vis, double s,
                                      const IntegratorOptions& opt, Counters* counters) {
  NormalizationValue out;
  if (theta_s <= 0.0) return out;  // the limit N = 1
  if (alpha <= 0.0) {              // the limit alpha -> 0 at fixed theta_s > 0
    out.N = 0.0;
    return out;
  }
  const double sin2 = std::sin(theta_s) * std::sin(theta_s);
  const double one_minus_cos = 2.0 * std::sin(0.5 * theta_s) * std::sin(0.5 * theta_s);
  static const double kN[3] = {0, 0, 1};
  uint64_t rep_evals = 0, spec_evals = 0;
  double err_true = 0, err_rep = 0;

  if (opt.kind == IntegratorKind::Qmc) {
    // 4-D: l uniform in the cone, v cosine-weighted; estimator f (n.l) Omega pi / sin^2.
    const double omega = 2.0 * kPi * one_minus_cos;
    auto ft = [&](const std::array<double, 4>& p, std::array<double, 1>& o) {
      const double cl = 1.0 - p[0] * one_minus_cos, sl = std::sqrt(std::max(0.0, 1 - cl * cl));
      const double pl = 2 * kPi * p[1];
      const double l[3] = {sl * std::cos(pl), sl * std::sin(pl), cl};
      const double cv = std::sqrt(1.0 - p[2]), sv = std::sqrt(p[2]), pv = 2 * kPi * p[3];
      const double v[3] = {sv * std::cos(pv), sv * std::sin(pv), cv};
      o[0] = specCos(l, v, alpha, vis) * omega * kPi / sin2;
    };
    auto fr = [&](const std::array<double, 2>& p, std::array<double, 1>& o) {
      const double cv = std::sqrt(1.0 - p[0]), sv = std::sqrt(p[0]), pv = 2 * kPi * p[1];
      const double v[3] = {sv * std::cos(pv), sv * std::sin(pv), cv};
      double l[3];
      representativePoint(v, kN, kN, theta_s, s, l);
      o[0] = specCos(l, v, alpha, vis) * kPi * kPi;  // E_perp pi; / (pdf = n.v/pi) * (n.v)
    };
    QmcOptions q;
    q.points = opt.qmc_points;
    q.shifts = opt.qmc_shifts;
    auto et = qmc<4, 1>(ft, q);
    auto er = qmc<2, 1>(fr, q);
    out.p_true = et.value[0];
    out.p_rep = er.value[0];
    err_true = et.error[0];
    err_rep = er.error[0];
    spec_evals = et.evals;
    rep_evals = er.evals;
  } else {
    // P_true / sin^2 = 2 pi integral_{cos ts}^1 E mu dmu / sin^2
    IntegratorOptions inner = opt;
    inner.abs_tol = 0.1 * opt.abs_tol;
    double q[2] = {0, 0}, node_err = 0;
    const int orders[2] = {8, 12};
    for (int o = 0; o < 2; ++o) {
      const GaussRule& g = gaussLegendre(orders[o]);
      for (size_t i = 0; i < g.x.size(); ++i) {
        const double mu = 1.0 - one_minus_cos * g.x[i];
        const DfgValue e = dfgPoint(mu, alpha, vis, false, inner, nullptr);
        const double w = 2.0 * kPi * g.w[i] * one_minus_cos / sin2 * mu;
        q[o] += w * e.E;
        if (o == 1) node_err += w * e.err_E;
        spec_evals += e.evals;
        out.converged = out.converged && e.converged;
      }
    }
    out.p_true = q[1];
    err_true = std::abs(q[1] - q[0]) + node_err;
    // P_rep / sin^2 = pi * 2 pi integral_0^{pi/2} g cos sin dtheta_v
    auto fr = [&](const std::array<double, 1>& p, std::array<double, 1>& o) {
      const double th = p[0];
      const double v[3] = {std::sin(th), 0.0, std::cos(th)};
      double l[3];
      representativePoint(v, kN, kN, theta_s, s, l);
      o[0] = 2.0 * kPi * kPi * specCos(l, v, alpha, vis) * v[2] * v[0];
    };
    // Initial partition: geometric breakpoints at alpha 2^k (the lobe width in theta_v) and
    // theta_s 2^k (the soft-min transition), so no rule can step over a narrow peak; and at
    // alpha 2^k below the horizon, where G2 drops to zero within ~alpha of n.v = 0 (missed, that
    // layer was a 2e-11 relative error that no estimate saw).
    std::vector<double> cuts = {0.0, 0.5 * kPi};
    for (double base : {alpha, theta_s})
      for (int k = -3; k < 40; ++k) {
        const double x = std::ldexp(base, k);
        if (x >= 0.5 * kPi) break;
        if (x > 1e-12) cuts.push_back(x);
      }
    for (int k = -3; k < 40; ++k) {
      const double x = std::ldexp(alpha, k);
      if (x >= 0.25 * kPi) break;
      cuts.push_back(0.5 * kPi - x);
    }
    std::sort(cuts.begin(), cuts.end());
    std::vector<Box<1>> parts;
    for (size_t i = 0; i + 1 < cuts.size(); ++i)
      if (cuts[i + 1] > cuts[i] * (1 + 1e-9)) parts.push_back({{cuts[i]}, {cuts[i + 1]}});
    std::span<const Box<1>> boxes(parts);
    Estimate<1> er;
    if (opt.kind == IntegratorKind::Gauss) {
      er = gaussProduct<1, 1>(fr, boxes, opt.order);
    } else {
      AdaptiveOptions ao;
      ao.rel_tol = 0.1 * opt.abs_tol;
      ao.abs_tol = 0;
      ao.order = 2 * opt.adaptive_order + 1;
      ao.max_evals = opt.max_evals;
      er = adaptive<1, 1>(fr, boxes, ao);
      out.converged = out.converged && er.converged;
    }
    out.p_rep = er.value[0];
    err_rep = er.error[0];
    rep_evals = er.evals;
  }
  out.N = out.p_true / out.p_rep;
  out.error = std::abs(out.N) * (err_true / std::abs(out.p_true) + err_rep / std::abs(out.p_rep));
  out.evals = spec_evals + rep_evals;
  if (counters) {
    counters->specular += spec_evals + rep_evals;
    counters->rep_point += rep_evals;
  }
  return out;
}

}  // namespace lgp::datasets
