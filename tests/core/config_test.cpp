// Config validation names the JSON path; table loading names the file, row and column.
#include <gtest/gtest.h>

#include <unistd.h>
#include <filesystem>
#include <fstream>

#include "lgp/config/config.hpp"
#include "lgp/core/table.hpp"

namespace lgp {
namespace {

using nlohmann::json;

std::string errorOf(const json& j) {
  auto c = parseRunConfig(j, ".");
  return c ? std::string() : c.error();
}

json minimal() {
  return {{"data", {{"path", "t.csv"}, {"inputs", {"x"}}, {"outputs", {"y"}}}}};
}

TEST(Config, DefaultsAreValid) {
  auto c = parseRunConfig(minimal(), ".");
  ASSERT_TRUE(c) << c.error();
  EXPECT_EQ(c->search.population, 400);
  EXPECT_EQ(c->program.max_length, 96);
  EXPECT_EQ(c->program.num_constants, 48);
  EXPECT_EQ(c->search.islands.profiles.size(), 4u);
  EXPECT_EQ(c->search.islands.deal, IslandDeal::ByCost);
  EXPECT_EQ(c->objectives.cost_model, CostTarget::GpuGeneric);
  // Round trip through JSON.
  auto again = parseRunConfig(toJson(*c), ".");
  ASSERT_TRUE(again) << again.error();
  EXPECT_EQ(toJson(*again), toJson(*c));
}

TEST(Config, OutputPathsNamedInTheConfigAreRelativeToIt) {
  json j = minimal();
  j["output"] = {
      {"front_json", "out/f.json"}, {"checkpoint", "ck.json"}, {"front_csv", "/tmp/f.csv"}};
  auto c = parseRunConfig(j, "runs/dfg");
  ASSERT_TRUE(c) << c.error();
  EXPECT_EQ(c->output.front_json, "runs/dfg/out/f.json");
  EXPECT_EQ(c->output.checkpoint, "runs/dfg/ck.json");
  EXPECT_EQ(c->output.front_csv, "/tmp/f.csv");  // absolute: as written
  // Defaults stay in the working directory.
  auto d = parseRunConfig(minimal(), "runs/dfg");
  ASSERT_TRUE(d) << d.error();
  EXPECT_EQ(d->output.front_json, "front.json");
  EXPECT_EQ(d->output.checkpoint, "");
}

TEST(Config, UnknownKeyNamesItsPath) {
  json j = minimal();
  j["search"] = {{"popsize", 10}};
  EXPECT_EQ(errorOf(j), "/search/popsize: unknown key");
  j = minimal();
  j["colour"] = 1;
  EXPECT_EQ(errorOf(j), "/colour: unknown key");
}

TEST(Config, WrongTypeNamesItsPath) {
  json j = minimal();
  j["search"] = {{"population", "many"}};
  EXPECT_NE(errorOf(j).find("/search/population: must be an integer"), std::string::npos);
  j = minimal();
  j["program"] = {{"ops", {"add", 3}}};
  EXPECT_NE(errorOf(j).find("/program/ops/1"), std::string::npos);
}

TEST(Config, OutOfRangeNamesItsPath) {
  json j = minimal();
  j["search"] = {{"population", 2}};
  EXPECT_NE(errorOf(j).find("/search/population: must be in [4,"), std::string::npos);
  j = minimal();
  j["eval"] = {{"block_size", 100}};
  EXPECT_NE(errorOf(j).find("/eval/block_size: must be a multiple of 16"), std::string::npos);
  j = minimal();
  j["objectives"] = {{"cost_model", "voodoo"}};
  EXPECT_NE(errorOf(j).find("/objectives/cost_model: 'voodoo' is not one of"), std::string::npos);
  j = minimal();
  j["program"] = {{"ops", {"add", "frob"}}};
  EXPECT_NE(errorOf(j).find("/program/ops/1: unknown operator 'frob'"), std::string::npos);
  j = minimal();
  j["objectives"] = {{"cost_overrides", {{"div", -1}}}};
  EXPECT_NE(errorOf(j).find("/objectives/cost_overrides/div"), std::string::npos);
  j = minimal();
  j["search"] = {{"generations", 0}};
  EXPECT_NE(errorOf(j).find("at least one budget"), std::string::npos);
  j = minimal();
  j["search"] = {{"stages", {{"modes", {"add", "outside"}}}}};
  EXPECT_NE(errorOf(j).find("/search/stages/modes/1: 'outside' is not one of add, mul, inside"),
            std::string::npos)
      << errorOf(j);
  j = minimal();
  j["search"] = {{"stages", {{"pick", "cheap"}}}};
  EXPECT_NE(errorOf(j).find("/search/stages/pick: 'cheap' is not one of accurate, spread"),
            std::string::npos)
      << errorOf(j);
}

TEST(Config, LmMetricSwitch) {
  auto d = parseRunConfig(minimal(), ".");
  ASSERT_TRUE(d) << d.error();
  EXPECT_EQ(d->search.refine.lm_metric, LmObjective::Auto);
  EXPECT_EQ(toJson(*d)["search"]["refine"]["lm_metric"], "auto");
  json j = minimal();
  j["search"] = {{"refine", {{"lm_metric", "least_squares"}}}};
  auto c = parseRunConfig(j, ".");
  ASSERT_TRUE(c) << c.error();
  EXPECT_EQ(c->search.refine.lm_metric, LmObjective::LeastSquares);
  EXPECT_EQ(toJson(*c)["search"]["refine"]["lm_metric"], "least_squares");
  j["search"] = {{"refine", {{"lm_metric", "l1"}}}};
  EXPECT_NE(errorOf(j).find("/search/refine/lm_metric: must be \"auto\", \"configured\" or"),
            std::string::npos)
      << errorOf(j);
}

TEST(Config, DataNeedsExactlyOneSource) {
  EXPECT_NE(errorOf(json{{"data", json::object()}}).find("/data"), std::string::npos);
  EXPECT_NE(errorOf(json::object()).find("/data: required"), std::string::npos);
  EXPECT_NE(errorOf(json{{"data", {{"path", "a"}, {"scene", "b"}}}}).find("exactly one"),
            std::string::npos);
}

TEST(Config, OverridesAndTransformsApply) {
  json j = minimal();
  j["objectives"] = {{"cost_model", "gcn"},
                     {"cost_overrides", {{"div", 2.5}}},
                     {"discontinuity_weights", {{"abs", 0.25}}}};
  j["data"]["transforms"] = {{"y", "log"}};
  auto c = parseRunConfig(j, ".");
  ASSERT_TRUE(c) << c.error();
  EXPECT_EQ(c->costModel().cost[static_cast<int>(Op::Div)], 2.5);
  // The operators not overridden keep the gcn table's prices.
  EXPECT_EQ(c->costModel().cost[static_cast<int>(Op::Sqrt)],
            CostModel::preset(CostTarget::Gcn).cost[static_cast<int>(Op::Sqrt)]);
  EXPECT_NE(c->costModel().cost[static_cast<int>(Op::Sqrt)],
            CostModel::preset(CostTarget::GpuGeneric).cost[static_cast<int>(Op::Sqrt)]);
  EXPECT_EQ(c->discontinuityModel().weight[static_cast<int>(Op::Abs)], 0.25);
  EXPECT_EQ(c->errorConfig({"y"}).transforms[0], TargetTransform::Log);
  j["data"]["transforms"] = {{"z", "log"}};
  EXPECT_NE(errorOf(j).find("/data/transforms/z"), std::string::npos);
}

TEST(Config, ArchiveOrderAndIslandDeal) {
  json j = minimal();
  auto d = parseRunConfig(j, ".");
  ASSERT_TRUE(d) << d.error();
  EXPECT_EQ(d->search.refine.archive_order, ArchiveRefineOrder::Oldest);
  EXPECT_EQ(d->search.islands.deal, IslandDeal::ByCost);
  j["search"] = {{"refine", {{"archive_order", "accurate"}}},
                 {"islands", {{"deal", "interleaved"}}}};
  auto c = parseRunConfig(j, ".");
  ASSERT_TRUE(c) << c.error();
  EXPECT_EQ(c->search.refine.archive_order, ArchiveRefineOrder::Accurate);
  EXPECT_EQ(c->search.islands.deal, IslandDeal::Interleaved);
  auto again = parseRunConfig(toJson(*c), ".");
  ASSERT_TRUE(again) << again.error();
  EXPECT_EQ(toJson(*again), toJson(*c));
  j["search"] = {{"refine", {{"archive_order", "newest"}}}};
  EXPECT_NE(errorOf(j).find("/search/refine/archive_order: must be \"accurate\" or \"oldest\""),
            std::string::npos)
      << errorOf(j);
  j["search"] = {{"islands", {{"deal", "all"}}}};
  EXPECT_NE(errorOf(j).find("/search/islands/deal: must be \"interleaved\" or \"by_cost\""),
            std::string::npos)
      << errorOf(j);
}

TEST(Config, MeasuredCostFamiliesAndSwitch) {
  json j = minimal();
  auto d = parseRunConfig(j, ".");
  ASSERT_TRUE(d) << d.error();
  EXPECT_EQ(d->objectives.measured_cost.families, allGpuFamilies());
  EXPECT_FALSE(d->objectives.measured_cost.in_search);
  j["objectives"] = {{"measured_cost", {{"families", {"gcn5"}}, {"in_search", true}}}};
  auto c = parseRunConfig(j, ".");
  ASSERT_TRUE(c) << c.error();
  EXPECT_EQ(c->objectives.measured_cost.families, std::vector<GpuFamily>{GpuFamily::Gcn5});
  EXPECT_TRUE(c->objectives.measured_cost.in_search);
  // The resolved config records it, and reads back the same.
  auto again = parseRunConfig(toJson(*c), ".");
  ASSERT_TRUE(again) << again.error();
  EXPECT_EQ(again->objectives.measured_cost.families, c->objectives.measured_cost.families);
  j["objectives"]["measured_cost"]["families"] = {"rdna9"};
  EXPECT_NE(errorOf(j).find("/objectives/measured_cost/families/0: 'rdna9' is not one of"),
            std::string::npos)
      << errorOf(j);
  j["objectives"]["measured_cost"] = {{"families", {"rdna2", "rdna2"}}};
  EXPECT_NE(errorOf(j).find("listed twice"), std::string::npos) << errorOf(j);
  j["objectives"]["measured_cost"] = {{"families", json::array()}, {"in_search", true}};
  EXPECT_NE(errorOf(j).find("/objectives/measured_cost/in_search"), std::string::npos)
      << errorOf(j);
  j["objectives"]["measured_cost"] = {{"familes", {"rdna2"}}};
  EXPECT_NE(errorOf(j).find("/objectives/measured_cost/familes: unknown key"), std::string::npos)
      << errorOf(j);
}

class TableFiles : public ::testing::Test {
 protected:
  // One directory per process: CTest runs these tests in parallel processes.
  std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("lgp_table_test_" + std::to_string(getpid()));
  void SetUp() override { std::filesystem::create_directories(dir); }
  void TearDown() override { std::filesystem::remove_all(dir); }
  std::filesystem::path write(const std::string& name, const std::string& text) {
    std::ofstream(dir / name) << text;
    return dir / name;
  }
};

TEST_F(TableFiles, ReadsCsv) {
  auto raw = readCsv(write("ok.csv", "# comment\nmu, r ,y\n0.5,0.25,1\n1,0,2e-3\n"));
  ASSERT_TRUE(raw) << raw.error();
  auto t = selectColumns(*raw, {"mu", "r"}, {"y"}, "", "ok.csv");
  ASSERT_TRUE(t) << t.error();
  EXPECT_EQ(t->rows(), 2u);
  EXPECT_DOUBLE_EQ(t->outputs[0][1], 2e-3);
}

TEST_F(TableFiles, CsvErrorsNameFileRowAndColumn) {
  auto p = write("bad.csv", "x,y\n1,2\n3,abc\n");
  auto raw = readCsv(p);
  ASSERT_FALSE(raw);
  EXPECT_NE(raw.error().find(p.string() + ": line 3, column 2: not a decimal number"),
            std::string::npos)
      << raw.error();
  raw = readCsv(write("short.csv", "x,y\n1,2\n3\n"));
  ASSERT_FALSE(raw);
  EXPECT_NE(raw.error().find("line 3: 1 fields, header has 2"), std::string::npos) << raw.error();
  raw = readCsv(write("nan.csv", "x,y\n1,nan\n"));
  ASSERT_FALSE(raw);
  EXPECT_NE(raw.error().find("column 2"), std::string::npos);
  raw = readCsv(write("dup.csv", "x,x\n1,2\n"));
  ASSERT_FALSE(raw);
  EXPECT_NE(raw.error().find("column 2: the same name as column 1"), std::string::npos);
  raw = readCsv(dir / "missing.csv");
  ASSERT_FALSE(raw);
  EXPECT_NE(raw.error().find("cannot open"), std::string::npos);
  raw = readCsv(write("empty.csv", ""));
  ASSERT_FALSE(raw);
  raw = readCsv(write("ok.csv", "x,y\n1,2\n"));
  ASSERT_TRUE(raw);
  auto t = selectColumns(*raw, {"x"}, {"z"}, "", "ok.csv");
  ASSERT_FALSE(t);
  EXPECT_NE(t.error().find("no column named 'z'"), std::string::npos);
}

TEST_F(TableFiles, ReadsJsonTableWithDefaultRolesAndWeights) {
  auto p = write("t.json", R"({"format":"lgp-table/1","inputs":["a"],"outputs":["b"],
    "columns":{"a":[1,2,3],"b":[4,5,6]},"weights":[1,0,2],"meta":{"k":1}})");
  auto raw = readTableFile(p);
  ASSERT_TRUE(raw) << raw.error();
  auto t = selectColumns(*raw, {}, {}, "", p.string());
  ASSERT_TRUE(t) << t.error();
  EXPECT_EQ(t->input_names, std::vector<std::string>{"a"});
  EXPECT_EQ(t->weights, (std::vector<double>{1, 0, 2}));
  EXPECT_EQ(t->meta["k"], 1);
  raw = readTableFile(write("bad.json", R"({"columns":{"a":[1,"x"]}})"));
  ASSERT_FALSE(raw);
  EXPECT_NE(raw.error().find("/columns/a/1 (row 2)"), std::string::npos) << raw.error();
  raw = readTableFile(write("neg.json", R"({"columns":{"a":[1,2]},"weights":[1,-1]})"));
  ASSERT_FALSE(raw);
  EXPECT_NE(raw.error().find("/weights/1"), std::string::npos);
  raw = readTableFile(write("broken.json", R"({"columns":)"));
  ASSERT_FALSE(raw);
  EXPECT_NE(raw.error().find("invalid JSON"), std::string::npos);
}

TEST_F(TableFiles, TableJsonRoundTrip) {
  Table t;
  t.input_names = {"mu"};
  t.output_names = {"y"};
  t.inputs = {{0.1, 0.2}};
  t.outputs = {{1.0 / 3, 2.0 / 3}};
  std::ofstream(dir / "rt.json") << toJson(t).dump();
  auto raw = readTableFile(dir / "rt.json");
  ASSERT_TRUE(raw);
  auto u = selectColumns(*raw, {}, {}, "", "rt.json");
  ASSERT_TRUE(u) << u.error();
  EXPECT_EQ(u->outputs, t.outputs);
  ASSERT_TRUE(writeCsv(t, dir / "rt.csv"));
  auto c = readCsv(dir / "rt.csv");
  ASSERT_TRUE(c);
  EXPECT_EQ(c->columns[1], t.outputs[0]);  // %.17g round-trips doubles exactly
}

}  // namespace
}  // namespace lgp
