// Integration over GGX half vectors, shared by dfg (reflection) and dielectric (reflection and
// transmission). Private to the datasets library.
//
// A half vector h at polar angle theta_h is addressed by the GGX CDF variable
// w = 1 - u = alpha^2 / (alpha^2 + tan^2 theta_h), which absorbs D (n.h) and keeps its
// precision where the lobe is sharp, and by an azimuth phi in [0, pi] (the configuration is
// mirror-symmetric). A lobe's domain in h is a full circle below theta_A and a partial circle
// |phi| < phi_max(theta_h) between theta_A and theta_B:
//   reflection (n.l > 0):  theta_A = pi/4 - theta_v/2, theta_B = pi/4 + theta_v/2,
//                          cos phi_max = -cot(theta_v) cot(2 theta_h);
//   transmission (v.h > 0, eta >= 1 keeps n.l < 0): theta_A = pi/2 - theta_v, theta_B = pi/2,
//                          cos phi_max = -cot(theta_v) cot(theta_h).
// The unit square [0, 2] x [0, 1] maps onto it: x in [0, 1] is the full-circle piece (w linear
// in x, phi = pi y), x in [1, 2] the partial piece (w smoothstep in x, which removes the
// square-root behaviour of phi_max at both ends, phi = phi_max y). With `smooth_full` the
// full-circle piece is a smoothstep in x too: near theta_h = 0 the integrand of polar
// coordinates holds terms in sqrt(u) cos(phi) (u ~ theta_h^2), and a transmission lobe's full
// piece can end at w = 0 (mu -> 1), where cos theta_h ~ sqrt(w); both become smooth in x (dfg
// keeps the linear map, which its tables were made with). The starting partition has
// geometric breakpoints where the integrand changes on a scale far below the square's: within
// min(alpha, n.v) 2^k of the piece edges (in theta_h, and in phi near phi_max), and at
// theta_h = alpha 2^k in the full-circle piece (docs/tables.md, "dfg").
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <vector>

#include "lgp/datasets/quadrature.hpp"

namespace lgp::datasets::detail {

inline constexpr double kPi = std::numbers::pi;

// (cos, sin) of theta_h from w; precise near u = 1.
inline void thetaFromW(double w, double a2, double& ch, double& sh) {
  const double den = w + a2 * (1.0 - w);
  ch = std::sqrt(w / den);
  sh = std::sqrt(a2 * (1.0 - w) / den);
}
inline double wFromTheta(double theta, double a2) {
  if (theta >= 0.5 * kPi) return 0.0;
  const double t = std::tan(theta);
  return a2 / (a2 + t * t);
}

enum class Lobe { Reflection, Transmission };

struct HalfVectorDomain {
  Lobe lobe = Lobe::Reflection;
  double cv = 1, sv = 0, alpha = 0, a2 = 0;  // view cosine and sine, roughness
  double th1 = 0, th2 = 0;                   // theta_A, theta_B
  double w1 = 1, w2 = 1;                     // w at theta_A and theta_B
  bool smooth_full = false;                  // smoothstep map of the full-circle piece
  std::vector<Box<2>> boxes;                 // starting partition of [0, 2] x [0, 1]
};

// t in [0, 1] with 3 t^2 - 2 t^3 = s.
inline double invSmoothstep(double s) {
  return 0.5 - std::sin(std::asin(std::clamp(1.0 - 2.0 * s, -1.0, 1.0)) / 3.0);
}

// The domain of `lobe` for view cosine mu and roughness alpha > 0, with its partition; the
// extra polar angles are breakpoints too (where the integrand turns over on a scale of its
// own, such as the Fresnel factor's near eta = 1).
HalfVectorDomain halfVectorDomain(Lobe lobe, double mu, double alpha, bool smooth_full = false,
                                  const std::vector<double>& extra_theta = {});

// A point of the square as a half vector: (cos, sin) of theta_h, phi, and the Jacobian of
// (u, phi) with respect to the square (zero outside the domain).
struct HalfVector {
  double ch = 1, sh = 0, phi = 0, jac = 0;
};
inline HalfVector mapHalfVector(const HalfVectorDomain& d, const std::array<double, 2>& p) {
  HalfVector h;
  double wv, phimax;
  if (p[0] <= 1.0 && !d.smooth_full) {
    wv = 1.0 - (1.0 - d.w1) * p[0];
    h.jac = (1.0 - d.w1) * kPi;
    thetaFromW(wv, d.a2, h.ch, h.sh);
    phimax = kPi;
  } else if (p[0] <= 1.0) {
    const double t = p[0];
    wv = 1.0 - (1.0 - d.w1) * t * t * (3.0 - 2.0 * t);
    h.jac = (1.0 - d.w1) * 6.0 * t * (1.0 - t) * kPi;
    thetaFromW(wv, d.a2, h.ch, h.sh);
    phimax = kPi;
  } else {
    const double t = p[0] - 1.0;
    const double s = t * t * (3.0 - 2.0 * t);
    wv = d.w1 - (d.w1 - d.w2) * s;
    thetaFromW(wv, d.a2, h.ch, h.sh);
    double c0;
    if (d.lobe == Lobe::Reflection) {
      const double c2 = h.ch * h.ch - h.sh * h.sh, s2 = 2.0 * h.sh * h.ch;
      c0 = (d.sv * s2 > 0.0) ? -c2 * d.cv / (s2 * d.sv) : -1.0;
    } else {
      c0 = (d.sv * h.sh > 0.0) ? -h.ch * d.cv / (h.sh * d.sv) : -1.0;
    }
    phimax = std::acos(std::clamp(c0, -1.0, 1.0));
    h.jac = (d.w1 - d.w2) * 6.0 * t * (1.0 - t) * phimax;
  }
  h.phi = phimax * p[1];
  return h;
}

}  // namespace lgp::datasets::detail
