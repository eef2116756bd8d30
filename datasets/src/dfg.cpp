#include "lgp/datasets/dfg.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

#include "half_vector.hpp"
#include "lgp/datasets/quadrature.hpp"

namespace lgp::datasets {

namespace {
using detail::kPi;

// Half-vector weight W = G2 (v.h) / ((n.v)(n.h)) and the Fresnel weight, for h given by
// (cos theta_h, sin theta_h, phi). Returns false below the horizon.
struct Frame {
  double cv, sv, alpha;
  Visibility vis;
};

inline bool weight(const Frame& f, double ch, double sh, double phi, double& w, double& fc) {
  const double vh = f.sv * sh * std::cos(phi) + f.cv * ch;
  const double nl = 2.0 * vh * ch - f.cv;
  if (nl <= 0.0 || vh <= 0.0 || ch <= 0.0) return false;
  w = g2OverNv(nl, f.cv, f.alpha, f.vis) * vh / ch;
  fc = schlickWeight(vh);
  return true;
}

// The QMC estimate: (u, u2) over the whole unit square, the n.l <= 0 part contributing zero
// (an independent check of the partition the deterministic rules use).
Estimate<2> dfgQmc(const Frame& f, bool split, const IntegratorOptions& opt) {
  const double a2 = f.alpha * f.alpha;
  auto fq = [&](const std::array<double, 2>& p, std::array<double, 2>& o) {
    double ch, sh, w, fc;
    detail::thetaFromW(1.0 - p[0], a2, ch, sh);
    if (!weight(f, ch, sh, 2.0 * kPi * p[1], w, fc)) return;
    o[0] = split ? w * (1.0 - fc) : w;
    o[1] = split ? w * fc : 0.0;
  };
  QmcOptions q;
  q.points = opt.qmc_points;
  q.shifts = opt.qmc_shifts;
  return qmc<2, 2>(fq, q);
}

// Gauss or adaptive over the reflection domain's partition (half_vector.hpp).
Estimate<2> dfgRules(const Frame& f, double mu, bool split, const IntegratorOptions& opt) {
  const detail::HalfVectorDomain dom =
      detail::halfVectorDomain(detail::Lobe::Reflection, mu, f.alpha);
  auto fg = [&](const std::array<double, 2>& p, std::array<double, 2>& o) {
    const detail::HalfVector h = detail::mapHalfVector(dom, p);
    double w, fc;
    if (h.jac <= 0.0 || !weight(f, h.ch, h.sh, h.phi, w, fc)) return;
    w *= h.jac / kPi;
    o[0] = split ? w * (1.0 - fc) : w;
    o[1] = split ? w * fc : 0.0;
  };
  const std::span<const Box<2>> boxes(dom.boxes);
  if (opt.kind == IntegratorKind::Gauss) return gaussProduct<2, 2>(fg, boxes, opt.order);
  AdaptiveOptions ao;
  ao.abs_tol = opt.abs_tol;
  ao.order = opt.adaptive_order;
  ao.max_evals = opt.max_evals;
  return adaptive<2, 2>(fg, boxes, ao);
}
}  // namespace

DfgValue dfgPoint(double mu, double alpha, Visibility vis, bool split, const IntegratorOptions& opt,
                  Counters* counters) {
  DfgValue out;
  mu = std::clamp(mu, 0.0, 1.0);
  if (alpha <= 0.0) {  // mirror limit at fixed mu
    const double fc = schlickWeight(mu);
    out.E = 1.0;
    if (split) {
      out.A = 1.0 - fc;
      out.B = fc;
    }
    return out;
  }
  const Frame f{mu, std::sqrt(std::max(0.0, 1.0 - mu * mu)), alpha, vis};
  const Estimate<2> e =
      opt.kind == IntegratorKind::Qmc ? dfgQmc(f, split, opt) : dfgRules(f, mu, split, opt);
  if (split) {
    out.A = e.value[0];
    out.B = e.value[1];
    out.err_A = e.error[0];
    out.err_B = e.error[1];
    out.E = out.A + out.B;
    out.err_E = e.error[0] + e.error[1];
  } else {
    out.E = e.value[0];
    out.err_E = e.error[0];
  }
  out.evals = e.evals;
  out.converged = e.converged;
  if (counters) {
    counters->specular += e.evals;
    if (split) counters->fresnel += e.evals;
  }
  return out;
}

}  // namespace lgp::datasets
