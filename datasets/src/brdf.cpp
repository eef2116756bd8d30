#include "lgp/datasets/brdf.hpp"

#include "lgp/datasets/integrator.hpp"

namespace lgp::datasets {

const char* toString(Ndf) {
  return "ggx";
}
const char* toString(Visibility v) {
  switch (v) {
    case Visibility::SmithCorrelated:
      return "smith-correlated";
    case Visibility::SchlickSmith:
      return "schlick-smith";
    case Visibility::SmithSeparable:
      return "smith-separable";
  }
  return "?";
}
const char* toString(FresnelModel v) {
  switch (v) {
    case FresnelModel::None:
      return "none";
    case FresnelModel::Schlick:
      return "schlick";
    case FresnelModel::Dielectric:
      return "dielectric";
  }
  return "?";
}
const char* toString(RoughnessMap v) {
  switch (v) {
    case RoughnessMap::Perceptual:
      return "perceptual";
    case RoughnessMap::Linear:
      return "linear";
  }
  return "?";
}
const char* toString(Diffuse v) {
  switch (v) {
    case Diffuse::Disney:
      return "disney";
    case Diffuse::Lambert:
      return "lambert";
  }
  return "?";
}
const char* toString(Transmission v) {
  switch (v) {
    case Transmission::Flux:
      return "flux";
    case Transmission::Radiance:
      return "radiance";
  }
  return "?";
}
const char* toString(IntegratorKind k) {
  switch (k) {
    case IntegratorKind::Gauss:
      return "gauss";
    case IntegratorKind::Adaptive:
      return "adaptive";
    case IntegratorKind::Qmc:
      return "qmc";
  }
  return "?";
}

namespace {
template <class E, size_t N>
bool parseEnum(const std::string& s, E& v, const E (&all)[N]) {
  for (E e : all)
    if (s == toString(e)) {
      v = e;
      return true;
    }
  return false;
}
}  // namespace

bool fromString(const std::string& s, Ndf& v) {
  return parseEnum(s, v, {Ndf::Ggx});
}
bool fromString(const std::string& s, Visibility& v) {
  return parseEnum(
      s, v, {Visibility::SmithCorrelated, Visibility::SchlickSmith, Visibility::SmithSeparable});
}
bool fromString(const std::string& s, FresnelModel& v) {
  return parseEnum(s, v, {FresnelModel::None, FresnelModel::Schlick, FresnelModel::Dielectric});
}
bool fromString(const std::string& s, RoughnessMap& v) {
  return parseEnum(s, v, {RoughnessMap::Perceptual, RoughnessMap::Linear});
}
bool fromString(const std::string& s, Diffuse& v) {
  return parseEnum(s, v, {Diffuse::Disney, Diffuse::Lambert});
}
bool fromString(const std::string& s, Transmission& v) {
  return parseEnum(s, v, {Transmission::Flux, Transmission::Radiance});
}
bool fromString(const std::string& s, IntegratorKind& k) {
  return parseEnum(s, k, {IntegratorKind::Gauss, IntegratorKind::Adaptive, IntegratorKind::Qmc});
}

}  // namespace lgp::datasets
