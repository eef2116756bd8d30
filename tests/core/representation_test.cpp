// The search-4 representations (the output layer, program.genes, and weighted operands,
// search.variation.weight_rate), alone and together, with what every run relies on: a
// checkpoint resumes to the uninterrupted run's front, the semantic cache changes no figure,
// and `lgp run` takes them with the exhaustive cheap end, a checkpoint and a resume.
#include <gtest/gtest.h>

#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "../shell.hpp"
#include "lgp/config/config.hpp"
#include "lgp/eval/fidelity.hpp"
#include "lgp/io/result.hpp"
#include "lgp/search/search.hpp"
#include "test_tables.hpp"

namespace lgp {
namespace {

namespace fs = std::filesystem;

struct Variant {
  const char* name;
  int genes;
  double weight_rate;
};
const Variant kVariants[] = {{"genes3", 3, 0}, {"weights", 1, 0.3}, {"genes3_weights", 3, 0.3}};

nlohmann::json variantJson(const Variant& v) {
  return {{"data", {{"path", "t.csv"}, {"outputs", {"y"}}}},
          {"program", {{"max_length", 16}, {"constants", 10}, {"genes", v.genes}}},
          {"search",
           {{"population", 64},
            {"generations", 12},
            {"seed", 4},
            {"threads", 2},
            {"linear_scaling", true},
            {"variation", {{"weight_rate", v.weight_rate}, {"weight_min_length", 0}}}}}};
}

RunConfig variantConfig(const Variant& v) {
  auto c = parseRunConfig(variantJson(v), ".");
  EXPECT_TRUE(c.hasValue()) << c.error();
  return *c;
}

nlohmann::json members(const Search& s) {
  return frontToJson(s, s.front())["members"];
}

class Representation : public ::testing::TestWithParam<Variant> {};

TEST_P(Representation, CheckpointResumesToTheUninterruptedFront) {
  const RunConfig c = variantConfig(GetParam());
  const Table t = test::gridTable(12);
  Search full(c, t);
  full.run();
  Search first(c, t);
  for (int g = 0; g < 5; ++g) first.step();
  Search resumed(c, t);
  ASSERT_TRUE(resumed.restore(nlohmann::json::parse(first.checkpoint().dump())));
  resumed.run();
  EXPECT_EQ(members(resumed), members(full));
  EXPECT_EQ(resumed.progress().evaluations, full.progress().evaluations);
  // Every member exports what it scored (float32 and double agree within the bound), and
  // the layer is materialised: one output per table output.
  const double tol = fidelityTolerances(t)[0];
  for (const auto& e : full.front()) {
    EXPECT_EQ(e.program.outputs.size(), 1u) << e.formula;
    EXPECT_NEAR(e.metrics[0].rmse, e.metrics_ref[0].rmse, tol) << e.formula;
  }
}

TEST_P(Representation, SemanticCacheChangesNoFigure) {
  RunConfig on = variantConfig(GetParam());
  on.search.semantic_cache = 1 << 12;
  RunConfig off = on;
  off.search.semantic_cache = 0;
  const Table t = test::gridTable(12);
  Search a(on, t), b(off, t);
  a.run();
  b.run();
  EXPECT_EQ(members(a), members(b));
  EXPECT_EQ(a.progress().evaluations, b.progress().evaluations);
  EXPECT_GT(a.refineStats().cache_score_hits, 0u);
}

INSTANTIATE_TEST_SUITE_P(Variants, Representation, ::testing::ValuesIn(kVariants),
                         [](const auto& variant) { return std::string(variant.param.name); });

// `lgp run` with both representations, the exhaustive enumeration and checkpoints: the
// enumeration seeds the islands, the front reproduces its scores, and a resumed run writes the
// uninterrupted run's front.
TEST(RepresentationCli, ExhaustiveCheckpointAndResume) {
  const fs::path dir = fs::temp_directory_path() / ("lgp_repr_" + std::to_string(getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  {
    std::ofstream csv(dir / "t.csv");
    csv << "mu,r,y\n";
    const Table t = test::gridTable(12);
    for (size_t i = 0; i < t.rows(); ++i)
      csv << t.inputs[0][i] << "," << t.inputs[1][i] << "," << t.outputs[0][i] << "\n";
  }
  auto config = [&](const std::string& name, int generations) {
    nlohmann::json j = variantJson(kVariants[2]);
    j["data"]["inputs"] = {"mu", "r"};
    j["search"]["generations"] = generations;
    j["search"]["exhaustive"] = {{"max_ops", 2}, {"seconds", 20}};
    j["output"] = {{"front_json", (dir / (name + "_front.json")).string()},
                   {"front_csv", ""},
                   {"checkpoint", (dir / (name + ".ckpt")).string()},
                   {"checkpoint_interval_s", 0.01}};
    std::ofstream(dir / (name + ".json")) << j.dump();
    return (dir / (name + ".json")).string();
  };
  const std::string lgp = LGP_CLI_PATH;
  const auto whole = lgp_test::sh(lgp + " run " + config("whole", 12) + " -q");
  ASSERT_EQ(whole.code, 0) << whole.out;
  // The same run in two parts: 5 generations, then resumed from its checkpoint to 12.
  const auto part = lgp_test::sh(lgp + " run " + config("part", 5) + " -q");
  ASSERT_EQ(part.code, 0) << part.out;
  config("part", 12);
  const auto rest = lgp_test::sh(lgp + " run " + (dir / "part.json").string() + " --resume -q");
  ASSERT_EQ(rest.code, 0) << rest.out;
  auto read = [&](const std::string& name) {
    std::ifstream in(dir / (name + "_front.json"));
    return nlohmann::json::parse(in);
  };
  const auto a = read("whole"), b = read("part");
  ASSERT_TRUE(a.contains("exhaustive")) << a.dump().substr(0, 400);
  EXPECT_GT(a["exhaustive"]["fitted"].get<double>(), 0);
  // The enumeration scores its one-gene expressions as one gene (the layer's three read as 0
  // error and seeded `y = mu`): no expression of two operators fits this table exactly.
  for (const auto& lvl : a["exhaustive"]["best"])
    EXPECT_GT(lvl["error"].get<double>(), 1e-3) << lvl.dump();
  EXPECT_GE(a["exhaustive"]["seeded"].get<int>(), 2);
  ASSERT_FALSE(a["members"].empty());
  EXPECT_EQ(a["members"], b["members"]);
  for (const auto& m : a["members"]) {
    ASSERT_EQ(m["outputs"].size(), 1u);
    const auto& o = m["outputs"][0];
    EXPECT_NEAR(o["float32"]["rmse"].get<double>(), o["double"]["rmse"].get<double>(),
                1e-4 * (1 + o["double"]["rmse"].get<double>()))
        << o.dump();
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace lgp
