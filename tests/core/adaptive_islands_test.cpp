// Time goes where the front moves (search.islands.adaptive): a front gain is the area a member
// takes off the staircase of log10 error over cost, each island's offspring follow its recent
// gain, and a run with it on is as deterministic and resumable as one without.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <nlohmann/json.hpp>
#include <numeric>

#include "lgp/config/config.hpp"
#include "lgp/search/front_gain.hpp"
#include "lgp/search/migration.hpp"
#include "lgp/search/search.hpp"
#include "test_tables.hpp"

namespace lgp {
namespace {

TEST(FrontGain, AreaTakenOffTheStaircase) {
  FrontGain g(64);
  g.reset({Objectives{0.1, 2}, Objectives{0.01, 10}});
  // Bands 5-9 fall from 0.1 to 0.05; from band 10 on 0.01 is better already.
  EXPECT_NEAR(g.add(Objectives{0.05, 5}), 5 * std::log10(2.0), 1e-12);
  EXPECT_EQ(g.add(Objectives{0.05, 5}), 0);  // the staircase holds it now
  EXPECT_EQ(g.add(Objectives{0.07, 6.5}), 0);
  // A halving at the accurate end is worth a halving at the cheap end, band for band.
  EXPECT_NEAR(g.add(Objectives{0.005, 60}), 4 * std::log10(2.0), 1e-12);
  EXPECT_NEAR(g.add(Objectives{0.025, 60}), 0, 1e-12);
  // Past the last band, not finite, or worse than everything: nothing.
  EXPECT_EQ(g.add(Objectives{1e-9, 64}), 0);
  EXPECT_EQ(g.add(Objectives{std::numeric_limits<double>::infinity(), 3}), 0);
  EXPECT_EQ(g.add(Objectives{std::nan(""), 3}), 0);
  EXPECT_EQ(g.add(Objectives{0.5, 0}), 0);
  // Below every member the worst error of the reset is the reference, and an exact fit gains
  // a bounded area (errors count from 1e-12).
  g.reset({Objectives{0.1, 2}, Objectives{0.01, 10}});
  EXPECT_NEAR(g.add(Objectives{0.01, 0}), 2 * 1.0 + 8 * 1.0,
              1e-12);  // bands 0-1 from the reference 0.1
  const double exact = g.add(Objectives{0, 20});
  EXPECT_NEAR(exact, 44 * 10.0, 1e-9);
}

TEST(OffspringCounts, FollowTheCreditAndKeepTheTotal) {
  const std::vector<int> sizes{100, 100, 100, 100};
  EXPECT_EQ(offspringCounts(sizes, {0, 0, 0, 0}, 0.5), sizes);  // no credit yet
  EXPECT_EQ(offspringCounts(sizes, {1, 1, 1, 1}, 0.5), sizes);
  EXPECT_EQ(offspringCounts(sizes, {0, 0, 0, 3}, 0), sizes);  // off
  EXPECT_EQ(offspringCounts(sizes, {0, 0, 0, 3}, 0.5), (std::vector<int>{50, 50, 50, 250}));
  EXPECT_EQ(offspringCounts(sizes, {1, 0, 0, 3}, 0.5), (std::vector<int>{100, 50, 50, 200}));
  EXPECT_EQ(offspringCounts(sizes, {std::nan(""), -1, 0, 3}, 0.5),
            (std::vector<int>{50, 50, 50, 250}));  // nonsense credit counts as none
  EXPECT_EQ(offspringCounts({7}, {5}, 0.9), (std::vector<int>{7}));
  // Every island keeps at least one offspring, and the total never changes.
  for (double a : {0.1, 0.5, 0.95})
    for (const std::vector<double>& credit :
         {std::vector<double>{0, 0, 0, 1}, {1e-9, 5, 0, 1e9}, {3, 1, 4, 1}}) {
      const std::vector<int> sz{4, 4, 5, 87};
      const auto c = offspringCounts(sz, credit, a);
      EXPECT_EQ(std::accumulate(c.begin(), c.end(), 0), 100);
      for (int n : c) EXPECT_GE(n, 1);
    }
}

nlohmann::json adaptiveConfig(double adaptive) {
  return {{"data", {{"path", "t.csv"}, {"outputs", {"y"}}}},
          {"program", {{"max_length", 32}, {"constants", 16}}},
          {"search",
           {{"population", 96},
            {"generations", 30},
            {"seed", 7},
            {"threads", 2},
            {"islands",
             {{"count", 4},
              {"migration_interval", 3},
              {"restart_after", 6},
              {"adaptive", adaptive},
              {"adaptive_halflife", 4}}}}}};
}

std::vector<std::string> formulas(const Search& s) {
  std::vector<std::string> out;
  for (const auto& e : s.front()) out.push_back(e.formula);
  return out;
}

// With the shares moving: islands keep their population, the split moves away from the even
// one, the same seed gives the same front, and a checkpoint taken mid-run (each island's credit
// in it) resumes to the uninterrupted front, also from a checkpoint written before credit was.
TEST(AdaptiveIslands, SharesMoveAndRunsAreDeterministicAndResume) {
  auto cfg = parseRunConfig(adaptiveConfig(0.8), ".");
  ASSERT_TRUE(cfg.hasValue()) << cfg.error();
  const Table t = test::gridTable(12);
  Search s(*cfg, t);
  nlohmann::json mid;
  bool moved = false;
  for (int g = 0; g <= cfg->search.generations; ++g) {
    s.step();
    const nlohmann::json ck = s.checkpoint();
    ASSERT_EQ(ck.at("islands").size(), 4u);
    for (const auto& isl : ck.at("islands")) {
      ASSERT_EQ(isl.at("population").size(), 24u) << "generation " << g;
      ASSERT_GE(isl.at("credit").get<double>(), 0);
    }
    const auto split = s.progress().island_offspring;
    ASSERT_EQ(std::accumulate(split.begin(), split.end(), 0), 96);
    moved = moved || split != std::vector<int>{24, 24, 24, 24};
    if (g == 12) mid = ck;
  }
  EXPECT_TRUE(moved) << "the split never left the population's";
  const auto whole = formulas(s);
  Search again(*cfg, t);
  again.run();
  EXPECT_EQ(formulas(again), whole);
  Search resumed(*cfg, t);
  ASSERT_TRUE(resumed.restore(mid));
  resumed.run();
  EXPECT_EQ(formulas(resumed), whole);
  // Credit is what drives the split: a checkpoint without it (an older one) resumes as a run
  // whose islands start with none, which deals as adaptive 0 does until gains accrue.
  for (auto& isl : mid.at("islands")) isl.erase("credit");
  Search old(*cfg, t);
  ASSERT_TRUE(old.restore(mid));
  EXPECT_EQ(old.progress().island_offspring, (std::vector<int>{24, 24, 24, 24}));
  old.run();
  EXPECT_FALSE(formulas(old).empty());
  // A credit that is not a finite number >= 0 is refused by name.
  mid.at("islands")[1]["credit"] = -1;
  Search bad(*cfg, t);
  const Status st = bad.restore(mid);
  EXPECT_FALSE(st);
  EXPECT_NE(st.message().find("credit"), std::string::npos) << st.message();
}

// adaptive 0 is the fixed split exactly: the same front as a config without the key.
TEST(AdaptiveIslands, OffIsTheFixedSplit) {
  auto off = parseRunConfig(adaptiveConfig(0), ".");
  ASSERT_TRUE(off.hasValue()) << off.error();
  auto plain_json = adaptiveConfig(0);
  plain_json["search"]["islands"].erase("adaptive");
  plain_json["search"]["islands"].erase("adaptive_halflife");
  auto plain = parseRunConfig(plain_json, ".");
  ASSERT_TRUE(plain.hasValue()) << plain.error();
  const Table t = test::gridTable(12);
  Search a(*off, t), b(*plain, t);
  a.run();
  b.run();
  EXPECT_EQ(formulas(a), formulas(b));
  EXPECT_EQ(a.progress().island_offspring, (std::vector<int>{24, 24, 24, 24}));
}

TEST(AdaptiveIslands, ConfigNamesTheFieldAndReason) {
  auto j = adaptiveConfig(1.5);
  auto bad = parseRunConfig(j, ".");
  ASSERT_FALSE(bad.hasValue());
  EXPECT_NE(bad.error().find("/search/islands/adaptive"), std::string::npos) << bad.error();
  j = adaptiveConfig(0.5);
  j["search"]["islands"]["adaptive_halflife"] = 0;
  bad = parseRunConfig(j, ".");
  ASSERT_FALSE(bad.hasValue());
  EXPECT_NE(bad.error().find("adaptive_halflife"), std::string::npos) << bad.error();
}

}  // namespace
}  // namespace lgp
