// Every field of the run config round-trips and reaches the checkpoint digest (structure,
// round 2). The parser's own key list (JsonKeyRecorder) is the list of fields: a field the
// parser learns without this test's full config setting it, without toJson writing it, or
// without the digest seeing it, fails here by name.
//
// The digest rule (io/checkpoint.hpp configDigest): every field of toJson but where results go
// (output), how ranks talk (mpi) and what a resume may extend or does not change the result
// (search.threads, search.generations, search.max_evaluations, search.wall_time_s,
// search.semantic_cache).
#include <gtest/gtest.h>

#include <optional>
#include <set>
#include <string>

#include "lgp/config/config.hpp"
#include "lgp/config/json_reader.hpp"
#include "lgp/io/checkpoint.hpp"
#include "test_tables.hpp"

namespace lgp {
namespace {

using nlohmann::json;

// Every field set away from its default (and consistent with the others).
json fullConfig() {
  return json::parse(R"({
    "data": {"path": "t.csv", "inputs": ["x", "y"], "outputs": ["f"], "weights": "w",
             "cache_dir": "-", "transforms": {"f": "sqrt"},
             "edges": {"domain": {"x": [0.001, 2]}, "weight": 0.5}},
    "program": {"max_length": 40, "constants": 12, "output_mode": "designated",
                "ops": ["add", "mul", "exp2", "sin"], "init_min_length": 3, "init_max_length": 9,
                "const_min": -3, "const_max": 4, "genes": 2},
    "objectives": {"error": "mae", "combine": "max", "rel_floor": 1e-4, "cost_model": "rdna",
                   "cost_overrides": {"add": 0.5}, "discontinuity_weights": {"min": 2},
                   "channels": [{"name": "c", "weights": {"f": 2}}],
                   "measured_cost": {"families": ["rdna2"], "in_search": false}},
    "search": {"population": 64, "generations": 7, "max_evaluations": 12345,
               "wall_time_s": 99, "seed": 42, "threads": 1, "tournament_size": 3,
               "error_bias": 0.25, "cost_strata": 3, "semantic_cache": 1024,
               "linear_scaling": true, "seed_references": true,
               "multi_output": {"mode": "joint", "first": "f", "first_share": 0.4,
                                "first_max_cost": 9},
               "islands": {"count": 3, "migration_interval": 7, "migrants": 3, "restart_after": 9,
                           "adaptive": 0.5, "adaptive_halflife": 20, "deal": "interleaved", "topology": "by_profile",
                           "profiles": [{"max_length": 20, "constants": 5, "weight_rate": 0.3,
                                         "share": 2, "error_bias": 0.7, "cost_strata": 2}]},
               "variation": {"crossover_rate": 0.4, "macro_rate": 0.3, "micro_rate": 0.2,
                             "micro_max": 3, "constant_sigma": 0.2, "effective_bias": 0.6,
                             "wrap_share": 0.1, "weight_rate": 0.2, "weight_min_length": 5},
               "refine": {"offspring_share": 0.3, "lm_iterations": 7, "archive_lm_iterations": 9,
                          "offspring_evaluations": 77, "archive_period": 3, "archive_max": 5,
                          "archive_order": "oldest", "max_evaluations": 321, "restarts": 2,
                          "initial_step": 0.2, "tolerance": 1e-7, "method": "de+nm",
                          "de_evaluations": 111, "lm_metric": "least_squares"},
               "archive": {"max_size": 123, "eps_log10_error": 0.01, "eps_cost": 0.2,
                           "eps_discontinuity": 0.3},
               "exhaustive": {"max_ops": 2, "ops": ["add", "mul"], "constants": 2,
                              "seconds": 3, "screen_rows": 64, "keep": 5},
               "structured": {"max_degree": 3, "rational": false, "exp2": false,
                              "sqrt_inputs": false, "square_inputs": false, "tensor": false,
                              "polish": 7, "max_rows": 1000, "share": 0.5},
               "stages": {"islands": 2, "population": 20, "retarget": 7, "max_length": 12,
                          "constants": 4, "modes": ["mul", "inside"], "bases": 3,
                          "pick": "spread"}},
    "eval": {"block_size": 64},
    "output": {"front_json": "f.json", "front_csv": "f.csv", "progress_interval_s": 2,
               "progress_cost_levels": [3, 9], "checkpoint": "c.json",
               "checkpoint_interval_s": 30},
    "mpi": {"np": 2, "migration": "sync"},
    "references": [{"name": "r", "expr": "f = x*y"}]
  })");
}

// The leaf paths of a JSON value (objects are walked; arrays and scalars are leaves).
void leaves(const json& j, const std::string& at, std::set<std::string>& out) {
  if (!j.is_object() || j.empty()) {
    out.insert(at);
    return;
  }
  for (auto it = j.begin(); it != j.end(); ++it) leaves(it.value(), jsonPath(at, it.key()), out);
}

// The keys the parser reads that hold values (not objects it walks into), with array entries
// ("/0/") folded: the parser's field list.
std::set<std::string> parserFields(const json& cfg) {
  JsonKeyRecorder rec;
  auto c = parseRunConfig(cfg, ".");
  EXPECT_TRUE(c) << c.error();
  std::set<std::string> fields;
  for (const auto& k : rec.keys()) {
    bool parent = false;
    for (const auto& other : rec.keys())
      parent = parent || (other.size() > k.size() && other.compare(0, k.size() + 1, k + "/") == 0);
    if (!parent) fields.insert(k);
  }
  return fields;
}

const json* at(const json& j, const std::string& pointer) {
  const json::json_pointer p(pointer);
  return j.contains(p) ? &j.at(p) : nullptr;
}

bool digestExempt(const std::string& path) {
  for (const char* p : {"/output", "/mpi", "/search/threads", "/search/generations",
                        "/search/max_evaluations", "/search/wall_time_s", "/search/semantic_cache"})
    if (path.rfind(p, 0) == 0) return true;
  return false;
}

TEST(ConfigRoundTrip, TheFullConfigSetsEveryFieldTheParserReads) {
  const json full = fullConfig();
  std::set<std::string> set;
  leaves(full, "", set);
  for (const auto& f : parserFields(full)) {
    // Keys of user-named maps (transforms, weights, overrides) are values, not fields.
    if (f.find("/transforms/") != std::string::npos || f.find("/weights/") != std::string::npos)
      continue;
    // Refused in a run config: the launcher and hostfile belong to whoever starts MPI.
    if (f == "/mpi/launcher" || f == "/mpi/hostfile") continue;
    // The other form of /data/path (one of the two): SceneFormRoundTrips covers it.
    if (f == "/data/scene") continue;
    EXPECT_TRUE(set.count(f) || at(full, f))
        << "the parser reads " << f << ", which fullConfig() does not set: add it";
  }
}

TEST(ConfigRoundTrip, SceneFormRoundTrips) {
  json j = fullConfig();
  j["data"].erase("path");
  j["data"]["scene"] = "s.json";
  auto c = parseRunConfig(j, ".");
  ASSERT_TRUE(c) << c.error();
  EXPECT_EQ(toJson(*c)["data"]["scene"], "s.json");
  auto again = parseRunConfig(toJson(*c), ".");
  ASSERT_TRUE(again) << again.error();
  EXPECT_EQ(toJson(*again), toJson(*c));
}

TEST(ConfigRoundTrip, ParseToJsonParseKeepsEveryField) {
  const json full = fullConfig();
  auto c1 = parseRunConfig(full, ".");
  ASSERT_TRUE(c1) << c1.error();
  const json j1 = toJson(*c1);
  auto c2 = parseRunConfig(j1, ".");
  ASSERT_TRUE(c2) << c2.error();
  EXPECT_EQ(toJson(*c2), j1);
  std::set<std::string> set;
  leaves(full, "", set);
  for (const auto& f : set) {
    const json* in = at(full, f);
    const json* out = at(j1, f);
    ASSERT_NE(out, nullptr) << "toJson does not write " << f;
    if (f.rfind("/output/", 0) == 0 && in->is_string())
      continue;  // paths are resolved against the config's directory
    EXPECT_EQ(*out, *in) << f;
  }
}

// A valid config that differs from `full` at `f` only: the field left to its default
// (removed), else its value changed (a number moved, a flag flipped, a list grown, a name or
// an enumeration changed), with the field another one must follow where there is one.
std::optional<RunConfig> variant(const json& full, const std::string& f) {
  const json::json_pointer ptr(f);
  const json base = toJson(*parseRunConfig(full, "."));
  json j = full;
  j[ptr.parent_pointer()].erase(ptr.back());
  if (auto c = parseRunConfig(j, "."); c && toJson(*c) != base) return *c;
  j = full;
  json& v = j[ptr];
  if (f == "/search/multi_output/mode")
    v = "two_step";
  else if (f == "/search/refine/archive_order")
    v = "accurate";
  else if (f == "/data/edges/domain/x")
    v = {0.002, 2};
  else if (v.is_boolean())
    v = !v.get<bool>();
  else if (v.is_number_integer())
    v = v.get<int64_t>() + 1;
  else if (v.is_number())
    v = v.get<double>() * 0.9;
  else if (v.is_array() && !v.empty() && v[0].is_string())
    v.push_back("g");
  else if (v.is_array() && !v.empty() && v[0].is_number())
    v.push_back(v.back().get<double>() + 1);
  else if (v.is_string() && !v.get<std::string>().empty())
    v = v.get<std::string>() + "2";
  else
    return std::nullopt;
  // The output layer needs linear scaling; two_step needs two outputs and one gene each.
  if (f == "/search/linear_scaling") j["program"]["genes"] = 1;
  if (f == "/search/multi_output/mode") {
    j["program"]["genes"] = 1;
    j["data"]["outputs"] = {"f", "g"};
  }
  if (auto c = parseRunConfig(j, ".")) return *c;
  return std::nullopt;
}

TEST(ConfigRoundTrip, EveryFieldButTheExemptOnesChangesTheDigest) {
  const json full = fullConfig();
  const Table t = test::gridTable(6);
  auto base = parseRunConfig(full, ".");
  ASSERT_TRUE(base) << base.error();
  const std::string d0 = configDigest(*base, t);
  std::set<std::string> set;
  leaves(full, "", set);
  size_t checked = 0, bound = 0;
  for (const auto& f : set) {
    bound += !digestExempt(f);
    auto c = variant(full, f);
    ASSERT_TRUE(c) << f << ": no valid config differs from the full one there: extend variant()";
    const std::string d = configDigest(*c, t);
    if (digestExempt(f)) {
      EXPECT_EQ(d, d0) << f << " is exempt from the digest (a resume may change it)";
    } else if (toJson(*c) != toJson(*base)) {
      EXPECT_NE(d, d0) << f << " changes the config but not the checkpoint digest";
      ++checked;
    } else {
      ADD_FAILURE() << f << ": its variant does not change the config (toJson leaves it out?)";
    }
  }
  EXPECT_EQ(checked, bound);
}

}  // namespace
}  // namespace lgp
