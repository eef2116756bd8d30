#include "lgp/datasets/dielectric.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

#include "half_vector.hpp"
#include "lgp/datasets/quadrature.hpp"

namespace lgp::datasets {

namespace {
using detail::kPi;

struct Frame {
  double cv, sv, alpha, eta;
  Visibility vis;
  double trans_scale;  // 1 (flux) or 1 / eta^2 (radiance)
};

// Reflection weight F G2 (v.h) / ((n.v)(n.h)) at h; 0 outside n.l > 0.
double reflWeight(const Frame& f, double ch, double sh, double phi) {
  const double vh = f.sv * sh * std::cos(phi) + f.cv * ch;
  const double nl = 2.0 * vh * ch - f.cv;
  if (nl <= 0.0 || vh <= 0.0 || ch <= 0.0) return 0.0;
  return fresnelDielectric(vh, f.eta) * g2OverNv(nl, f.cv, f.alpha, f.vis) * vh / ch;
}

// Transmission weight (1 - F) G2 (v.h) / ((n.v)(n.h)) at h, times the convention's scale.
double transWeight(const Frame& f, double ch, double sh, double phi) {
  const double vh = f.sv * sh * std::cos(phi) + f.cv * ch;
  if (vh <= 0.0 || ch <= 0.0) return 0.0;
  const double ct2 = cosTransmitted2(vh, f.eta);
  if (ct2 <= 0.0) return 0.0;  // total internal reflection (not reached for eta >= 1)
  const double nlt = f.cv / f.eta + (std::sqrt(ct2) - vh / f.eta) * ch;  // -(n.l_t)
  if (nlt <= 0.0) return 0.0;
  return (1.0 - fresnelDielectric(vh, f.eta)) * g2OverNv(nlt, f.cv, f.alpha, f.vis) * vh / ch *
         f.trans_scale;
}

// Polar angles where 1 - F(v.h) turns over near eta = 1: cos_t ~ sqrt(eta^2 - 1 + (v.h)^2)
// changes on the scale v.h ~ sqrt(eta^2 - 1) (exactly there when v = n).
std::vector<double> fresnelBreakpoints(double eta) {
  std::vector<double> th;
  const double m0 = std::sqrt(std::max(0.0, eta * eta - 1.0));
  if (m0 <= 0.0 || m0 >= 0.25) return th;
  for (int k = -3; k < 60; ++k) {
    const double c = std::ldexp(m0, k);
    if (c >= 1.0) break;
    th.push_back(std::acos(c));
  }
  return th;
}

template <class W>
Estimate<1> lobeIntegral(const Frame& f, detail::Lobe lobe, W weight, double tol,
                         const IntegratorOptions& opt) {
  const detail::HalfVectorDomain dom =
      detail::halfVectorDomain(lobe, f.cv, f.alpha, true, fresnelBreakpoints(f.eta));
  auto fg = [&](const std::array<double, 2>& p, std::array<double, 1>& o) {
    const detail::HalfVector h = detail::mapHalfVector(dom, p);
    if (h.jac <= 0.0) return;
    o[0] = weight(f, h.ch, h.sh, h.phi) * h.jac / kPi;
  };
  const std::span<const Box<2>> boxes(dom.boxes);
  if (opt.kind == IntegratorKind::Gauss) return gaussProduct<2, 1>(fg, boxes, opt.order);
  AdaptiveOptions ao;
  ao.abs_tol = tol;
  ao.order = opt.adaptive_order;
  ao.max_evals = opt.max_evals;
  return adaptive<2, 1>(fg, boxes, ao);
}

// eta = 1: no refraction, every h transmits straight on (l_t = -v), and
// E_trans = G2(v, -v) / (n.v) integral_{v.h > 0} D (v.h) dh = G2(v, -v) / G1(v) with the exact
// Smith G1(v) = 2 mu / (mu + S(mu)) (the normalisation of visible normals); written so that
// mu = 0 is its limit.
double transmissionAtEtaOne(double mu, double alpha, Visibility vis) {
  const double a2 = alpha * alpha;
  const double S = std::sqrt(a2 + (1.0 - a2) * mu * mu);
  switch (vis) {
    case Visibility::SmithCorrelated:  // (1 + Lambda) / (1 + 2 Lambda)
      return 0.5 * (1.0 + mu / S);
    case Visibility::SmithSeparable:  // G1(v)
      return 2.0 * mu / (mu + S);
    case Visibility::SchlickSmith: {  // G1s(v)^2 / G1(v)
      const double k = 0.5 * alpha, d = mu * (1.0 - k) + k;
      return mu * (mu + S) / (2.0 * d * d);
    }
  }
  return 0.0;
}

// Both lobes at once from (u, u2) over the whole unit square (an independent check of the
// partitions).
Estimate<2> qmcBoth(const Frame& f, const IntegratorOptions& opt) {
  const double a2 = f.alpha * f.alpha;
  auto fq = [&](const std::array<double, 2>& p, std::array<double, 2>& o) {
    double ch, sh;
    detail::thetaFromW(1.0 - p[0], a2, ch, sh);
    const double phi = 2.0 * kPi * p[1];
    o[0] = reflWeight(f, ch, sh, phi);
    o[1] = transWeight(f, ch, sh, phi);
  };
  QmcOptions q;
  q.points = opt.qmc_points;
  q.shifts = opt.qmc_shifts;
  return qmc<2, 2>(fq, q);
}
}  // namespace

DielectricValue dielectricPoint(double mu, double alpha, double eta, Visibility vis,
                                Transmission tr, bool want_refl, bool want_trans,
                                const IntegratorOptions& opt, Counters* counters) {
  DielectricValue out;
  mu = std::clamp(mu, 0.0, 1.0);
  const double scale = tr == Transmission::Radiance ? 1.0 / (eta * eta) : 1.0;
  if (alpha <= 0.0) {  // a smooth interface
    const double F = fresnelDielectric(mu, eta);
    out.refl = want_refl ? F : 0.0;
    out.trans = want_trans ? (1.0 - F) * scale : 0.0;
    return out;
  }
  if (eta == 1.0) {  // F = 0: a closed form (and mu = 0 its limit)
    out.trans = want_trans ? transmissionAtEtaOne(mu, alpha, vis) : 0.0;
    out.err_trans = want_trans ? kRoundoff : 0.0;
    return out;
  }
  const Frame f{mu, std::sqrt(std::max(0.0, 1.0 - mu * mu)), alpha, eta, vis, scale};
  if (opt.kind == IntegratorKind::Qmc) {
    const Estimate<2> e = qmcBoth(f, opt);
    out.refl = want_refl ? e.value[0] : 0.0;
    out.trans = want_trans ? e.value[1] : 0.0;
    out.err_refl = want_refl ? e.error[0] : 0.0;
    out.err_trans = want_trans ? e.error[1] : 0.0;
    out.evals = e.evals;
  } else {
    // Each lobe to its share of the tolerance, so that E_dielectric keeps it too.
    const double tol = want_refl && want_trans ? 0.5 * opt.abs_tol : opt.abs_tol;
    auto lobe = [&](detail::Lobe which, double (*w)(const Frame&, double, double, double),
                    double& value, double& error) {
      const Estimate<1> e = lobeIntegral(f, which, w, tol, opt);
      value = e.value[0];
      error = e.error[0];
      out.evals += e.evals;
      out.converged = out.converged && e.converged;
    };
    if (want_refl) lobe(detail::Lobe::Reflection, reflWeight, out.refl, out.err_refl);
    if (want_trans) lobe(detail::Lobe::Transmission, transWeight, out.trans, out.err_trans);
  }
  if (counters) counters->dielectric += out.evals;
  return out;
}

FavgValue fresnelAverageDielectric(double eta, const IntegratorOptions& opt, Counters* counters) {
  FavgValue out;
  if (eta == 1.0) return out;  // no interface: F = 0
  // Below the critical cosine (eta < 1) F = 1: that part is mu_c^2 exactly.
  const double mc = eta < 1.0 ? std::sqrt(1.0 - eta * eta) : 0.0;
  auto f = [&](const std::array<double, 1>& p, std::array<double, 1>& o) {
    const double t = p[0];
    const double mu = mc + (1.0 - mc) * t * t;
    o[0] = 2.0 * fresnelDielectric(mu, eta) * mu * 2.0 * (1.0 - mc) * t;
  };
  // F turns over where mu - mu_c ~ sqrt(|1 - 1/eta^2|) (the scale of cos_t at grazing).
  const double m0 = std::sqrt(std::abs(1.0 - 1.0 / (eta * eta)));
  std::vector<double> cuts = {0.0, 1.0};
  for (int k = -6; k < 60; ++k) {
    const double d = std::ldexp(m0, k) / (1.0 - mc);
    if (d >= 1.0) break;
    if (d > 1e-12) cuts.push_back(std::sqrt(d));
  }
  std::sort(cuts.begin(), cuts.end());
  std::vector<Box<1>> parts;
  for (size_t i = 0; i + 1 < cuts.size(); ++i)
    if (cuts[i + 1] > cuts[i]) parts.push_back({{cuts[i]}, {cuts[i + 1]}});
  AdaptiveOptions ao;
  ao.abs_tol = opt.abs_tol;
  ao.order = 2 * opt.adaptive_order + 1;
  ao.max_evals = opt.max_evals;
  const Estimate<1> e = adaptive<1, 1>(f, std::span<const Box<1>>(parts), ao);
  out.value = mc * mc + e.value[0];
  out.error = e.error[0];
  out.evals = e.evals;
  out.converged = e.converged;
  if (counters) counters->dielectric += e.evals;
  return out;
}

}  // namespace lgp::datasets
