// Island profiles (search.islands.profiles): some islands search small programs while the
// others grow long ones. An island only ever holds programs that fit its profile, a program
// moved into one computes what it computed, and a profile equal to the run's shape changes
// nothing.
#include <gtest/gtest.h>

#include <cstring>
#include <nlohmann/json.hpp>

#include "lgp/config/config.hpp"
#include "lgp/core/variation.hpp"
#include "lgp/eval/interpreter.hpp"
#include "lgp/search/migration.hpp"
#include "lgp/search/search.hpp"
#include "test_tables.hpp"

namespace lgp {
namespace {

ProgramShape runShape() {
  ProgramShape s;
  s.num_inputs = 2;
  s.num_outputs = 1;
  s.max_length = 40;
  s.num_constants = 24;
  return s;
}

bool readsOnlyFirstSlots(const Program& p, int slots) {
  for (const Instr& in : p.code)
    for (int a = 0; a < arity(in.op); ++a)
      if (in.args[a].kind == OperandKind::Const && in.args[a].index >= slots) return false;
  return true;
}

std::vector<float> outputOf(const Program& p, const Dataset& ds) {
  Interpreter it(ds.blockSize());
  return it.evaluate(p, ds)[0];
}

TEST(IslandShape, ProfileCapsLengthAndSlotsButNeverBelowTheOutputs) {
  const ProgramShape run = runShape();
  const ProgramShape s = islandShape(run, {12, 4, -1});
  EXPECT_EQ(s.max_length, 12);
  EXPECT_EQ(s.num_constants, 4);
  EXPECT_EQ(s.num_inputs, run.num_inputs);
  EXPECT_EQ(islandShape(run, {}).max_length, run.max_length);
  EXPECT_EQ(islandShape(run, {}).num_constants, run.num_constants);
  EXPECT_EQ(islandShape(run, {100, 100, -1}).max_length, run.max_length);
  ProgramShape three = run;
  three.num_outputs = 3;
  EXPECT_EQ(islandShape(three, {1, 0, -1}).max_length, 3);
}

// Random long programs reading slots anywhere: what fitToIsland returns fits the island, has the
// run's constant count and computes the same bits on every row; it refuses only programs whose
// effective code is too long or reads too many slots.
TEST(FitToIsland, FitsTheIslandAndComputesTheSameBits) {
  const ProgramShape run = runShape();
  const ProgramShape island = islandShape(run, {10, 3, -1});
  Table t = test::gridTableOf(8, [](double, double) { return 0.0; });
  for (auto& col : t.inputs)
    for (auto& v : col) v = 4 * v - 2;  // both signs: protected operators take their guards
  const Dataset ds(t, 16);
  Rng rng(3);
  int moved = 0, refused = 0, unchanged = 0;
  for (int trial = 0; trial < 3000; ++trial) {
    const Program p = randomProgram(run, {1, 30, -2, 2}, rng);
    Program fitted = p;
    const bool ok = fitToIsland(fitted, run, island);
    const Program* q = &fitted;
    const Program pruned = pruneIntrons(p);
    const auto used = effectiveConstants(p);
    if (!ok) {
      ++refused;
      EXPECT_EQ(fitted, p);  // left as it was
      EXPECT_TRUE(static_cast<int>(pruned.code.size()) > island.max_length ||
                  static_cast<int>(used.size()) > island.num_constants);
      continue;
    }
    ASSERT_TRUE(validate(*q, run)) << validate(*q, run).message();
    EXPECT_LE(static_cast<int>(q->code.size()), island.max_length);
    EXPECT_TRUE(readsOnlyFirstSlots(*q, island.num_constants));
    const auto a = outputOf(p, ds), b = outputOf(*q, ds);
    ASSERT_EQ(a.size(), b.size());
    EXPECT_EQ(std::memcmp(a.data(), b.data(), a.size() * sizeof(float)), 0) << trial;
    if (*q == p)
      ++unchanged;
    else
      ++moved;
  }
  // Every case occurs.
  EXPECT_GT(moved, 100);
  EXPECT_GT(refused, 50);
  EXPECT_GT(unchanged, 10);
}

nlohmann::json J(const char* text) {
  return nlohmann::json::parse(text);
}

nlohmann::json profileConfig(const nlohmann::json& profiles) {
  nlohmann::json j = {{"data", {{"path", "t.csv"}, {"outputs", {"y"}}}},
                      {"program", {{"max_length", 32}, {"constants", 16}}},
                      {"search",
                       {{"population", 96},
                        {"generations", 24},
                        {"seed", 4},
                        {"threads", 2},
                        {"variation", {{"weight_rate", 0.3}}},
                        {"islands", {{"count", 4}, {"migration_interval", 3}}}}}};
  if (!profiles.is_null()) j["search"]["islands"]["profiles"] = profiles;
  return j;
}

std::vector<std::string> frontOf(const RunConfig& c, const Table& t) {
  Search s(c, t);
  s.run();
  std::vector<std::string> out;
  for (const auto& e : s.front()) out.push_back(e.formula);
  return out;
}

// Islands 0 and 2 search programs of at most 6 opcodes reading 2 slots, without weights, while
// 1 and 3 grow: after every generation (migration, restarts and archive refinements included)
// each island holds only what fits it, and the long islands hold longer programs.
class IslandProfiles : public ::testing::TestWithParam<const char*> {};

TEST_P(IslandProfiles, EveryIslandHoldsOnlyWhatFitsIt) {
  auto cfg = parseRunConfig(
      profileConfig(J(R"([{"max_length": 6, "constants": 2, "weight_rate": 0}, {}])")), ".");
  ASSERT_TRUE(cfg.hasValue()) << cfg.error();
  cfg->search.islands.restart_after = 4;
  cfg->search.islands.topology = std::string(GetParam()) == "by_profile"
                                     ? MigrationTopology::ByProfile
                                     : MigrationTopology::Ring;
  cfg->search.refine.archive_period = 5;
  Search s(*cfg, test::gridTable(12));
  size_t longest_free = 0;
  for (int g = 0; g <= cfg->search.generations; ++g) {
    s.step();
    const nlohmann::json ck = s.checkpoint();
    const auto& islands = ck.at("islands");
    ASSERT_EQ(islands.size(), 4u);
    for (size_t k = 0; k < islands.size(); ++k)
      for (const auto& m : islands[k].at("population")) {
        auto p = programFromJson(m.at("program"), s.shape());
        ASSERT_TRUE(p.hasValue()) << p.error();
        if (k % 2 == 0) {
          ASSERT_LE(p->code.size(), 6u) << "island " << k << " generation " << g;
          ASSERT_TRUE(readsOnlyFirstSlots(*p, 2)) << "island " << k << " generation " << g;
        } else {
          longest_free = std::max(longest_free, p->code.size());
        }
      }
  }
  EXPECT_GT(longest_free, 6u);
  EXPECT_GT(s.progress().migrants, 0u);
}

INSTANTIATE_TEST_SUITE_P(Topologies, IslandProfiles, ::testing::Values("ring", "by_profile"));

// Profiles that change nothing give the run without profiles ([{}]); real ones change the
// front, and the same seed gives the same front.
TEST(IslandProfileRuns, NeutralProfilesChangeNothingAndRunsAreDeterministic) {
  const Table t = test::gridTable(12);
  const auto none = frontOf(*parseRunConfig(profileConfig(J("[{}]")), "."), t);
  EXPECT_EQ(frontOf(*parseRunConfig(profileConfig(J("[{}, {}]")), "."), t), none);
  EXPECT_EQ(frontOf(*parseRunConfig(profileConfig(J(R"([{"max_length": 40}])")), "."), t),
            none);  // capped at the run's 32 opcodes
  EXPECT_EQ(
      frontOf(*parseRunConfig(profileConfig(J(R"([{"max_length": 32, "constants": 16}])")), "."),
              t),
      none);
  const auto cfg = parseRunConfig(
      profileConfig(J(R"([{"max_length": 8, "constants": 3, "weight_rate": 0}, {}])")), ".");
  ASSERT_TRUE(cfg.hasValue()) << cfg.error();
  const auto a = frontOf(*cfg, t);
  EXPECT_EQ(frontOf(*cfg, t), a);
  EXPECT_NE(a, none);
}

// A profile's error_bias and cost_strata act in its island only: set on every island they
// are the run's own setting, set on one island they change the run, and a missing one is the
// run's.
TEST(IslandProfileRuns, SelectionSettingsActPerIsland) {
  const Table t = test::gridTable(12);
  auto withRun = [](const char* profiles, double bias, int strata) {
    nlohmann::json j = profileConfig(J(profiles));
    j["search"]["error_bias"] = bias;
    j["search"]["cost_strata"] = strata;
    auto c = parseRunConfig(j, ".");
    EXPECT_TRUE(c.hasValue()) << c.error();
    return *c;
  };
  const auto biased = frontOf(withRun("[{}]", 0.5, 0), t);
  EXPECT_EQ(frontOf(withRun(R"([{"error_bias": 0.5}])", 0, 0), t), biased);
  EXPECT_EQ(frontOf(withRun(R"([{"error_bias": 0.5}, {}])", 0.5, 0), t), biased);
  const auto strata = frontOf(withRun("[{}]", 0, 6), t);
  EXPECT_EQ(frontOf(withRun(R"([{"cost_strata": 6}])", 0, 0), t), strata);
  EXPECT_EQ(frontOf(withRun(R"([{}, {"cost_strata": 6}])", 0, 6), t), strata);
  const auto plain = frontOf(withRun("[{}]", 0, 0), t);
  EXPECT_NE(biased, plain);
  EXPECT_NE(strata, plain);
  // On one island of four: neither the plain run nor the run-wide setting.
  const auto one =
      frontOf(withRun(R"([{}, {}, {}, {"error_bias": 0.9, "cost_strata": 6}])", 0, 0), t);
  EXPECT_NE(one, plain);
  EXPECT_NE(one, frontOf(withRun("[{}]", 0.9, 6), t));
  EXPECT_EQ(frontOf(withRun(R"([{}, {}, {}, {"error_bias": 0.9, "cost_strata": 6}])", 0, 0), t),
            one);
}

TEST(MigrationTopology, ByProfileIsARingPerProfile) {
  const IslandProfile small{8, 2, 0}, large{};
  EXPECT_EQ(migrationTargets(4, {}, MigrationTopology::ByProfile), (std::vector<int>{1, 2, 3, 0}));
  EXPECT_EQ(migrationTargets(4, {small, large}, MigrationTopology::Ring),
            (std::vector<int>{1, 2, 3, 0}));
  EXPECT_EQ(migrationTargets(4, {small, large}, MigrationTopology::ByProfile),
            (std::vector<int>{2, 3, 0, 1}));
  // Island 3 is alone with its profile: it is its own target (and sends nothing).
  EXPECT_EQ(migrationTargets(4, {small, small, small, large}, MigrationTopology::ByProfile),
            (std::vector<int>{1, 2, 0, 3}));
  // Equal profiles at different entries share a ring; every result is a permutation.
  EXPECT_EQ(migrationTargets(6, {small, large, small}, MigrationTopology::ByProfile),
            (std::vector<int>{2, 4, 3, 5, 1, 0}));
  for (int n = 1; n <= 9; ++n) {
    const auto to = migrationTargets(n, {small, large, large}, MigrationTopology::ByProfile);
    const auto from = migrationSources(to);
    for (int k = 0; k < n; ++k) EXPECT_EQ(from[to[k]], k) << n;
  }
}

// The population is split in proportion to the shares; equal shares split it as before
// (population / islands, the remainder to the first islands), and no island gets fewer than 4.
TEST(IslandSizes, PopulationFollowsTheShares) {
  for (int n : {16, 17, 99, 100, 1000, 1003})
    for (int count = 1; count <= 6 && n / count >= 4; ++count) {
      const auto sizes = islandSizes(n, count, {});
      ASSERT_EQ(static_cast<int>(sizes.size()), count);
      for (int k = 0; k < count; ++k)
        EXPECT_EQ(sizes[k], n / count + (k < n % count ? 1 : 0)) << n << " " << count;
      EXPECT_EQ(islandSizes(n, count, {IslandProfile{8, 2, 0}, IslandProfile{}}), sizes);
    }
  IslandProfile small{32, 8, 0}, half{};
  half.share = 0.5;
  EXPECT_EQ(islandSizes(700, 4, {small, small, small, half}),
            (std::vector<int>{200, 200, 200, 100}));
  EXPECT_EQ(islandSizes(1000, 5, {small, small, small, small, half}),
            (std::vector<int>{223, 222, 222, 222, 111}));  // 222.2 x 4 + 111.1: one left over
  EXPECT_EQ(islandSizes(1000, 4, {small, half}), (std::vector<int>{333, 167, 333, 167}));
  IslandProfile tiny{};
  tiny.share = 0.01;
  EXPECT_EQ(islandSizes(40, 2, {small, tiny}), (std::vector<int>{40, 4}));  // at least 4
}

// A run with shares: every island holds its share after every generation (survival,
// restarts, migration), a checkpoint taken mid-run resumes to the uninterrupted front, and the
// same seed gives the same front.
TEST(IslandSizes, SharedRunsHoldTheirSizesAndResume) {
  auto cfg = parseRunConfig(
      profileConfig(J(
          R"([{"max_length": 6, "constants": 2, "weight_rate": 0, "share": 2}, {"share": 0.5}])")),
      ".");
  ASSERT_TRUE(cfg.hasValue()) << cfg.error();
  cfg->search.islands.restart_after = 4;
  const Table t = test::gridTable(12);
  const auto want = islandSizes(96, 4, cfg->search.islands.profiles);
  EXPECT_EQ(want, (std::vector<int>{38, 10, 38, 10}));
  Search s(*cfg, t);
  nlohmann::json mid;
  for (int g = 0; g <= cfg->search.generations; ++g) {
    s.step();
    const nlohmann::json ck = s.checkpoint();
    ASSERT_EQ(ck.at("islands").size(), 4u);
    for (size_t k = 0; k < 4; ++k)
      ASSERT_EQ(static_cast<int>(ck.at("islands")[k].at("population").size()), want[k])
          << "island " << k << " generation " << g;
    if (g == 10) mid = ck;
  }
  std::vector<std::string> whole;
  for (const auto& e : s.front()) whole.push_back(e.formula);
  EXPECT_EQ(frontOf(*cfg, t), whole);
  Search resumed(*cfg, t);
  ASSERT_TRUE(resumed.restore(mid)) << "resume";
  resumed.run();
  std::vector<std::string> again;
  for (const auto& e : resumed.front()) again.push_back(e.formula);
  EXPECT_EQ(again, whole);
}

TEST(IslandProfileConfig, ConfigNamesTheFieldAndRoundTrips) {
  auto ok = parseRunConfig(
      profileConfig(J(
          R"([{"max_length": 8, "weight_rate": 0}, {"share": 0.5, "error_bias": 0.25, "cost_strata": 4}])")),
      ".");
  ASSERT_TRUE(ok.hasValue()) << ok.error();
  ASSERT_EQ(ok->search.islands.profiles.size(), 2u);
  EXPECT_EQ(ok->search.islands.profiles[0].max_length, 8);
  EXPECT_EQ(ok->search.islands.profiles[0].constants, 0);
  EXPECT_EQ(ok->search.islands.profiles[0].weight_rate, 0);
  EXPECT_LT(ok->search.islands.profiles[1].weight_rate, 0);
  EXPECT_EQ(ok->search.islands.profiles[0].share, 1);
  EXPECT_EQ(ok->search.islands.profiles[1].share, 0.5);
  EXPECT_LT(ok->search.islands.profiles[0].error_bias, 0);
  EXPECT_LT(ok->search.islands.profiles[0].cost_strata, 0);
  EXPECT_EQ(ok->search.islands.profiles[1].error_bias, 0.25);
  EXPECT_EQ(ok->search.islands.profiles[1].cost_strata, 4);
  const nlohmann::json round = toJson(*ok);
  EXPECT_EQ(round["search"]["islands"]["profiles"],
            nlohmann::json::parse(R"([{"max_length": 8, "weight_rate": 0},
                                      {"share": 0.5, "error_bias": 0.25, "cost_strata": 4}])"));
  auto again = parseRunConfig(round, ".");
  ASSERT_TRUE(again.hasValue()) << again.error();
  EXPECT_EQ(again->search.islands.profiles, ok->search.islands.profiles);
  // The default profiles (three small islands, one long) are written, so a checkpoint's config
  // digest says which islands it ran; the default topology is not.
  const RunConfig defaults;
  ASSERT_EQ(defaults.search.islands.profiles.size(), 4u);
  const nlohmann::json plain = toJson(*parseRunConfig(profileConfig(nullptr), "."));
  EXPECT_EQ(plain["search"]["islands"]["profiles"],
            nlohmann::json::parse(R"([{"max_length": 32, "constants": 8, "weight_rate": 0},
                                      {"max_length": 32, "constants": 8, "weight_rate": 0},
                                      {"max_length": 32, "constants": 8, "weight_rate": 0},
                                      {"cost_strata": 8}])"));
  EXPECT_EQ(plain["search"]["islands"]["deal"], "by_cost");
  EXPECT_FALSE(plain["search"]["islands"].contains("topology"));
  nlohmann::json by = profileConfig(J("[{}]"));
  by["search"]["islands"]["topology"] = "by_profile";
  auto topo = parseRunConfig(by, ".");
  ASSERT_TRUE(topo.hasValue()) << topo.error();
  EXPECT_EQ(topo->search.islands.topology, MigrationTopology::ByProfile);
  EXPECT_EQ(toJson(*topo)["search"]["islands"]["topology"], "by_profile");
  by["search"]["islands"]["topology"] = "star";
  auto bad_topo = parseRunConfig(by, ".");
  ASSERT_FALSE(bad_topo.hasValue());
  EXPECT_NE(bad_topo.error().find("/search/islands/topology"), std::string::npos)
      << bad_topo.error();

  const std::vector<std::pair<const char*, std::string>> bad = {
      {"[]", "/search/islands/profiles"},
      {R"({"max_length": 8})", "/search/islands/profiles"},
      {R"([{"max_length": 256}])", "/search/islands/profiles/0/max_length"},
      {R"([{}, {"constants": -1}])", "/search/islands/profiles/1/constants"},
      {R"([{"weight_rate": 2}])", "/search/islands/profiles/0/weight_rate"},
      {R"([{}, {"share": 0}])", "/search/islands/profiles/1/share"},
      {R"([{"error_bias": 1.5}])", "/search/islands/profiles/0/error_bias"},
      {R"([{}, {"cost_strata": -1}])", "/search/islands/profiles/1/cost_strata"},
      {R"([{"length": 4}])", "/search/islands/profiles/0/length"},
      {"[3]", "/search/islands/profiles/0"},
  };
  for (const auto& [profiles, path] : bad) {
    auto r = parseRunConfig(profileConfig(J(profiles)), ".");
    ASSERT_FALSE(r.hasValue()) << profiles;
    EXPECT_NE(r.error().find(path), std::string::npos) << r.error();
  }
}

}  // namespace
}  // namespace lgp
