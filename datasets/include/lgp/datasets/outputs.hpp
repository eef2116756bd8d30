// The outputs a scene can ask for: one catalogue, in canonical order, with the inputs each
// output depends on, the effect (the integral) it needs and the definition written into a
// table's metadata. The conventions are in docs/tables.md.
//
// A table's inputs are the union of its outputs' inputs in the canonical order mu, r, eta; an
// output that depends on fewer of them (E_avg on r, F_avg on eta) is repeated along the others.
// N is the exception: its inputs (r and the light size) are shared with no other output.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace lgp::datasets {

// The integrals behind the outputs ("simulate only the effects a scene calls for").
enum class Effect {
  Specular,       // GGX with F = 1: E and what is built from it (dfg, energy, normalization)
  Fresnel,        // of those, the Schlick split A / B
  Energy,         // terms built from E and E_avg (1 - E, E_avg, the multiple-scattering factors)
  Diffuse,        // Disney diffuse in zonal harmonics
  Normalization,  // the sphere light's representative point
  Sheen,          // Charlie sheen with Neubelt-Pettineo visibility
  DiffuseAlbedo,  // directional albedo of Burley and Oren-Nayar diffuse
  Dielectric,     // exact dielectric Fresnel: F, F_avg, GGX reflection and transmission
};

// Every output, in canonical order (the catalogue's). A new output is an entry here, one in
// outputCatalog() and a case of the evaluator map in generate.cpp (a switch with no
// `default:`); tests/datasets/registry_test.cpp generates each and checks its cache key.
enum class Output : uint8_t {
  A,
  B,
  E,
  one_minus_E,
  E_avg,
  ZH0,
  ZH1,
  ZH2,
  ZH1_over_ZH0,
  ZH2_over_ZH0,
  beta,
  N,
  ms_turquin,
  ms_lobe,
  E_sheen,
  E_burley,
  E_oren_nayar,
  F_dielectric,
  F_avg,
  E_refl,
  E_trans,
  E_dielectric,
};
inline constexpr size_t kNumOutputs = static_cast<size_t>(Output::E_dielectric) + 1;

struct OutputSpec {
  Output id;
  std::string name;
  std::vector<std::string> inputs;  // in canonical order; "size" stands for the light's input
  Effect effect;
  std::string definition;  // one line, for the table's meta
};

// Every output, in canonical order.
const std::vector<OutputSpec>& outputCatalog();
// The entry of `name`, or nullptr.
const OutputSpec* findOutput(const std::string& name);
// The canonical order of the surface inputs.
const std::vector<std::string>& canonicalInputs();

}  // namespace lgp::datasets
