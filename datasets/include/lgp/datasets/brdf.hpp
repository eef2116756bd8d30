// Microfacet and diffuse BRDF terms shared by the generators (conventions: docs/tables.md).
// Frame: n = +z, v = (sqrt(1 - mu^2), 0, mu). All functions are branch-light and finite for
// alpha > 0 and every mu in [0, 1]; alpha = 0 (a delta lobe) is handled by the callers with
// its analytic limit.
#pragma once

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>

namespace lgp::datasets {

enum class Ndf { Ggx };
enum class Visibility { SmithCorrelated, SchlickSmith, SmithSeparable };
enum class FresnelModel { None, Schlick, Dielectric };
enum class RoughnessMap { Perceptual, Linear };  // alpha = r^2 | alpha = r
enum class Diffuse { Disney, Lambert };
// How the transmitted lobe of a dielectric is counted (docs/tables.md, "dielectric"): as the
// transmitted flux (smooth limit 1 - F; what energy compensation needs), or as radiance seen
// from outside (Walter et al. 2007's BTDF with the outer index 1; smooth limit (1 - F) / eta^2).
enum class Transmission { Flux, Radiance };

const char* toString(Ndf v);
const char* toString(Visibility v);
const char* toString(FresnelModel v);
const char* toString(RoughnessMap v);
const char* toString(Diffuse v);
const char* toString(Transmission v);
bool fromString(const std::string& s, Ndf& v);
bool fromString(const std::string& s, Visibility& v);
bool fromString(const std::string& s, FresnelModel& v);
bool fromString(const std::string& s, RoughnessMap& v);
bool fromString(const std::string& s, Diffuse& v);
bool fromString(const std::string& s, Transmission& v);

struct Material {
  Ndf ndf = Ndf::Ggx;                                   // microfacet distribution
  Visibility visibility = Visibility::SmithCorrelated;  // G2 form
  FresnelModel fresnel = FresnelModel::Schlick;         // F = F0 + (F90 - F0)(1 - v.h)^5
  double f90 = 1.0;                                     // Schlick grazing reflectance
  RoughnessMap roughness = RoughnessMap::Perceptual;    // r -> alpha
  Diffuse diffuse = Diffuse::Disney;                    // for the zh generator
  Transmission transmission = Transmission::Flux;       // dielectric E_trans convention

