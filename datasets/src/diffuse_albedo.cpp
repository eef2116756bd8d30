#include "lgp/datasets/diffuse_albedo.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "lgp/datasets/quadrature.hpp"

namespace lgp::datasets {

AlbedoValue burleyAlbedo(double mu, double r, Counters* counters) {
  mu = std::clamp(mu, 0.0, 1.0);
  // F_D90 - 1 = c0 + r (l.v), l.v = s_l s_v cos(phi) + x mu; over the azimuth
  // <l.v> = x mu and <(l.v)^2> = x^2 mu^2 + (1 - x^2)(1 - mu^2) / 2.
  const double c0 = r - 0.5;
  const double m = 1.0 - mu;
  const double wv = m * m * m * m * m;
  const GaussRule& g = gaussLegendre(8);
  double sum = 0;
  for (size_t i = 0; i < g.x.size(); ++i) {
    const double x = g.x[i];
    const double ml = 1.0 - x;
    const double wl = ml * ml * ml * ml * ml;
    const double a1 = c0 + r * x * mu;
    const double a2 = c0 * c0 + 2.0 * c0 * r * x * mu +
                      r * r * (x * x * mu * mu + 0.5 * (1.0 - x * x) * (1.0 - mu * mu));
    sum += g.w[i] * x * (1.0 + a1 * (wl + wv) + a2 * wl * wv);
  }
  if (counters) counters->diffuse += g.x.size();
  AlbedoValue out;
  out.E = 2.0 * sum;  // (1/pi) 2 pi integral_0^1 ... dx
  out.error = kRoundoff * std::abs(out.E);
  return out;
}

AlbedoValue orenNayarAlbedo(double mu, double r, Counters* counters) {
  mu = std::clamp(mu, 0.0, 1.0);
  const double s2 = r * r;
  const double A = 1.0 - 0.5 * s2 / (s2 + 0.33);
  const double B = 0.45 * s2 / (s2 + 0.09);
  const double sv = std::sqrt(std::max(0.0, 1.0 - mu * mu));
  const double tv = std::acos(mu);
  const double inner = 0.5 * sv * (tv - sv * mu);                            // theta_l < theta_v
  const double outer = sv * mu * (1.0 + sv + sv * sv) / (3.0 * (1.0 + sv));  // theta_l > theta_v
  if (counters) counters->diffuse += 1;
  AlbedoValue out;
  out.E = A + 2.0 * B / std::numbers::pi * (inner + outer);
  out.error = kRoundoff * std::abs(out.E);
  return out;
}

}  // namespace lgp::datasets
