// Scene JSON: what to simulate ("simulate only the effects a scene calls for").
//
// {
//   "format": "lgp-scene/1",                      // optional
//   "name": "dfg-64",                              // optional, free text
//   "material": {
//     "ndf": "ggx",                                // only GGX
//     "visibility": "smith-correlated",            // "schlick-smith" (k = alpha / 2) or
//                                                  // "smith-separable" (exact G1(l) G1(v))
//     "fresnel": {"model": "schlick", "f90": 1},   // "none", or "dielectric" (outputs over eta)
//     "roughness": "perceptual",                   // alpha = r^2, or "linear" (alpha = r)
//     "diffuse": "disney",                         // or "lambert" (zh outputs only)
//     "transmission": "flux"                       // or "radiance" (E_trans, E_dielectric)
//   },
//   "light": {"type": "environment"}               // every output but N
//         or {"type": "sphere", "size": "theta_s", // or "tan_half_theta_s" = tan(theta_s / 2)
//             "range": [0, 1.2], "softmin_s": -3, "incidence": "normal"},
//   "outputs": ["A", "B"],
//   "grid": {                                      // one entry per input of the outputs
//     "mu": {"count": 64, "range": [0.015625, 1], "spacing": "edge"},  // edge-inclusive
//     "r":  {"count": 64, "range": [0, 1], "spacing": "cell"},         // cell-centred
//     "theta_s": {"values": [0.1, 0.2, 0.4]}                           // explicit
//   },
//   "accuracy": {"abs_error": 1e-6, "integrator": "adaptive",   // or "gauss", "qmc"
//                "gauss_order": 16, "qmc_points": 16384}
// }
//
// Outputs and their inputs (outputs.hpp; a table's inputs are the union over its outputs, in
// the order mu, r, eta, and an output is repeated along the inputs it does not depend on):
//   A, B (need fresnel "schlick"), E, one_minus_E, E_avg, ms_turquin, ms_lobe  inputs (mu, r)
//   ZH0, ZH1, ZH2, ZH1_over_ZH0, ZH2_over_ZH0, beta                          inputs (mu, r)
//   E_sheen, E_burley, E_oren_nayar                                          inputs (mu, r)
//   F_dielectric (mu, eta), F_avg (eta), E_refl, E_trans, E_dielectric (mu, r, eta): fresnel
//   "dielectric"; E_refl, E_trans and E_dielectric need eta >= 1
//   N (needs a sphere light, alone)                  inputs (r, theta_s | tan_half_theta_s)
// Rows: the Cartesian product of the grids, the first input varying fastest.
// Limits: at most 100000 points per axis ("count") and kMaxSceneCells = 16,777,216 (2^24,
// e.g. 4096 x 4096) rows in all, checked when the scene is parsed (the error names /grid);
// a scene file is read only if it is a regular file of at most 64 MiB (lgp::readInputFile)
// and parsed with lgp::parseJson (depth, duplicate keys, number range).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "lgp/core/status.hpp"
#include "lgp/datasets/brdf.hpp"
#include "lgp/datasets/integrator.hpp"
#include "lgp/datasets/outputs.hpp"

namespace lgp::datasets {

enum class LightType { Environment, Sphere };

struct Light {
  LightType type = LightType::Environment;  // environment or sphere
  std::string size = "theta_s";             // sphere size input: theta_s or tan_half_theta_s
  double range_lo = 0, range_hi = 0;        // sphere size range, in the size variable
  double softmin_s = -3.0;                  // soft-minimum exponent of the representative point
};

struct GridAxis {
  std::string name;              // input name
  std::string spacing = "edge";  // edge | cell | values
  int count = 0;                 // points
  double lo = 0, hi = 0;         // range
  std::vector<double> values;    // the expanded points
};

struct Accuracy {
  double abs_error = 1e-6;  // target absolute error per entry
  IntegratorKind integrator = IntegratorKind::Adaptive;
  int gauss_order = 16;    // gauss: coarse order (fine = 2n)
  int qmc_points = 16384;  // qmc: points per shift (8 shifts)
};

struct Scene {
  std::string name;
  Material material;
  Light light;
  std::vector<std::string> outputs;  // in table order
  std::vector<GridAxis> grid;        // in input order (one to three inputs)
  Accuracy accuracy;

  std::vector<std::string> inputNames() const;
  size_t rows() const;
  bool wants(const std::string& output) const;
  bool needs(Effect e) const;  // does any requested output need this effect?
  // The grid axis of `input`, or nullptr.
  const GridAxis* axis(const std::string& input) const;
};

inline constexpr size_t kMaxSceneCells = size_t{1} << 24;

// The known outputs, in canonical order.
const std::vector<std::string>& knownOutputs();

// Parses and validates a scene. Errors name the JSON path and the reason, prefixed by origin:
// "scene.json: /grid/mu/count: must be an integer >= 1 (got 0)".
Expected<Scene> parseScene(const nlohmann::json& j, const std::string& origin = "scene");
Expected<Scene> loadScene(const std::filesystem::path& path);
// Canonical JSON of a parsed scene (defaults filled in); the cache key hashes it.
nlohmann::json toJson(const Scene& s);

}  // namespace lgp::datasets