  double alpha(double r) const { return roughness == RoughnessMap::Perceptual ? r * r : r; }
};

// GGX NDF (Walter et al. 2007): D(h) = alpha^2 / (pi ((n.h)^2 (alpha^2 - 1) + 1)^2).
inline double ggxD(double nh, double alpha) {
  const double a2 = alpha * alpha;
  const double d = nh * nh * (a2 - 1.0) + 1.0;
  return a2 / (std::numbers::pi * d * d);
}
// The same with the denominator written as sin^2(theta_h) + alpha^2 cos^2(theta_h), from
// sin2h = 1 - (n.h)^2 computed without cancellation (e.g. as h_x^2 + h_y^2). Near the peak
// of a sharp lobe 1 - (n.h)^2 ~ alpha^2, and forming it from n.h loses eps / alpha^2 of it
// (7e-10 relative at alpha = 4e-4).
inline double ggxD(double nh, double sin2h, double alpha) {
  const double a2 = alpha * alpha;
  const double d = sin2h + a2 * nh * nh;
  return a2 / (std::numbers::pi * d * d);
}

// G2(l, v) / (n.v), finite at n.v = 0 for alpha > 0.
//  Smith height-correlated: G2 = 1 / (1 + Lambda(v) + Lambda(l)),
//    Lambda(x) = (sqrt(alpha^2 + (1 - alpha^2) x^2) / x - 1) / 2, which rearranges to
//    G2 / nv = 2 nl / (nv S(nl) + nl S(nv)),  S(x) = sqrt(alpha^2 + (1 - alpha^2) x^2).
//  Schlick-Smith separable: G2 = G1(l) G1(v), G1(x) = x / (x (1 - k) + k), k = alpha / 2.
//  Smith separable (uncorrelated; Walter et al. 2007): G2 = G1(l) G1(v) with the exact
//    G1(x) = 2 x / (x + S(x)), so G2 / nv = 2 G1(l) / (nv + S(nv)).
// A transmitted direction passes |n.l| (Smith masking of the lower side).
inline double g2OverNv(double nl, double nv, double alpha, Visibility vis) {
  if (nl <= 0.0) return 0.0;
  const double a2 = alpha * alpha;
  if (vis == Visibility::SmithCorrelated) {
    const double sl = std::sqrt(a2 + (1.0 - a2) * nl * nl);
    const double sv = std::sqrt(a2 + (1.0 - a2) * nv * nv);
    return 2.0 * nl / (nv * sl + nl * sv);
  }
  if (vis == Visibility::SmithSeparable) {
    const double sl = std::sqrt(a2 + (1.0 - a2) * nl * nl);
    const double sv = std::sqrt(a2 + (1.0 - a2) * nv * nv);
    return 4.0 * nl / ((nl + sl) * (nv + sv));
  }
  const double k = 0.5 * alpha;
  const double g1l = nl / (nl * (1.0 - k) + k);
  return g1l / (nv * (1.0 - k) + k);
}

// Schlick's Fresnel weight (1 - v.h)^5 (F = F0 (1 - Fc) + F90 Fc).
inline double schlickWeight(double vh) {
  const double m = std::clamp(1.0 - vh, 0.0, 1.0);
  const double m2 = m * m;
  return m2 * m2 * m;
}

// cos^2 of the refracted angle for light at cosine c entering relative index eta:
// 1 - (1 - c^2) / eta^2, formed as ((eta - 1)(eta + 1) + c^2) / eta^2 so that near eta = 1
// a grazing c (c^2 below double's epsilon) is not cancelled away and read as total internal
// reflection. <= 0: total internal reflection.
inline double cosTransmitted2(double c, double eta) {
  return ((eta - 1.0) * (eta + 1.0) + c * c) / (eta * eta);
}

// Exact unpolarised Fresnel reflectance of a smooth dielectric interface (Born and Wolf 1999),
// for light arriving at cosine c >= 0 to the interface normal from the side of index 1 into
// relative index eta = n_inside / n_outside (eta < 1: the denser medium is outside; total
// internal reflection gives 1). F = (r_s^2 + r_p^2) / 2 with cos_t = sqrt(cosTransmitted2).
// eta = 1 is no interface: F = 0 at every c, grazing included.
inline double fresnelDielectric(double c, double eta) {
  if (eta == 1.0) return 0.0;
  c = std::clamp(c, 0.0, 1.0);
  const double ct2 = cosTransmitted2(c, eta);
  if (ct2 <= 0.0) return 1.0;
  const double ct = std::sqrt(ct2);
  const double rs = (c - eta * ct) / (c + eta * ct);
  const double rp = (eta * c - ct) / (eta * c + ct);
  return 0.5 * (rs * rs + rp * rp);
}

// f_spec(l, v) with F = 1: D G2 / (4 nl nv). Zero below the horizon. sin2h = 1 - (n.h)^2,
// computed by the caller without cancellation (see ggxD).
inline double specularBrdf(double nl, double nv, double nh, double sin2h, double alpha,
                           Visibility vis) {
  if (nl <= 0.0 || nv <= 0.0) return 0.0;
  return ggxD(nh, sin2h, alpha) * g2OverNv(nl, nv, alpha, vis) / (4.0 * nl);
}

// Disney diffuse (Burley 2012) with baseColor = 1, or Lambert 1/pi.
//  f_d = (1/pi) (1 + (F_D90 - 1)(1 - nl)^5) (1 + (F_D90 - 1)(1 - nv)^5),
//  F_D90 = 0.5 + 2 r (l.h)^2, (l.h)^2 = (1 + l.v) / 2.
inline double diffuseBrdf(double nl, double nv, double lv, double r, Diffuse model) {
  if (model == Diffuse::Lambert) return std::numbers::inv_pi;
  const double lh2 = 0.5 * (1.0 + lv);
  const double fd90 = 0.5 + 2.0 * r * lh2;
  return std::numbers::inv_pi * (1.0 + (fd90 - 1.0) * schlickWeight(nl)) *
         (1.0 + (fd90 - 1.0) * schlickWeight(nv));
}

}  // namespace lgp::datasets
