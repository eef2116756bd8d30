// Integrator selection shared by the generators, and per-effect evaluation counters.
#pragma once

#include <cstdint>
#include <string>

namespace lgp::datasets {

enum class IntegratorKind {
  Gauss,     // product Gauss-Legendre, orders n and 2n, in half-vector / CDF space
  Adaptive,  // globally adaptive subdivision with a heap, to a tolerance
  Qmc,       // randomly shifted Hammersley points, GGX importance sampling
};
const char* toString(IntegratorKind k);
bool fromString(const std::string& s, IntegratorKind& k);

struct IntegratorOptions {
  IntegratorKind kind = IntegratorKind::Adaptive;  // method
  double abs_tol = 1e-7;         // adaptive: target absolute error of every table entry
  int order = 16;                // gauss: points per dimension of the coarse rule (fine = 2n)
  int adaptive_order = 5;        // adaptive: points per dimension per region
  uint64_t max_evals = 4000000;  // adaptive: budget per integral
  int qmc_points = 16384;        // qmc: points per shift
  int qmc_shifts = 8;            // qmc: independent random shifts
};

// Integrand evaluations per effect. A scene that does not ask for an effect leaves its
// counter at zero (the "simulate only what the scene calls for" contract, tested).
struct Counters {
  uint64_t specular = 0;    // microfacet BRDF evaluations (D, G2)
  uint64_t fresnel = 0;     // of those, evaluations that also split by the Fresnel weight
  uint64_t diffuse = 0;     // diffuse evaluations (zh moments, diffuse albedo nodes)
  uint64_t rep_point = 0;   // of the specular ones, at a representative point (normalization)
  uint64_t sheen = 0;       // Charlie sheen evaluations
  uint64_t dielectric = 0;  // GGX evaluations with the exact dielectric Fresnel (and F_avg)
  void add(const Counters& o) {
    specular += o.specular;
    fresnel += o.fresnel;
    diffuse += o.diffuse;
    rep_point += o.rep_point;
    sheen += o.sheen;
    dielectric += o.dielectric;
  }
  uint64_t total() const { return specular + diffuse + sheen + dielectric; }
};

}  // namespace lgp::datasets
