#include "lgp/datasets/scene.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <sstream>

#include "lgp/config/json_reader.hpp"
#include "lgp/core/data_roots.hpp"
#include "lgp/core/table.hpp"

namespace lgp::datasets {

namespace {
using nlohmann::json;

// A scene is a few hundred bytes; explicit "values" grids stay far below this.
constexpr size_t kMaxSceneFileBytes = size_t{64} << 20;

std::string fmt(double v) {
  std::ostringstream s;
  s.precision(17);
  s << v;
  return s.str();
}

struct Parser {
  std::string origin;
  std::string err;
  bool fail(const std::string& path, const std::string& why) {
    if (err.empty()) err = origin + ": " + jsonError(path, why);
    return false;
  }
  bool checkKeys(const json& j, const std::string& path,
                 std::initializer_list<std::string_view> allowed) {
    JsonObjectReader o(j, path);
    if (!o.isObject()) return fail(path, "must be an object");
    o.allow(allowed);
    if (auto k = o.unknownKey()) return fail(*k, "unknown key");
    return true;
  }
  template <class E>
  bool enumField(const json& j, const std::string& key, const std::string& path, E& out,
                 const char* choices) {
    if (!j.contains(key)) return true;
    const json& v = j.at(key);
    if (!v.is_string() || !fromString(v.get<std::string>(), out))
      return fail(jsonPath(path, key),
                  std::string("must be one of ") + choices + " (got " + v.dump() + ")");
    return true;
  }
  bool number(const json& j, const std::string& key, const std::string& path, double& out) {
    if (!j.contains(key)) return true;
    const json& v = j.at(key);
    if (!v.is_number() || !std::isfinite(v.get<double>()))
      return fail(jsonPath(path, key), "must be a finite number (got " + v.dump() + ")");
    out = v.get<double>();
    return true;
  }
  bool integer(const json& j, const std::string& key, const std::string& path, int& out, int lo,
               int hi) {
    if (!j.contains(key)) return true;
    const json& v = j.at(key);
    if (!v.is_number_integer() || v.get<long long>() < lo || v.get<long long>() > hi)
      return fail(jsonPath(path, key), "must be an integer in [" + std::to_string(lo) + ", " +
                                           std::to_string(hi) + "] (got " + v.dump() + ")");
    out = v.get<int>();
    return true;
  }
  bool range(const json& j, const std::string& path, double& lo, double& hi) {
    if (!j.is_array() || j.size() != 2 || !j[0].is_number() || !j[1].is_number())
      return fail(path, "must be [lo, hi] (got " + j.dump() + ")");
    lo = j[0].get<double>();
    hi = j[1].get<double>();
    if (!std::isfinite(lo) || !std::isfinite(hi) || lo > hi)
      return fail(path, "needs finite lo <= hi (got " + j.dump() + ")");
    return true;
  }
};

// Domain of each input: [lo, hi], and whether hi is included.
struct Domain {
  double lo, hi;
  bool hi_open;
};
Domain domainOf(const std::string& name) {
  if (name == "theta_s") return {0.0, 0.5 * std::numbers::pi, true};
  if (name == "tan_half_theta_s") return {0.0, 1.0, true};
  if (name == "eta") return {0.2, 5.0, false};
  return {0.0, 1.0, false};  // mu, r
}
// The range a "count" grid spans when it gives none.
void defaultRange(const std::string& name, const Scene& s, double& lo, double& hi) {
  const Domain d = domainOf(name);
  lo = d.lo;
  hi = d.hi_open ? 0.0 : d.hi;
  if (name == "eta") lo = 1.0, hi = 3.0;
  if (name == s.light.size && s.wants("N")) {
    lo = s.light.range_lo;
    hi = s.light.range_hi;
  }
}
}  // namespace

const std::vector<std::string>& knownOutputs() {
  static const std::vector<std::string> k = [] {
    std::vector<std::string> n;
    for (const auto& o : outputCatalog()) n.push_back(o.name);
    return n;
  }();
  return k;
}

std::vector<std::string> Scene::inputNames() const {
  std::vector<std::string> n;
  for (const auto& a : grid) n.push_back(a.name);
  return n;
}

size_t Scene::rows() const {
  size_t n = grid.empty() ? 0 : 1;
  for (const auto& a : grid) n *= a.values.size();
  return n;
}

bool Scene::wants(const std::string& o) const {
  return std::find(outputs.begin(), outputs.end(), o) != outputs.end();
}

const GridAxis* Scene::axis(const std::string& input) const {
  for (const auto& a : grid)
    if (a.name == input) return &a;
  return nullptr;
}

bool Scene::needs(Effect e) const {
  for (const auto& o : outputs) {
    const OutputSpec* spec = findOutput(o);
    if (!spec) continue;
    const Effect f = spec->effect;
    // E underlies the dfg split, the energy terms and the normalization.
    if (e == Effect::Specular && (f == Effect::Specular || f == Effect::Fresnel ||
                                  f == Effect::Energy || f == Effect::Normalization))
      return true;
    if (f == e) return true;
  }
  return false;
}

namespace {
// ---- one function per section of the scene; each returns false with p.err set ----

bool parseHeader(Parser& p, const json& j, Scene& s) {
  if (!p.checkKeys(
          j, "",
          {"format", "name", "description", "material", "light", "outputs", "grid", "accuracy"}))
    return false;
  if (j.contains("format") && j["format"] != "lgp-scene/1")
    return p.fail("/format", "must be \"lgp-scene/1\" (got " + j["format"].dump() + ")");
  if (j.contains("name")) {
    if (!j["name"].is_string()) return p.fail("/name", "must be a string");
    s.name = j["name"].get<std::string>();
  }
  return true;
}

bool parseFresnel(Parser& p, const json& f, Material& m) {
  const char* kModels = "\"none\", \"schlick\", \"dielectric\"";
  if (f.is_string()) {
    json wrapped = {{"model", f}};
    return p.enumField(wrapped, "model", "/material/fresnel", m.fresnel, kModels);
  }
  if (!p.checkKeys(f, "/material/fresnel", {"model", "f90"}) ||
      !p.enumField(f, "model", "/material/fresnel", m.fresnel, kModels) ||
      !p.number(f, "f90", "/material/fresnel", m.f90))
    return false;
  if (m.f90 < 0 || m.f90 > 1)
    return p.fail("/material/fresnel/f90", "must be in [0, 1] (got " + fmt(m.f90) + ")");
  return true;
}

bool parseMaterial(Parser& p, const json& j, Scene& s) {
  if (!j.contains("material")) return true;
  const json& m = j["material"];
  if (!p.checkKeys(m, "/material",
                   {"ndf", "visibility", "fresnel", "roughness", "diffuse", "transmission"}) ||
      !p.enumField(m, "ndf", "/material", s.material.ndf, "\"ggx\"") ||
      !p.enumField(m, "visibility", "/material", s.material.visibility,
                   "\"smith-correlated\", \"schlick-smith\", \"smith-separable\"") ||
      !p.enumField(m, "roughness", "/material", s.material.roughness,
                   "\"perceptual\", \"linear\"") ||
      !p.enumField(m, "diffuse", "/material", s.material.diffuse, "\"disney\", \"lambert\"") ||
      !p.enumField(m, "transmission", "/material", s.material.transmission,
                   "\"flux\", \"radiance\""))
    return false;
  return !m.contains("fresnel") || parseFresnel(p, m["fresnel"], s.material);
}

bool parseSphereLight(Parser& p, const json& l, Light& light) {
  light.type = LightType::Sphere;
  if (l.contains("size")) {
    if (!l["size"].is_string() || (l["size"] != "theta_s" && l["size"] != "tan_half_theta_s"))
      return p.fail("/light/size",
                    "must be \"theta_s\" or \"tan_half_theta_s\" (got " + l["size"].dump() + ")");
    light.size = l["size"].get<std::string>();
  }
  const Domain d = domainOf(light.size);
  light.range_lo = d.lo;
  light.range_hi = light.size == "theta_s" ? 1.2 : 0.6;
  if (l.contains("range") && !p.range(l["range"], "/light/range", light.range_lo, light.range_hi))
    return false;
  if (light.range_lo < d.lo || light.range_hi >= d.hi)
    return p.fail("/light/range", "must lie in [0, " + fmt(d.hi) + ") for " + light.size);
  if (!p.number(l, "softmin_s", "/light", light.softmin_s)) return false;
  if (!(light.softmin_s < 0))
    return p.fail("/light/softmin_s", "must be < 0 (got " + fmt(light.softmin_s) + ")");
  if (l.contains("incidence") && l["incidence"] != "normal")
    return p.fail("/light/incidence",
                  "only \"normal\" is implemented (got " + l["incidence"].dump() + ")");
  return true;
}

bool parseLight(Parser& p, const json& j, Scene& s) {
  if (!j.contains("light")) return true;
  const json& l = j["light"];
  if (!p.checkKeys(l, "/light", {"type", "size", "range", "softmin_s", "incidence"})) return false;
  if (l.contains("type") && !l["type"].is_string())
    return p.fail("/light/type",
                  "must be \"environment\" or \"sphere\" (got " + l["type"].dump() + ")");
  const std::string type = l.value("type", std::string("environment"));
  if (type == "sphere") return parseSphereLight(p, l, s.light);
  if (type != "environment")
    return p.fail("/light/type", "must be \"environment\" or \"sphere\" (got \"" + type + "\")");
  s.light.type = LightType::Environment;
  for (const char* k : {"size", "range", "softmin_s", "incidence"})
    if (l.contains(k)) return p.fail(jsonPath("/light", k), "only valid for a sphere light");
  return true;
}

bool parseOutputs(Parser& p, const json& j, Scene& s) {
  if (!j.contains("outputs") || !j["outputs"].is_array() || j["outputs"].empty())
    return p.fail("/outputs", "must be a non-empty array of output names");
  for (size_t i = 0; i < j["outputs"].size(); ++i) {
    const json& o = j["outputs"][i];
    const std::string path = jsonPath("/outputs", i);
    if (!o.is_string() || !findOutput(o.get<std::string>())) {
      std::string list;
      for (const auto& k : knownOutputs()) list += (list.empty() ? "" : ", ") + k;
      return p.fail(path, "unknown output " + o.dump() + " (known: " + list + ")");
    }
    if (s.wants(o.get<std::string>())) return p.fail(path, "duplicate output " + o.dump());
    s.outputs.push_back(o.get<std::string>());
  }
  return true;
}

// What the outputs ask of the light and the material.
bool validateOutputs(Parser& p, const Scene& s) {
  const bool has_n = s.wants("N");
  if (has_n && s.outputs.size() > 1)
    return p.fail("/outputs", "\"N\" has inputs (r, " + s.light.size +
                                  ") and cannot share a table with outputs over (mu, r)");
  if (has_n && s.light.type != LightType::Sphere)
    return p.fail("/light/type", "output \"N\" needs a sphere light");
  if (s.needs(Effect::Fresnel) && s.material.fresnel != FresnelModel::Schlick)
    return p.fail("/material/fresnel",
                  "outputs \"A\"/\"B\" are the Fresnel split; they need "
                  "\"schlick\" (use \"E\" with Fresnel off)");
  if (s.needs(Effect::Dielectric) && s.material.fresnel != FresnelModel::Dielectric)
    return p.fail("/material/fresnel",
                  "outputs over eta use the exact dielectric Fresnel; they need \"dielectric\"");
  return true;
}

// The table's inputs: the union of the outputs' inputs in canonical order (N: r and the size).
std::vector<std::string> tableInputs(const Scene& s) {
  if (s.wants("N")) return {"r", s.light.size};
  std::vector<std::string> in;
  for (const auto& name : canonicalInputs())
    for (const auto& o : s.outputs) {
      const auto& oi = findOutput(o)->inputs;
      if (std::find(oi.begin(), oi.end(), name) != oi.end()) {
        in.push_back(name);
        break;
      }
    }
  return in;
}

std::string listed(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& x : v) s += (s.empty() ? "" : ", ") + x;
  return s;
}

// Expands {"count", "range", "spacing"} into points.
bool expandCounted(Parser& p, const json& g, const std::string& path, const Scene& s, GridAxis& a) {
  if (!g.contains("count")) return p.fail(jsonPath(path, "count"), "missing");
  if (!p.integer(g, "count", path, a.count, 1, 100000)) return false;
  defaultRange(a.name, s, a.lo, a.hi);
  if (g.contains("range") && !p.range(g["range"], jsonPath(path, "range"), a.lo, a.hi))
    return false;
  if (g.contains("spacing") && !g["spacing"].is_string())
    return p.fail(jsonPath(path, "spacing"),
                  "must be \"edge\" or \"cell\" (got " + g["spacing"].dump() + ")");
  a.spacing = g.value("spacing", std::string("edge"));
  if (a.spacing == "edge") {
    if (a.count == 1) {
      a.values = {a.lo};
    } else {
      for (int i = 0; i < a.count; ++i)
        a.values.push_back(i + 1 == a.count ? a.hi : a.lo + (a.hi - a.lo) * i / (a.count - 1.0));
    }
  } else if (a.spacing == "cell") {
    for (int i = 0; i < a.count; ++i)
      a.values.push_back(a.lo + (a.hi - a.lo) * (i + 0.5) / a.count);
  } else {
    return p.fail(jsonPath(path, "spacing"),
                  "must be \"edge\" or \"cell\" (got \"" + a.spacing + "\")");
  }
  return true;
}

bool expandValues(Parser& p, const json& g, const std::string& path, GridAxis& a) {
  if (g.contains("count") || g.contains("range") ||
      (g.contains("spacing") && g["spacing"] != "values"))
    return p.fail(path, "give either \"values\" or \"count\"/\"range\"/\"spacing\", not both");
  if (!g["values"].is_array() || g["values"].empty())
    return p.fail(jsonPath(path, "values"), "must be a non-empty array of numbers");
  a.spacing = "values";
  for (size_t i = 0; i < g["values"].size(); ++i) {
    const json& v = g["values"][i];
    if (!v.is_number() || !std::isfinite(v.get<double>()))
      return p.fail(jsonPath(jsonPath(path, "values"), i), "must be a finite number");
    a.values.push_back(v.get<double>());
  }
  a.count = static_cast<int>(a.values.size());
  a.lo = *std::min_element(a.values.begin(), a.values.end());
  a.hi = *std::max_element(a.values.begin(), a.values.end());
  return true;
}

bool parseAxis(Parser& p, const json& g, const std::string& name, const Scene& s, GridAxis& a) {
  const std::string path = jsonPath("/grid", name);
  a.name = name;
  if (!p.checkKeys(g, path, {"count", "range", "spacing", "values"})) return false;
  const bool ok =
      g.contains("values") ? expandValues(p, g, path, a) : expandCounted(p, g, path, s, a);
  if (!ok) return false;
  const Domain d = domainOf(name);
  for (const double v : a.values)
    if (v < d.lo || v > d.hi || (d.hi_open && v >= d.hi))
      return p.fail(path, "value " + fmt(v) + " outside the domain [" + fmt(d.lo) + ", " +
                              fmt(d.hi) + (d.hi_open ? ")" : "]"));
  return true;
}

// The table is the Cartesian product: bounded before anything of that size is allocated.
bool checkGridSize(Parser& p, const Scene& s) {
  double cells = 1;
  std::string dims;
  for (const auto& a : s.grid) {
    cells *= static_cast<double>(a.values.size());
    dims += (dims.empty() ? "" : " x ") + std::to_string(a.values.size());
  }
  if (cells > static_cast<double>(kMaxSceneCells))
    return p.fail("/grid", dims + " = " + fmt(cells) + " cells, more than the limit of " +
                               std::to_string(kMaxSceneCells) + " (kMaxSceneCells)");
  return true;
}

bool parseGrid(Parser& p, const json& j, Scene& s) {
  const std::vector<std::string> inputs = tableInputs(s);
  if (!j.contains("grid") || !j["grid"].is_object())
    return p.fail("/grid", "must be an object with one entry per input (" + listed(inputs) + ")");
  for (auto it = j["grid"].begin(); it != j["grid"].end(); ++it)
    if (std::find(inputs.begin(), inputs.end(), it.key()) == inputs.end())
      return p.fail(jsonPath("/grid", it.key()),
                    "not an input of the requested outputs (inputs: " + listed(inputs) + ")");
  for (const auto& name : inputs) {
    if (!j["grid"].contains(name))
      return p.fail(jsonPath("/grid", name), "missing (every input needs a grid)");
    GridAxis a;
    if (!parseAxis(p, j["grid"][name], name, s, a)) return false;
    s.grid.push_back(std::move(a));
  }
  return checkGridSize(p, s);
}

// Points where an output has no finite value, or no definition, on the grid.
bool validateGridPoints(Parser& p, const Scene& s) {
  auto lowest = [](const GridAxis* a) {
    return *std::min_element(a->values.begin(), a->values.end());
  };
  const GridAxis* eta = s.axis("eta");
  if (eta && (s.wants("E_refl") || s.wants("E_trans") || s.wants("E_dielectric")) &&
      lowest(eta) < 1)
    return p.fail("/grid/eta",
                  "E_refl, E_trans and E_dielectric are defined for eta >= 1 (the "
                  "view outside the denser medium; got " +
                      fmt(lowest(eta)) + ")");
  const GridAxis* mu = s.axis("mu");
  const GridAxis* r = s.axis("r");
  if (s.wants("E_sheen") && mu && r && lowest(mu) <= 0 && s.material.alpha(lowest(r)) <= 0)
    return p.fail("/grid",
                  "E_sheen diverges at mu = 0 with alpha = 0 (it grows like "
                  "alpha^(-1/2) at grazing view); leave out mu = 0 or r = 0");
  return true;
}

bool parseAccuracy(Parser& p, const json& j, Scene& s) {
  if (!j.contains("accuracy")) return true;
  const json& a = j["accuracy"];
  if (!p.checkKeys(a, "/accuracy", {"abs_error", "integrator", "gauss_order", "qmc_points"}) ||
      !p.number(a, "abs_error", "/accuracy", s.accuracy.abs_error) ||
      !p.enumField(a, "integrator", "/accuracy", s.accuracy.integrator,
                   "\"adaptive\", \"gauss\", \"qmc\"") ||
      !p.integer(a, "gauss_order", "/accuracy", s.accuracy.gauss_order, 2, 128) ||
      !p.integer(a, "qmc_points", "/accuracy", s.accuracy.qmc_points, 64, 1 << 24))
    return false;
  if (!(s.accuracy.abs_error >= 1e-12 && s.accuracy.abs_error <= 0.1))
    return p.fail("/accuracy/abs_error",
                  "must be in [1e-12, 0.1] (got " + fmt(s.accuracy.abs_error) + ")");
  return true;
}

Expected<Scene> parseSceneImpl(const json& j, const std::string& origin) {
  Parser p{origin, {}};
  Scene s;
  const bool ok = parseHeader(p, j, s) && parseMaterial(p, j, s) && parseLight(p, j, s) &&
                  parseOutputs(p, j, s) && validateOutputs(p, s) && parseGrid(p, j, s) &&
                  validateGridPoints(p, s) && parseAccuracy(p, j, s);
  if (!ok) return Status::error(p.err);
  return s;
}
}  // namespace

