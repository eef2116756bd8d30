// Independent high-precision references for the ground-truth generators (tests only).
//
// Nothing here calls the generators' code: the BRDF terms are written again from their
// definitions (GGX: Walter et al. 2007; height-correlated Smith G2 in its Lambda form: Heitz
// 2014; split sum: Karis 2013; Disney diffuse: Burley 2012), in long double, and the
// integrals use other variables and another method than the generators:
//   * quadrature: globally adaptive Gauss-Kronrod (G7-K15 or G10-K21, the QUADPACK pairs;
//     Piessens et al. 1983) in one dimension, nested for two or three; the error of an
//     interval is |K - G|, and the interval with the largest error is bisected until the
//     summed error is below the tolerance. The starting partitions are graded geometrically
//     towards every point where the integrand has a kink or a boundary layer (ratio 2 down to
//     2^-kGradeLevels for dfg and P_rep, ratio 4 from alpha / 16 for E_avg), so no feature of any
//     width is stepped over whatever alpha is.
//   * dfg: over the half vector in plain spherical coordinates (theta_h, phi), not in the GGX
//     CDF: E = int_0^{pi/2} dtheta_h sin(theta_h) D(theta_h) int dphi G2 (v.h) / (n.v),
//     phi over [0, phi_max(theta_h)] doubled, with D and G2 = 1 / (1 + Lambda(v) + Lambda(l))
//     written out.
//   * E_avg: bidirectionally, over h and then v around h, without ever forming E(mu) (the
//     generator integrates E(mu) over sqrt(mu)).
//   * normalization: P_true over the light's polar angle theta (not over mu) with the dfg
//     reference for E, and P_rep over theta_v with the representative point computed as an
//     angle in the plane of n and v (not with 3-D vectors).
//   * zh: exactly. With baseColor = 1 the cosine-weighted Disney lobe times 1, x, z, xx, xz, zz
//     is a polynomial in (x, z) = (l.x, l.z), and int_H x^a z^c dl = Gamma((a+1)/2)
//     Gamma(1/2) Gamma((c+1)/2) / Gamma((a+c+3)/2) for even a (0 for odd a). M0 is the Burley
//     directional albedo.
//   * sheen: over the half vector in (theta_h, phi) (the generator integrates over l), with the
//     region n.l > 0 of dfg and the Charlie D and Neubelt-Pettineo visibility written out.
//   * dielectric: both lobes over the half vector in (theta_h, phi) (the generator uses the GGX
//     CDF with smoothstep maps), the exact Fresnel and refraction written out.
//   * F_avg: over the polar angle theta in long double, graded towards the critical angle and
//     grazing (the generator integrates in t with mu = mu_c + (1 - mu_c) t^2).
// A reference is trusted only where it is shown converged: two different rules (K15 and K21),
// each to its own tolerance, agree to far below the tolerance under test, or (where the
// second rule costs too much) its own K - G estimate is; reference_test.cpp checks that.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <utility>
#include <vector>

