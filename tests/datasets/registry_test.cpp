// Registry coverage of the scene outputs (structure, round 2): every catalogue output
// (outputs.hpp) has an evaluator that writes it (a non-zero table, not a column of zeros), its
// name changes the cache key, and every key the scene parser reads reaches the scene's JSON,
// and so the cache key (a parameter missing there would serve one scene's table for another).
#include <gtest/gtest.h>

#include <set>
#include <string>

#include "lgp/config/json_reader.hpp"
#include "lgp/datasets/generate.hpp"
#include "lgp/datasets/outputs.hpp"
#include "lgp/datasets/scene.hpp"

namespace lgp::datasets {
namespace {

using nlohmann::json;

// The smallest scene of one output: a 3-point grid per input, coarse accuracy.
json sceneOf(const OutputSpec& o) {
  json s = {{"outputs", {o.name}}, {"accuracy", {{"abs_error", 1e-4}}}};
  json grid = json::object();
  for (const auto& in : o.inputs) {
    if (in == "size") {
      s["light"] = {{"type", "sphere"}, {"size", "theta_s"}, {"range", {0, 1}}};
      grid["theta_s"] = {{"values", {0.1, 0.3, 0.6}}};
    } else if (in == "eta") {
      grid["eta"] = {{"values", {1.2, 1.5, 2.0}}};
    } else {
      grid[in] = {{"values", {0.25, 0.5, 0.9}}};
    }
  }
  s["grid"] = grid;
  switch (o.effect) {
    case Effect::Fresnel:
      s["material"] = {{"fresnel", {{"model", "schlick"}, {"f90", 1}}}};
      break;
    case Effect::Dielectric:
      s["material"] = {{"fresnel", {{"model", "dielectric"}}}};
      break;
    case Effect::Specular:
    case Effect::Energy:
    case Effect::Diffuse:
    case Effect::Normalization:
    case Effect::Sheen:
    case Effect::DiffuseAlbedo:
      break;
  }
  return s;
}

TEST(SceneRegistry, EveryOutputIsCatalogedOnceInEnumOrder) {
  ASSERT_EQ(outputCatalog().size(), kNumOutputs);
  std::set<std::string> names;
  for (size_t i = 0; i < kNumOutputs; ++i) {
    const OutputSpec& o = outputCatalog()[i];
    EXPECT_EQ(static_cast<size_t>(o.id), i) << o.name;
    EXPECT_TRUE(names.insert(o.name).second) << o.name;
    EXPECT_EQ(findOutput(o.name), &o);
    EXPECT_FALSE(o.definition.empty()) << o.name;
  }
}

TEST(SceneRegistry, EveryOutputGeneratesANonZeroTableAndKeysTheCache) {
  std::set<std::string> keys;
  for (const auto& o : outputCatalog()) {
    auto s = parseScene(sceneOf(o), o.name);
    ASSERT_TRUE(s) << s.error();
    auto g = generate(*s);
    ASSERT_TRUE(g) << o.name << ": " << g.error();
    double largest = 0;
    for (double v : g->table.outputs[0]) largest = std::max(largest, std::fabs(v));
    EXPECT_GT(largest, 0.0) << o.name << ": every value is 0 (no evaluator writes it?)";
    EXPECT_TRUE(keys.insert(cacheKey(*s)).second) << o.name << " shares a cache key";
  }
}

// Scenes that between them set every key the parser knows.
std::vector<json> fullScenes() {
  return {json::parse(R"({"format": "lgp-scene/1", "name": "a", "description": "d",
            "material": {"ndf": "ggx", "visibility": "schlick-smith",
                         "fresnel": {"model": "schlick", "f90": 0.5}, "roughness": "linear",
                         "diffuse": "lambert", "transmission": "radiance"},
            "light": {"type": "environment"}, "outputs": ["A", "B", "ZH0"],
            "grid": {"mu": {"count": 3, "range": [0.1, 1], "spacing": "cell"},
                     "r": {"values": [0.2, 0.5]}},
            "accuracy": {"abs_error": 1e-5, "integrator": "gauss", "gauss_order": 12,
                         "qmc_points": 4096}})"),
          json::parse(R"({"light": {"type": "sphere", "size": "tan_half_theta_s",
                                     "range": [0, 0.9], "softmin_s": -2, "incidence": "normal"},
            "outputs": ["N"], "grid": {"r": {"count": 3}, "tan_half_theta_s": {"count": 3}}})")};
}

// The leaf paths of a JSON value.
void leaves(const json& j, const std::string& at, std::set<std::string>& out) {
  if (!j.is_object() || j.empty()) {
    out.insert(at);
    return;
  }
  for (auto it = j.begin(); it != j.end(); ++it) leaves(it.value(), jsonPath(at, it.key()), out);
}

TEST(SceneRegistry, EveryParsedKeyReachesTheSceneJsonAndTheCacheKey) {
  std::set<std::string> known, reached;
  for (const json& full : fullScenes()) {
    JsonKeyRecorder rec;
    auto s = parseScene(full, "full");
    ASSERT_TRUE(s) << s.error();
    known.insert(rec.keys().begin(), rec.keys().end());
    leaves(toJson(*s), "", reached);
    // Each key set in the test changes the cache key when it is left to its default.
    std::set<std::string> set;
    leaves(full, "", set);
    for (const auto& k : set) {
      if (k == "/description" || k == "/format" || k.rfind("/grid/", 0) == 0) continue;
      json j = full;
      const json::json_pointer ptr(k);
      j[ptr.parent_pointer()].erase(ptr.back());
      auto d = parseScene(j, "default");
      if (!d) continue;  // a required key
      if (toJson(*d) == toJson(*s)) continue;  // the test's value is the default
      EXPECT_NE(cacheKey(*d), cacheKey(*s)) << k << " does not change the cache key";
    }
  }
  // Every key the parser knows is written by toJson (a grid axis's name is a key of /grid;
  // the description is free text and is not part of the scene's identity).
  for (const auto& k : known) {
    if (k == "/description" || k.rfind("/grid/", 0) == 0) continue;
    bool found = reached.count(k) > 0;
    for (const auto& r : reached) found = found || r.rfind(k + "/", 0) == 0;
    EXPECT_TRUE(found) << "the scene parser reads " << k << ", which toJson(Scene) does not write";
  }
}

}  // namespace
}  // namespace lgp::datasets