Expected<Scene> parseScene(const json& j, const std::string& origin) {
  try {  // every field is type-checked; this only guards against a check that was missed
    return parseSceneImpl(j, origin);
  } catch (const json::exception& e) {
    return Status::error(origin + ": malformed scene: " + e.what());
  }
}

Expected<Scene> loadScene(const std::filesystem::path& path) {
  auto text = readDataFile(path, kMaxSceneFileBytes);  // inside lgpd's allowed_data_dirs
  if (!text) return text.status();
  auto j = parseJson(*text);
  if (!j) return Status::error(path.string() + ": " + j.error());
  return parseScene(*j, path.string());
}

json toJson(const Scene& s) {
  json j;
  j["format"] = "lgp-scene/1";
  j["name"] = s.name;
  j["material"] = {{"ndf", toString(s.material.ndf)},
                   {"visibility", toString(s.material.visibility)},
                   {"fresnel", {{"model", toString(s.material.fresnel)}, {"f90", s.material.f90}}},
                   {"roughness", toString(s.material.roughness)},
                   {"diffuse", toString(s.material.diffuse)}};
  // Only where it matters (or is set), so that older scenes keep their canonical form and key.
  if (s.wants("E_trans") || s.wants("E_dielectric") ||
      s.material.transmission != Transmission::Flux)
    j["material"]["transmission"] = toString(s.material.transmission);
  if (s.light.type == LightType::Sphere) {
    j["light"] = {{"type", "sphere"},
                  {"size", s.light.size},
                  {"range", {s.light.range_lo, s.light.range_hi}},
                  {"softmin_s", s.light.softmin_s},
                  {"incidence", "normal"}};
  } else {
    j["light"] = {{"type", "environment"}};
  }
  j["outputs"] = s.outputs;
  j["grid"] = json::object();
  for (const auto& a : s.grid) {
    json g = {{"spacing", a.spacing}};
    if (a.spacing == "values") {
      g["values"] = a.values;
    } else {
      g["count"] = a.count;
      g["range"] = {a.lo, a.hi};
    }
    j["grid"][a.name] = g;
  }
  j["accuracy"] = {{"abs_error", s.accuracy.abs_error},
                   {"integrator", toString(s.accuracy.integrator)},
                   {"gauss_order", s.accuracy.gauss_order},
                   {"qmc_points", s.accuracy.qmc_points}};
  return j;
}

}  // namespace lgp::datasets
