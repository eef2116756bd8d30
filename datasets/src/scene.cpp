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

const std::vector<std::string> kMuR = {"mu", "r"};
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
  return {0.0, 1.0, false};  // mu, r
}
}  // namespace

const std::vector<std::string>& knownOutputs() {
  static const std::vector<std::string> k = {"A",    "B",   "E",   "one_minus_E",  "E_avg",
                                             "ZH0",  "ZH1", "ZH2", "ZH1_over_ZH0", "ZH2_over_ZH0",
                                             "beta", "N"};
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

bool Scene::needs(Effect e) const {
  switch (e) {
    case Effect::Specular:
      return wants("A") || wants("B") || wants("E") || wants("one_minus_E") || wants("E_avg") ||
             wants("N");
    case Effect::Fresnel:
      return wants("A") || wants("B");
    case Effect::Energy:
      return wants("one_minus_E") || wants("E_avg");
    case Effect::Diffuse:
      return wants("ZH0") || wants("ZH1") || wants("ZH2") || wants("ZH1_over_ZH0") ||
             wants("ZH2_over_ZH0") || wants("beta");
    case Effect::Normalization:
      return wants("N");
  }
  return false;
}

static Expected<Scene> parseSceneImpl(const json& j, const std::string& origin) {
  Parser p{origin, {}};
  Scene s;
  if (!p.checkKeys(
          j, "",
          {"format", "name", "description", "material", "light", "outputs", "grid", "accuracy"}))
    return Status::error(p.err);
  if (j.contains("format") && j["format"] != "lgp-scene/1") {
    p.fail("/format", "must be \"lgp-scene/1\" (got " + j["format"].dump() + ")");
    return Status::error(p.err);
  }
  if (j.contains("name")) {
    if (!j["name"].is_string()) {
      p.fail("/name", "must be a string");
      return Status::error(p.err);
    }
    s.name = j["name"].get<std::string>();
  }
  // material
  if (j.contains("material")) {
    const json& m = j["material"];
    if (!p.checkKeys(m, "/material", {"ndf", "visibility", "fresnel", "roughness", "diffuse"}) ||
        !p.enumField(m, "ndf", "/material", s.material.ndf, "\"ggx\"") ||
        !p.enumField(m, "visibility", "/material", s.material.visibility,
                     "\"smith-correlated\", \"schlick-smith\"") ||
        !p.enumField(m, "roughness", "/material", s.material.roughness,
                     "\"perceptual\", \"linear\"") ||
        !p.enumField(m, "diffuse", "/material", s.material.diffuse, "\"disney\", \"lambert\""))
      return Status::error(p.err);
    if (m.contains("fresnel")) {
      const json& f = m["fresnel"];
      if (f.is_string()) {
        json wrapped = {{"model", f}};
        if (!p.enumField(wrapped, "model", "/material/fresnel", s.material.fresnel,
                         "\"none\", \"schlick\""))
          return Status::error(p.err);
      } else {
        if (!p.checkKeys(f, "/material/fresnel", {"model", "f90"}) ||
            !p.enumField(f, "model", "/material/fresnel", s.material.fresnel,
                         "\"none\", \"schlick\"") ||
            !p.number(f, "f90", "/material/fresnel", s.material.f90))
          return Status::error(p.err);
        if (s.material.f90 < 0 || s.material.f90 > 1) {
          p.fail("/material/fresnel/f90", "must be in [0, 1] (got " + fmt(s.material.f90) + ")");
          return Status::error(p.err);
        }
      }
    }
  }
  // light
  if (j.contains("light")) {
    const json& l = j["light"];
    if (!p.checkKeys(l, "/light", {"type", "size", "range", "softmin_s", "incidence"}))
      return Status::error(p.err);
    if (l.contains("type") && !l["type"].is_string()) {
      p.fail("/light/type", "must be \"environment\" or \"sphere\" (got " + l["type"].dump() + ")");
      return Status::error(p.err);
    }
    const std::string type = l.value("type", std::string("environment"));
    if (type == "environment") {
      s.light.type = LightType::Environment;
      for (const char* k : {"size", "range", "softmin_s", "incidence"})
        if (l.contains(k)) {
          p.fail(jsonPath("/light", k), "only valid for a sphere light");
          return Status::error(p.err);
        }
    } else if (type == "sphere") {
      s.light.type = LightType::Sphere;
      if (l.contains("size")) {
        if (!l["size"].is_string() || (l["size"] != "theta_s" && l["size"] != "tan_half_theta_s")) {
          p.fail("/light/size",
                 "must be \"theta_s\" or \"tan_half_theta_s\" (got " + l["size"].dump() + ")");
          return Status::error(p.err);
        }
        s.light.size = l["size"].get<std::string>();
      }
      const Domain d = domainOf(s.light.size);
      s.light.range_lo = d.lo;
      s.light.range_hi = s.light.size == "theta_s" ? 1.2 : 0.6;
      if (l.contains("range") &&
          !p.range(l["range"], "/light/range", s.light.range_lo, s.light.range_hi))
        return Status::error(p.err);
      if (s.light.range_lo < d.lo || s.light.range_hi >= d.hi) {
        p.fail("/light/range", "must lie in [0, " + fmt(d.hi) + ") for " + s.light.size);
        return Status::error(p.err);
      }
      if (!p.number(l, "softmin_s", "/light", s.light.softmin_s)) return Status::error(p.err);
      if (!(s.light.softmin_s < 0)) {
        p.fail("/light/softmin_s", "must be < 0 (got " + fmt(s.light.softmin_s) + ")");
        return Status::error(p.err);
      }
      if (l.contains("incidence") && l["incidence"] != "normal") {
        p.fail("/light/incidence",
               "only \"normal\" is implemented (got " + l["incidence"].dump() + ")");
        return Status::error(p.err);
      }
    } else {
      p.fail("/light/type", "must be \"environment\" or \"sphere\" (got \"" + type + "\")");
      return Status::error(p.err);
    }
  }
  // outputs
  if (!j.contains("outputs") || !j["outputs"].is_array() || j["outputs"].empty()) {
    p.fail("/outputs", "must be a non-empty array of output names");
    return Status::error(p.err);
  }
  for (size_t i = 0; i < j["outputs"].size(); ++i) {
    const json& o = j["outputs"][i];
    const std::string path = jsonPath("/outputs", i);
    const auto& known = knownOutputs();
    if (!o.is_string() ||
        std::find(known.begin(), known.end(), o.get<std::string>()) == known.end()) {
      std::string list;
      for (const auto& k : known) list += (list.empty() ? "" : ", ") + k;
      p.fail(path, "unknown output " + o.dump() + " (known: " + list + ")");
      return Status::error(p.err);
    }
    if (s.wants(o.get<std::string>())) {
      p.fail(path, "duplicate output " + o.dump());
      return Status::error(p.err);
    }
    s.outputs.push_back(o.get<std::string>());
  }
  const bool has_n = s.wants("N");
  if (has_n && s.outputs.size() > 1) {
    p.fail("/outputs", "\"N\" has inputs (r, " + s.light.size +
                           ") and cannot share a table with outputs over (mu, r)");
    return Status::error(p.err);
  }
  if (has_n && s.light.type != LightType::Sphere) {
    p.fail("/light/type", "output \"N\" needs a sphere light");
    return Status::error(p.err);
  }
  if (s.needs(Effect::Fresnel) && s.material.fresnel == FresnelModel::None) {
    p.fail("/material/fresnel",
           "outputs \"A\"/\"B\" are the Fresnel split; they need "
           "\"schlick\" (use \"E\" with Fresnel off)");
    return Status::error(p.err);
  }
  const std::vector<std::string> inputs =
      has_n ? std::vector<std::string>{"r", s.light.size} : kMuR;
  // grid
  if (!j.contains("grid") || !j["grid"].is_object()) {
    p.fail("/grid",
           "must be an object with one entry per input (" + inputs[0] + ", " + inputs[1] + ")");
    return Status::error(p.err);
  }
  for (auto it = j["grid"].begin(); it != j["grid"].end(); ++it)
    if (std::find(inputs.begin(), inputs.end(), it.key()) == inputs.end()) {
      p.fail(jsonPath("/grid", it.key()), "not an input of the requested outputs (inputs: " +
                                              inputs[0] + ", " + inputs[1] + ")");
      return Status::error(p.err);
    }
  for (const auto& name : inputs) {
    const std::string path = jsonPath("/grid", name);
    if (!j["grid"].contains(name)) {
      p.fail(path, "missing (every input needs a grid)");
      return Status::error(p.err);
    }
    const json& g = j["grid"][name];
    GridAxis a;
    a.name = name;
    const Domain d = domainOf(name);
    if (!p.checkKeys(g, path, {"count", "range", "spacing", "values"})) return Status::error(p.err);
    if (g.contains("values")) {
      if (g.contains("count") || g.contains("range") ||
          (g.contains("spacing") && g["spacing"] != "values")) {
        p.fail(path, "give either \"values\" or \"count\"/\"range\"/\"spacing\", not both");
        return Status::error(p.err);
      }
      if (!g["values"].is_array() || g["values"].empty()) {
        p.fail(jsonPath(path, "values"), "must be a non-empty array of numbers");
        return Status::error(p.err);
      }
      a.spacing = "values";
      for (size_t i = 0; i < g["values"].size(); ++i) {
        const json& v = g["values"][i];
        if (!v.is_number() || !std::isfinite(v.get<double>())) {
          p.fail(jsonPath(jsonPath(path, "values"), i), "must be a finite number");
          return Status::error(p.err);
        }
        a.values.push_back(v.get<double>());
      }
      a.count = static_cast<int>(a.values.size());
      a.lo = *std::min_element(a.values.begin(), a.values.end());
      a.hi = *std::max_element(a.values.begin(), a.values.end());
    } else {
      if (!g.contains("count")) {
        p.fail(jsonPath(path, "count"), "missing");
        return Status::error(p.err);
      }
      if (!p.integer(g, "count", path, a.count, 1, 100000)) return Status::error(p.err);
      a.lo = d.lo;
      a.hi = d.hi_open ? 0.0 : d.hi;
      if (name == s.light.size && has_n) {
        a.lo = s.light.range_lo;
        a.hi = s.light.range_hi;
      }
      if (g.contains("range") && !p.range(g["range"], jsonPath(path, "range"), a.lo, a.hi))
        return Status::error(p.err);
      if (g.contains("spacing") && !g["spacing"].is_string()) {
        p.fail(jsonPath(path, "spacing"),
               "must be \"edge\" or \"cell\" (got " + g["spacing"].dump() + ")");
        return Status::error(p.err);
      }
      a.spacing = g.value("spacing", std::string("edge"));
      if (a.spacing == "edge") {
        if (a.count == 1) {
          a.values = {a.lo};
        } else {
          for (int i = 0; i < a.count; ++i)
            a.values.push_back(i + 1 == a.count ? a.hi
                                                : a.lo + (a.hi - a.lo) * i / (a.count - 1.0));
        }
      } else if (a.spacing == "cell") {
        for (int i = 0; i < a.count; ++i)
          a.values.push_back(a.lo + (a.hi - a.lo) * (i + 0.5) / a.count);
      } else {
        p.fail(jsonPath(path, "spacing"),
               "must be \"edge\" or \"cell\" (got \"" + a.spacing + "\")");
        return Status::error(p.err);
      }
    }
    for (size_t i = 0; i < a.values.size(); ++i) {
      const double v = a.values[i];
      if (v < d.lo || v > d.hi || (d.hi_open && v >= d.hi)) {
        p.fail(path, "value " + fmt(v) + " outside the domain [" + fmt(d.lo) + ", " + fmt(d.hi) +
                         (d.hi_open ? ")" : "]"));
        return Status::error(p.err);
      }
    }
    s.grid.push_back(a);
  }
  // The table is the Cartesian product: bounded before anything of that size is allocated.
  {
    double cells = 1;
    std::string dims;
    for (const auto& a : s.grid) {
      cells *= static_cast<double>(a.values.size());
      dims += (dims.empty() ? "" : " x ") + std::to_string(a.values.size());
    }
    if (cells > static_cast<double>(kMaxSceneCells)) {
      p.fail("/grid", dims + " = " + fmt(cells) + " cells, more than the limit of " +
                          std::to_string(kMaxSceneCells) + " (kMaxSceneCells)");
      return Status::error(p.err);
    }
  }
  // accuracy
  if (j.contains("accuracy")) {
    const json& a = j["accuracy"];
    if (!p.checkKeys(a, "/accuracy", {"abs_error", "integrator", "gauss_order", "qmc_points"}) ||
        !p.number(a, "abs_error", "/accuracy", s.accuracy.abs_error) ||
        !p.enumField(a, "integrator", "/accuracy", s.accuracy.integrator,
                     "\"adaptive\", \"gauss\", \"qmc\"") ||
        !p.integer(a, "gauss_order", "/accuracy", s.accuracy.gauss_order, 2, 128) ||
        !p.integer(a, "qmc_points", "/accuracy", s.accuracy.qmc_points, 64, 1 << 24))
      return Status::error(p.err);
    if (!(s.accuracy.abs_error >= 1e-12 && s.accuracy.abs_error <= 0.1)) {
      p.fail("/accuracy/abs_error",
             "must be in [1e-12, 0.1] (got " + fmt(s.accuracy.abs_error) + ")");
      return Status::error(p.err);
    }
  }
  return s;
}

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