namespace ref {

using R = long double;
constexpr R kPi = std::numbers::pi_v<R>;

// Gauss-Kronrod pairs on [-1, 1]: Kronrod abscissae xk (descending, the last one 0), weights
// wk; the Gauss nodes are xk[1], xk[3], ... with weights wg (the centre too for G7).
struct GkRule {
  int nk;  // Kronrod abscissae listed (positive ones and 0)
  const R* xk;
  const R* wk;
  const R* wg;
  bool gauss_centre;  // 0 is a Gauss node (odd Gauss order)
};

inline const GkRule& gk15() {
  static const R xk[8] = {
      0.991455371120812639206854697526329L, 0.949107912342758524526189684047851L,
      0.864864423359769072789712788640926L, 0.741531185599394439863864773280788L,
      0.586087235467691130294144845693013L, 0.405845151377397166906606412076961L,
      0.207784955007898467600689403773245L, 0.0L};
  static const R wk[8] = {
      0.022935322010529224963732008058970L, 0.063092092629978553290700663189204L,
      0.104790010322250183839876322541518L, 0.140653259715525918745189590510238L,
      0.169004726639267902826583426598550L, 0.190350578064785409913256402421014L,
      0.204432940075298892414161999234649L, 0.209482141084727828012999174891714L};
  static const R wg[4] = {
      0.129484966168869693270611432679082L, 0.279705391489276667901467771423780L,
      0.381830050505118944950369775488975L, 0.417959183673469387755102040816327L};
  static const GkRule r{8, xk, wk, wg, true};
  return r;
}

inline const GkRule& gk21() {
  static const R xk[11] = {0.995657163025808080735527280689003L,
                           0.973906528517171720077964012084452L,
                           0.930157491355708226001207180059508L,
                           0.865063366688984510732096688423493L,
                           0.780817726586416897063717578345042L,
                           0.679409568299024406234327365114874L,
                           0.562757134668604683339000099272694L,
                           0.433395394129247190799265943165784L,
                           0.294392862701460198131126603103866L,
                           0.148874338981631210884826001129720L,
                           0.0L};
  static const R wk[11] = {
      0.011694638867371874278064396062192L, 0.032558162307964727478818972459390L,
      0.054755896574351996031381300244580L, 0.075039674810919952767043140916190L,
      0.093125454583697605535065465083366L, 0.109387158802297641899210590325805L,
      0.123491976262065851077208188491924L, 0.134709217311473325928054001771707L,
      0.142775938577060080797094273138717L, 0.147739104901338491374841515972068L,
      0.149445554002916905664936468389821L};
  static const R wg[5] = {
      0.066671344308688137593568809893332L, 0.149451349150580593145776339657697L,
      0.219086362515982043995534934228163L, 0.269266719309996355091226921569469L,
      0.295524224714752870173892994651338L};
  static const GkRule r{11, xk, wk, wg, false};
  return r;
}

template <int K>
using Vec = std::array<R, K>;

template <int K>
struct Result {
  Vec<K> value{};
  R error = 0;  // max over components of the summed |K - G|
  uint64_t evals = 0;
  bool converged = true;
};

// One Kronrod/Gauss pair on [a, b]; f(x, out) fills out (zeroed before the call).
template <int K, class F>
void gkInterval(const F& f, R a, R b, const GkRule& g, Vec<K>& kr, Vec<K>& ga, uint64_t& evals) {
  const R c = 0.5L * (a + b), h = 0.5L * (b - a);
  kr.fill(0);
  ga.fill(0);
  Vec<K> o{};
  for (int i = 0; i < g.nk; ++i) {
    const bool is_gauss = (i % 2 == 1) || (i == g.nk - 1 && g.gauss_centre);
    const R wg = is_gauss ? g.wg[i / 2] : 0;
    const int sides = g.xk[i] == 0 ? 1 : 2;
    for (int s = 0; s < sides; ++s) {
      const R x = s == 0 ? c + h * g.xk[i] : c - h * g.xk[i];
      o.fill(0);
      f(x, o);
      ++evals;
      for (int k = 0; k < K; ++k) {
        kr[k] += g.wk[i] * o[k];
        ga[k] += wg * o[k];
      }
    }
  }
  for (int k = 0; k < K; ++k) {
    kr[k] *= h;
    ga[k] *= h;
  }
}

// Globally adaptive Gauss-Kronrod over [breaks.front(), breaks.back()], starting from the
// partition `breaks` (sorted here; repeated points dropped). Stops when the summed error is
// <= max(abs_tol, rel_tol * |value|) for every component, or after max_intervals.
template <int K, class F>
Result<K> adaptiveGk(const F& f, std::vector<R> breaks, R abs_tol, R rel_tol, const GkRule& g,
                     int max_intervals = 20000) {
  struct Iv {
    R a, b, prio;
    Vec<K> kr, err;
  };
  Result<K> res;
  std::sort(breaks.begin(), breaks.end());
  breaks.erase(std::unique(breaks.begin(), breaks.end()), breaks.end());
  std::vector<Iv> heap;
  Vec<K> scale{};  // per-component tolerance, from the first pass
  auto prio = [&](Iv& iv) {
    iv.prio = 0;
    for (int k = 0; k < K; ++k) iv.prio = std::max(iv.prio, iv.err[k] / scale[k]);
  };
  auto make = [&](R a, R b) {
    Iv iv{a, b, 0, {}, {}};
    Vec<K> ga{};
    gkInterval<K>(f, a, b, g, iv.kr, ga, res.evals);
    for (int k = 0; k < K; ++k) iv.err[k] = std::abs(iv.kr[k] - ga[k]);
    return iv;
  };
  auto cmp = [](const Iv& x, const Iv& y) { return x.prio < y.prio; };
  for (size_t i = 0; i + 1 < breaks.size(); ++i) heap.push_back(make(breaks[i], breaks[i + 1]));
  auto totals = [&](Vec<K>& v, Vec<K>& e) {
    v.fill(0);
    e.fill(0);
    for (const auto& iv : heap)
      for (int k = 0; k < K; ++k) {
        v[k] += iv.kr[k];
        e[k] += iv.err[k];
      }
  };
  Vec<K> v{}, e{};
  totals(v, e);
  for (int k = 0; k < K; ++k)
    scale[k] = std::max({abs_tol, rel_tol * std::abs(v[k]), std::numeric_limits<R>::min()});
  for (auto& iv : heap) prio(iv);
  std::make_heap(heap.begin(), heap.end(), cmp);
  auto ok = [&]() {
    totals(v, e);
    for (int k = 0; k < K; ++k)
      if (e[k] > std::max(abs_tol, rel_tol * std::abs(v[k]))) return false;
    return true;
  };
  int iter = 0;
  while (!heap.empty()) {
    if (iter++ % 16 == 0 && ok()) break;
    if (static_cast<int>(heap.size()) >= max_intervals) {
      res.converged = false;
      break;
    }
    std::pop_heap(heap.begin(), heap.end(), cmp);
    const Iv worst = heap.back();
    heap.pop_back();
    const R m = 0.5L * (worst.a + worst.b);
    if (!(m > worst.a && m < worst.b)) {  // cannot split further: keep it as it is
      heap.push_back(worst);
      std::push_heap(heap.begin(), heap.end(), cmp);
      res.converged = false;
      break;
    }
    for (Iv iv : {make(worst.a, m), make(m, worst.b)}) {
      prio(iv);
      heap.push_back(iv);
      std::push_heap(heap.begin(), heap.end(), cmp);
    }
  }
  if (!ok()) res.converged = false;
  res.value = v;
  res.error = 0;
  for (int k = 0; k < K; ++k) res.error = std::max(res.error, e[k]);
  return res;
}

// Points p -/+ scale 2^-k (k = 1..levels) inside (lo, hi): grading towards a kink or a boundary
// layer at p.
inline constexpr int kGradeLevels = 32;  // 24 and 44 give the same dfg values to 1e-19
inline void gradeTowards(std::vector<R>& b, R p, R lo, R hi, R scale = 1) {
  b.push_back(std::clamp(p, lo, hi));
  for (int k = 1; k <= kGradeLevels; ++k) {
    const R d = std::ldexp(scale, -k);
    if (p - d > lo && p - d < hi) b.push_back(p - d);
    if (p + d > lo && p + d < hi) b.push_back(p + d);
  }
}

// ---------------------------------------------------------------- microfacet terms
// GGX D(theta_h) with the denominator written as sin^2 + alpha^2 cos^2 (no cancellation).
inline R ggxD(R ch, R sh, R alpha) {
  const R a2 = alpha * alpha;
  const R d = sh * sh + a2 * ch * ch;
  return a2 / (kPi * d * d);
}
// Smith Lambda for GGX, Lambda(x) = (sqrt(1 + alpha^2 tan^2) - 1) / 2 (Heitz 2014).
inline R lambda(R c, R alpha) {
  const R t2 = (1 - c * c) / (c * c);
  return 0.5L * (std::sqrt(1 + alpha * alpha * t2) - 1);
}
inline R g1Schlick(R c, R alpha) {
  const R k = 0.5L * alpha;
  return c / (c * (1 - k) + k);
}
// G2 for the height-correlated Smith form, or the separable Schlick-Smith product.
inline R g2(R nl, R nv, R alpha, bool separable) {
  if (nl <= 0 || nv <= 0) return 0;
  if (separable) return g1Schlick(nl, alpha) * g1Schlick(nv, alpha);
  return 1 / (1 + lambda(nv, alpha) + lambda(nl, alpha));
}
inline R fresnelWeight(R vh) {
  const R m = 1 - vh;
  return m * m * m * m * m;
}

// int over theta_h (starting partition `breaks`) of int_0^{phimax(theta_h)} w dphi, the inner
// integral graded towards phimax. `make(theta_h)` returns {phimax, w(phi, out)}: what depends on
// theta_h alone is computed once per outer node.
template <int K, class Make>
Result<K> overHalfVectors(std::vector<R> breaks, Make make, R tol, const GkRule& g) {
  uint64_t inner_evals = 0;
  bool inner_ok = true;
  auto outer = [&](R th, Vec<K>& o) {
    auto [phimax, inner] = make(th);
    if (phimax <= 0) return;
    std::vector<R> b = {0};
    gradeTowards(b, phimax, 0, phimax, phimax);
    auto r = adaptiveGk<K>(inner, b, 1e-3L * tol, 1e-16L, g);
    inner_evals += r.evals;
    inner_ok = inner_ok && r.converged;
    o = r.value;
  };
  auto r = adaptiveGk<K>(outer, std::move(breaks), tol, 0, g);
  r.evals += inner_evals;
  r.converged = r.converged && inner_ok;
  return r;
}

// Breakpoints in theta_h for a GGX lobe on [0, thB] whose full circle ends at thA: alpha 2^k (the
// D peak, of any width) and graded towards thA and thB.
inline std::vector<R> ggxBreaks(R alpha, R thA, R thB) {
  std::vector<R> b = {0, thB};
  for (int k = -8; k < 60; ++k) {
    const R x = std::ldexp(alpha, k);
    if (x >= thB) break;
    b.push_back(x);
  }
  if (thA > 0 && thA < thB) gradeTowards(b, thA, 0, thB);
  gradeTowards(b, thB, 0, thB);
  return b;
}

// phi_max of the reflection region n.l > 0: n.l = 2 (v.h)(n.h) - n.v = 0, v.h = sv sh cos + cv ch.
inline R reflectionPhiMax(R cv, R sv, R ch, R sh) {
  if (sv * sh > 0) {
    const R c0 = (cv / (2 * ch) - cv * ch) / (sv * sh);
    return c0 <= -1 ? kPi : (c0 >= 1 ? 0 : std::acos(c0));
  }
  return 2 * ch * ch - 1 <= 0 ? 0 : kPi;
}

struct Dfg {
  R A = 0, B = 0, E = 0;  // E = A + B
  R error = 0;            // the adaptive rule's own summed |K - G| (max of A, B)
  uint64_t evals = 0;
  bool converged = true;
};

// E, A, B at view cosine mu in (0, 1] and alpha > 0, over (theta_h, phi).
inline Dfg dfg(R mu, R alpha, bool separable, R tol, const GkRule& g) {
  const R cv = mu, sv = std::sqrt(std::max<R>(0, 1 - mu * mu));
  const R theta_v = std::acos(mu);
  const R th1 = std::max<R>(0, kPi / 4 - theta_v / 2);        // n.l > 0 for every phi below
  const R th2 = std::min<R>(kPi / 2, kPi / 4 + theta_v / 2);  // for no phi above
  auto make = [&](R th) {
    const R ch = std::cos(th), sh = std::sin(th);
    const R dsin = ggxD(ch, sh, alpha) * sh;
    auto inner = [=](R phi, Vec<2>& w) {
      const R vh = sv * sh * std::cos(phi) + cv * ch;
      const R nl = 2 * vh * ch - cv;
      if (nl <= 0 || vh <= 0) return;
      const R x = 2 * dsin * g2(nl, cv, alpha, separable) * vh / cv;  // x2: phi in [0, pi]
      const R fc = fresnelWeight(vh);
      w[0] = x * (1 - fc);
      w[1] = x * fc;
    };
    return std::make_pair(reflectionPhiMax(cv, sv, ch, sh), inner);
  };
  auto r = overHalfVectors<2>(ggxBreaks(alpha, th1, th2), make, tol, g);
  Dfg d;
  d.A = r.value[0];
  d.B = r.value[1];
  d.E = d.A + d.B;
  d.error = r.error;
  d.evals = r.evals;
  d.converged = r.converged;
  return d;
}

// ---------------------------------------------------------------- E_avg, bidirectionally
// E_avg = 2 int_0^1 E(mu) mu dmu = (1/pi) int_H dv (n.v) E(v), and with E(v) written over h
// and the order swapped, without any E(mu):
//   E_avg = (1/pi) int_{n.h > 0} dh D(h) int_{v.h > 0} dv G2(l, v) (v.h) [n.v > 0, n.l > 0].
// Around h (at theta_h from n), v = (theta', phi') and l = its mirror image: v.h = cos theta',
// n.v = cos theta_h cos theta' - sin theta_h sin theta' cos phi', n.l the same with + cos phi'.
// Both are positive where |cos phi'| < c = cot(theta_h) cot(theta'). By the symmetries
// phi' -> -phi' and phi' -> pi - phi' (which swaps v and l; G2 is symmetric)
//   E_avg = 8 int dtheta_h sin D int dtheta' sin cos int_{acos min(c, 1)}^{pi/2} G2 dphi'.
struct Eavg {
  R value = 0, error = 0;
  uint64_t evals = 0;
  bool converged = true;
};
// The starting partitions are graded by factors of 4 at the scale alpha (the width of the G2
// layers in n.v, and of the D peak in theta_h) towards every edge where n.v or n.l -> 0.
inline void gradeAlpha(std::vector<R>& b, R p, R lo, R hi, R alpha, int dir) {
  b.push_back(p);
  for (R d = alpha / 16; d < hi - lo; d *= 4) {
    const R x = p + dir * d;
    if (x > lo && x < hi) b.push_back(x);
  }
}
inline Eavg eAvg(R alpha, R tol, const GkRule& g) {
  Eavg out;
  uint64_t evals = 0;
  bool ok = true;
  auto outer = [&](R th, Vec<1>& o) {
    const R ch = std::cos(th), sh = std::sin(th);
    auto middle = [&](R tp, Vec<1>& m) {
      const R ct = std::cos(tp), st = std::sin(tp);
      const R c = (ch * ct) / (sh * st);  // cot cot
      const R phi0 = c >= 1 ? 0 : std::acos(c);
      auto inner = [&](R p, Vec<1>& w) {
        const R s2 = std::sin(p / 2);  // n.v without cancellation near phi' = 0
        const R nv = std::cos(th + tp) + 2 * sh * st * s2 * s2;
        const R nl = ch * ct + sh * st * std::cos(p);
        w[0] = g2(nl, nv, alpha, false);
      };
      // breakpoints where n.v = n.v(phi_lo) + alpha 4^k / 16: the G2 layer in n.v
      std::vector<R> b = {phi0, kPi / 2};
      const R nv0 = std::max<R>(0, std::cos(th + tp));
      if (phi0 > 0 || nv0 < 64 * alpha)
        for (R dv = alpha / 16; dv < ch * ct; dv *= 4) {
          const R cp = (ch * ct - ((phi0 > 0 ? 0 : nv0) + dv)) / (sh * st);
          if (cp > -1 && cp < 1) {
            const R p = std::acos(cp);
            if (p > phi0 && p < kPi / 2) b.push_back(p);
          }
        }
      auto r = adaptiveGk<1>(inner, b, 1e-2L * tol, 0, g);
      evals += r.evals;
      ok = ok && r.converged;
      m[0] = st * ct * r.value[0];
    };
    std::vector<R> b = {0, kPi / 2};
    const R edge = kPi / 2 - th;  // c = 1 there
    if (edge > 0 && edge < kPi / 2) {
      gradeAlpha(b, edge, 0, kPi / 2, alpha, -1);
      gradeAlpha(b, edge, 0, kPi / 2, alpha, +1);
    }
    gradeAlpha(b, kPi / 2, 0, kPi / 2, alpha, -1);
    auto r = adaptiveGk<1>(middle, b, 1e-2L * tol, 0, g);
    ok = ok && r.converged;
    o[0] = 8 * sh * ggxD(ch, sh, alpha) * r.value[0];
  };
  std::vector<R> b = {0, kPi / 2};
  gradeAlpha(b, 0, 0, kPi / 2, alpha, +1);
  gradeAlpha(b, kPi / 2, 0, kPi / 2, alpha, -1);
  auto r = adaptiveGk<1>(outer, b, tol, 0, g);
  out.value = r.value[0];
  out.error = r.error;
  out.evals = r.evals + evals;
  out.converged = r.converged && ok;
  return out;
}

// ---------------------------------------------------------------- normalization
struct Norm {
  R N = 1, p_true = 0, p_rep = 0, error_true = 0, error_rep = 0;
  bool converged = true;
};

// P_true / sin^2 = 2 pi / sin^2(ts) int_0^ts E(cos theta) cos sin dtheta, E from dfg().
inline R pTrue(R alpha, R theta_s, R tol, const GkRule& g, R& err, bool& ok) {
  const R s2 = std::sin(theta_s) * std::sin(theta_s);
  auto f = [&](R th, Vec<1>& o) {
    const Dfg e = dfg(std::cos(th), alpha, false, 0.01L * tol, g);
    ok = ok && e.converged;
    o[0] = 2 * kPi * e.E * std::cos(th) * std::sin(th) / s2;
  };
  auto r = adaptiveGk<1>(f, {0, theta_s}, 0, tol, g);
  err = r.error;
  ok = ok && r.converged;
  return r.value[0];
}

// P_rep / sin^2 = pi 2 pi int_0^{pi/2} f(l_rep, v) (n.l_rep) cos(theta_v) sin(theta_v) dtheta_v
// with c = n: in the plane of n and v, the reflection r is at -theta_v from n, |centerToRay| =
// sin(theta_v), and l_rep = (1 - t) n + t cos(theta_v) r, t = (1 + (|ctr| / R)^-s)^(1/s), at
// the angle -psi from n; the half vector is at (theta_v - psi) / 2 from n.
inline R pRep(R alpha, R theta_s, R softmin_s, R tol, const GkRule& g, R& err, bool& ok) {
  const R radius = std::sin(theta_s);
  auto f = [&](R tv, Vec<1>& o) {
    const R len = std::sin(tv), cvv = std::cos(tv);
    const R t = std::pow(1 + std::pow(len / radius, -softmin_s), 1 / softmin_s);
    const R psi = std::atan2(t * cvv * len, (1 - t) + t * cvv * cvv);
    const R th = 0.5L * (tv - psi);
    const R nl = std::cos(psi);
    // f (n.l) (n.v) sin = D G2 / (4 nv) nv sin
    o[0] = 2 * kPi * kPi * ggxD(std::cos(th), std::sin(th), alpha) * g2(nl, cvv, alpha, false) *
           len / 4;
  };
  // graded towards theta_v = 0 (the lobe, of any width) and towards the horizon (G2 drops to
  // 0 within ~alpha of n.v = 0)
  std::vector<R> b = {0, kPi / 2};
  for (int k = 1; k < 64; ++k) b.push_back(std::ldexp(kPi / 2, -k));
  gradeTowards(b, kPi / 2, 0, kPi / 2, kPi / 2);
  auto r = adaptiveGk<1>(f, b, 0, tol, g);
  err = r.error;
  ok = ok && r.converged;
  return r.value[0];
}

inline Norm normalization(R alpha, R theta_s, R softmin_s, R tol, const GkRule& g) {
  Norm n;
  n.p_true = pTrue(alpha, theta_s, tol, g, n.error_true, n.converged);
  n.p_rep = pRep(alpha, theta_s, softmin_s, tol, g, n.error_rep, n.converged);
  n.N = n.p_true / n.p_rep;
  return n;
}

// ---------------------------------------------------------------- sheen
// Charlie D (Estevez and Kulla 2017) from theta_h.
inline R charlieD(R sh, R alpha) {
  return (2 + 1 / alpha) * std::pow(sh, 1 / alpha) / (2 * kPi);
}

// E_sheen = int dh D(h) (n.l)(v.h) / (n.l + n.v - (n.l)(n.v)) over n.l > 0 (dl = 4 (v.h) dh).
inline Result<1> sheen(R mu, R alpha, R tol, const GkRule& g) {
  const R cv = mu, sv = std::sqrt(std::max<R>(0, 1 - mu * mu));
  const R theta_v = std::acos(mu);
  const R th1 = std::max<R>(0, kPi / 4 - theta_v / 2);
  const R th2 = std::min<R>(kPi / 2, kPi / 4 + theta_v / 2);
  auto make = [&](R th) {
    const R ch = std::cos(th), sh = std::sin(th);
    const R dsin = charlieD(sh, alpha) * sh;
    auto inner = [=](R phi, Vec<1>& w) {
      const R vh = sv * sh * std::cos(phi) + cv * ch;
      const R nl = 2 * vh * ch - cv;
      if (nl <= 0 || vh <= 0) return;
      w[0] = 2 * dsin * nl * vh / (nl + cv - nl * cv);  // x2: phi in [0, pi]
    };
    return std::make_pair(reflectionPhiMax(cv, sv, ch, sh), inner);
  };
  std::vector<R> b = {0, th2};
  if (th1 > 0 && th1 < th2) gradeTowards(b, th1, 0, th2);
  gradeTowards(b, th2, 0, th2, th2);
  return overHalfVectors<1>(b, make, tol, g);
}

// ---------------------------------------------------------------- dielectric
// Exact unpolarised Fresnel, relative index eta, incidence cosine c (Born and Wolf).
inline R fresnel(R c, R eta) {
  const R st2 = (1 - c * c) / (eta * eta);
  if (st2 >= 1) return 1;
  const R ct = std::sqrt(1 - st2);
  const R rs = (c - eta * ct) / (c + eta * ct), rp = (eta * c - ct) / (eta * c + ct);
  return (rs * rs + rp * rp) / 2;
}
// Exact Smith G1 = 1 / (1 + Lambda) (the separable form multiplies two).
inline R g1Smith(R c, R alpha) {
  return 1 / (1 + lambda(c, alpha));
}
enum class Vis { Correlated, Separable };
inline R g2Vis(R nl, R nv, R alpha, Vis vis) {
  if (nl <= 0 || nv <= 0) return 0;
  if (vis == Vis::Separable) return g1Smith(nl, alpha) * g1Smith(nv, alpha);
  return 1 / (1 + lambda(nv, alpha) + lambda(nl, alpha));
}

struct Dielectric {
  R refl = 0, trans = 0, error = 0;
  uint64_t evals = 0;
  bool converged = true;
};

// E_refl and E_trans (flux) at mu in (0, 1], alpha > 0, eta > 1, over (theta_h, phi):
//   E_refl  = int D G2(v, l_r) F(v.h) (v.h) / (n.v) dh over n.l_r > 0,
//   E_trans = int D G2(v, l_t) (1 - F(v.h)) (v.h) / (n.v) dh over v.h > 0 (n.l_t < 0 then).
inline Dielectric dielectric(R mu, R alpha, R eta, Vis vis, R tol, const GkRule& g) {
  const R cv = mu, sv = std::sqrt(std::max<R>(0, 1 - mu * mu));
  const R theta_v = std::acos(mu);
  Dielectric out;
  for (int lobe = 0; lobe < 2; ++lobe) {
    const R thA =
        lobe == 0 ? std::max<R>(0, kPi / 4 - theta_v / 2) : std::max<R>(0, kPi / 2 - theta_v);
    const R thB = lobe == 0 ? std::min<R>(kPi / 2, kPi / 4 + theta_v / 2) : kPi / 2;
    auto make = [&](R th) {
      const R ch = std::cos(th), sh = std::sin(th);
      R phimax = kPi;  // transmission: v.h > 0 where cos(phi) > -cot(theta_v) cot(theta_h)
      if (lobe == 0) {
        phimax = reflectionPhiMax(cv, sv, ch, sh);
      } else if (th > thA && sv * sh > 0) {
        const R c0 = -cv * ch / (sv * sh);
        phimax = c0 <= -1 ? kPi : (c0 >= 1 ? 0 : std::acos(c0));
      }
      const R dsin = ggxD(ch, sh, alpha) * sh;
      auto inner = [=](R phi, Vec<1>& w) {
        const R vh = sv * sh * std::cos(phi) + cv * ch;
        if (vh <= 0) return;
        const R F = fresnel(vh, eta);
        if (lobe == 0) {
          const R nl = 2 * vh * ch - cv;
          if (nl <= 0) return;
          w[0] = 2 * dsin * g2Vis(nl, cv, alpha, vis) * F * vh / cv;
        } else {
          const R ct = std::sqrt(1 - (1 - vh * vh) / (eta * eta));
          const R nlt = cv / eta + (ct - vh / eta) * ch;  // -(n.l_t)
          w[0] = 2 * dsin * g2Vis(nlt, cv, alpha, vis) * (1 - F) * vh / cv;
        }
      };
      return std::make_pair(phimax, inner);
    };
    auto r = overHalfVectors<1>(ggxBreaks(alpha, thA, thB), make, tol, g);
    (lobe == 0 ? out.refl : out.trans) = r.value[0];
    out.error = std::max(out.error, r.error);
    out.evals += r.evals;
    out.converged = out.converged && r.converged;
  }
  return out;
}

// F_avg = 2 int_0^{pi/2} F(cos theta) cos theta sin theta dtheta, graded towards the critical
// angle (eta < 1) and grazing incidence.
inline Result<1> fresnelAverage(R eta, R tol, const GkRule& g) {
  auto f = [&](R th, Vec<1>& o) {
    o[0] = 2 * fresnel(std::cos(th), eta) * std::cos(th) * std::sin(th);
  };
  std::vector<R> b = {0, kPi / 2};
  if (eta < 1) gradeTowards(b, std::asin(eta), 0, kPi / 2);
  gradeTowards(b, kPi / 2, 0, kPi / 2);
  return adaptiveGk<1>(f, b, tol, 0, g);
}

// ---------------------------------------------------------------- zh, exactly
// Polynomials in (x, z) with coefficients c[a][c] for x^a z^c, degree < 16 in each.
struct Poly {
  static constexpr int N = 16;
  std::array<std::array<R, N>, N> c{};
};
inline Poly mul(const Poly& p, const Poly& q) {
  Poly r;
  for (int a = 0; a < Poly::N; ++a)
    for (int b = 0; b < Poly::N; ++b) {
      if (p.c[a][b] == 0) continue;
      for (int e = 0; a + e < Poly::N; ++e)
        for (int f = 0; b + f < Poly::N; ++f) r.c[a + e][b + f] += p.c[a][b] * q.c[e][f];
    }
  return r;
}
inline Poly constant(R v) {
  Poly p;
  p.c[0][0] = v;
  return p;
}
// int over the upper hemisphere of x^a z^c
inline R hemiMonomial(int a, int c) {
  if (a % 2) return 0;
  return std::tgamma(R(a + 1) / 2) * std::tgamma(R(0.5)) * std::tgamma(R(c + 1) / 2) /
         std::tgamma(R(a + c + 3) / 2);
}
inline R integrate(const Poly& p) {
  R s = 0;
  for (int a = 0; a < Poly::N; ++a)
    for (int c = 0; c < Poly::N; ++c)
      if (p.c[a][c] != 0) s += p.c[a][c] * hemiMonomial(a, c);
  return s;
}

struct Zh {
  R zh0, zh1, zh2, ratio1, ratio2, beta;
};

// Moments M0, mx, mz, Mxx, Mxz, Mzz of CBRDF at view angle theta_v (v = (sin, 0, cos)).
inline std::array<R, 6> zhMoments(R theta_v, R r, bool lambert) {
  const R mu = std::cos(theta_v), sv = std::sin(theta_v);
  Poly x, z;
  x.c[1][0] = 1;
  z.c[0][1] = 1;
  Poly cb;  // CBRDF
  if (lambert) {
    cb = z;
    cb.c[0][1] = 1 / kPi;
  } else {
    Poly q;  // F_D90 - 1 = -1/2 + r (1 + l.v)
    q.c[0][0] = -0.5L + r;
    q.c[1][0] = r * sv;
    q.c[0][1] = r * mu;
    Poly omz = constant(1);  // (1 - z)
    omz.c[0][1] = -1;
    Poly p5 = constant(1);
    for (int i = 0; i < 5; ++i) p5 = mul(p5, omz);
    const R m = 1 - mu;
    const R v5 = m * m * m * m * m;
    Poly left = mul(q, p5);
    left.c[0][0] += 1;
    Poly right = q;
    for (auto& row : right.c)
      for (auto& v : row) v *= v5;
    right.c[0][0] += 1;
    cb = mul(mul(left, right), z);
    for (auto& row : cb.c)
      for (auto& v : row) v /= kPi;
  }
  return {integrate(cb),
          integrate(mul(cb, x)),
          integrate(mul(cb, z)),
          integrate(mul(mul(cb, x), x)),
          integrate(mul(mul(cb, x), z)),
          integrate(mul(mul(cb, z), z))};
}

inline Zh zhFromMoments(const std::array<R, 6>& m, R mu, R sv) {
  constexpr R y00 = 0.28209479177387814347403972578L;  // 1 / (2 sqrt(pi))
  constexpr R y10 = 0.48860251190291992158638462284L;  // sqrt(3 / (4 pi))
  constexpr R y20 = 0.31539156525252000603089369029L;  // sqrt(5 / (16 pi))
  Zh z{};
  const R len = std::hypot(m[1], m[2]);
  const R dx = m[1] / len, dz = m[2] / len;
  z.zh0 = y00 * m[0];
  z.zh1 = y10 * len;
  z.zh2 = y20 * (3 * (dx * dx * m[3] + 2 * dx * dz * m[4] + dz * dz * m[5]) - m[0]);
  z.ratio1 = z.zh1 / z.zh0;
  z.ratio2 = z.zh2 / z.zh0;
  const R k = m[1] / m[2];
  z.beta = sv > 0 ? k / (sv + k * (1 - mu)) : 0;
  return z;
}

// mu = 1: beta is the limit theta_v -> 0 of k / (sin + k (1 - cos)); k = O(theta_v), so at
// theta_v = 1e-7 the remainder is O(1e-14).
inline Zh zh(R mu, R r, bool lambert) {
  const R tv = std::acos(std::clamp<R>(mu, 0, 1));
  Zh z = zhFromMoments(zhMoments(tv, r, lambert), mu, std::sin(tv));
  if (tv < 1e-7L) {
    const R t = 1e-7L;
    z.beta = zhFromMoments(zhMoments(t, r, lambert), std::cos(t), std::sin(t)).beta;
  }
  return z;
}

}  // namespace ref
