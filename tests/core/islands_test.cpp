// Islands: determinism for a fixed seed, threads and K; migration counts and archive
// invariants; restarts; checkpoints of a multi-island run.
#include <gtest/gtest.h>

#include <cmath>

#include "lgp/io/result.hpp"
#include "lgp/search/migration.hpp"
#include "lgp/search/search.hpp"
#include "test_tables.hpp"

namespace lgp {
namespace {

Table grid(int n) {
  return test::gridTable(n);
}

RunConfig islandConfig(int islands, int threads, uint64_t seed = 7) {
  RunConfig c;
  c.data.path = "in-memory";
  c.search.population = 96;
  c.search.generations = 14;
  c.search.seed = seed;
  c.search.threads = threads;
  c.search.islands.count = islands;
  c.search.islands.migration_interval = 3;
  c.search.islands.migrants = 3;
  c.search.refine.archive_period = 5;
  c.program.max_length = 16;
  return c;
}

nlohmann::json members(const Search& s) {
  return frontToJson(s, s.front())["members"];
}

TEST(Islands, SameSeedThreadsAndIslandsSameFront) {
  Search a(islandConfig(4, 2), grid(10));
  a.run();
  Search b(islandConfig(4, 2), grid(10));
  b.run();
  EXPECT_EQ(members(a), members(b));
  EXPECT_EQ(a.progress().evaluations, b.progress().evaluations);
  EXPECT_EQ(a.progress().migrants, b.progress().migrants);
  // Per-program work is sequential and islands are visited in order: the thread count does
  // not matter either.
  Search c(islandConfig(4, 1), grid(10));
  c.run();
  EXPECT_EQ(members(a), members(c));
}

TEST(Islands, IslandCountChangesTheSearch) {
  Search one(islandConfig(1, 1), grid(10));
  one.run();
  Search four(islandConfig(4, 1), grid(10));
  four.run();
  EXPECT_EQ(one.progress().islands, 1);
  EXPECT_EQ(four.progress().islands, 4);
  EXPECT_EQ(one.progress().migrants, 0u);
  EXPECT_GT(four.progress().migrants, 0u);
  // Four demes of a quarter of the population each, and one of all of it.
  const auto demes = four.checkpoint()["islands"];
  ASSERT_EQ(demes.size(), 4u);
  for (const auto& d : demes) EXPECT_EQ(d["population"].size(), 24u);
  ASSERT_EQ(one.checkpoint()["islands"].size(), 1u);
  EXPECT_EQ(one.checkpoint()["islands"][0]["population"].size(), 96u);
}

TEST(Islands, MigrationHappensAndKeepsArchiveInvariants) {
  RunConfig c = islandConfig(4, 2);
  Search s(c, grid(10));
  s.run();
  const auto p = s.progress();
  // 14 generations, a migration every 3: 4 migrations, each island sends 1..3 members.
  EXPECT_GE(p.migrants, 4u * 4u);
  EXPECT_LE(p.migrants, 4u * 4u * 3u);
  const auto front = s.front();
  ASSERT_FALSE(front.empty());
  EXPECT_LE(front.size(), static_cast<size_t>(c.search.archive.max_size));
  for (size_t i = 0; i < front.size(); ++i) {
    EXPECT_TRUE(front[i].obj.finite());
    for (size_t j = 0; j < front.size(); ++j)
      if (i != j) {
        EXPECT_FALSE(dominates(front[j].obj, front[i].obj));
      }
  }
}

TEST(Islands, IslandsAreCappedByPopulation) {
  RunConfig c = islandConfig(64, 1);
  c.search.population = 20;  // at most 5 islands of 4
  c.search.generations = 3;
  Search s(c, grid(6));
  s.run();
  EXPECT_EQ(s.progress().islands, 5);
}

TEST(Islands, StagnantIslandsRestart) {
  RunConfig c = islandConfig(4, 1);
  c.search.generations = 30;
  c.search.islands.restart_after = 2;
  Search s(c, grid(8));
  s.run();
  EXPECT_GT(s.progress().restarts, 0u);
  // Restarts are drawn from seeded streams like everything else.
  Search t(c, grid(8));
  t.run();
  EXPECT_EQ(s.progress().restarts, t.progress().restarts);
  EXPECT_EQ(members(s), members(t));
}

TEST(Islands, ResumedRunEqualsUninterruptedRun) {
  RunConfig c = islandConfig(3, 2);
  c.search.islands.restart_after = 4;
  c.search.generations = 20;
  Search full(c, grid(9));
  full.run();
  Search first(c, grid(9));
  for (int g = 0; g < 8; ++g) first.step();
  Search resumed(c, grid(9));
  ASSERT_TRUE(resumed.restore(nlohmann::json::parse(first.checkpoint().dump())));
  resumed.run();
  EXPECT_EQ(members(resumed), members(full));
  EXPECT_EQ(resumed.progress().evaluations, full.progress().evaluations);
  EXPECT_EQ(resumed.progress().migrants, full.progress().migrants);
  EXPECT_EQ(resumed.progress().restarts, full.progress().restarts);
}

TEST(Islands, CheckpointFromAnotherIslandCountIsRejected) {
  Search a(islandConfig(4, 1), grid(8));
  a.step();
  Search b(islandConfig(2, 1), grid(8));
  EXPECT_FALSE(b.restore(a.checkpoint()));
}

TEST(Islands, LocalTransportDeliversInOrder) {
  LocalTransport t(3);
  Program p;
  Objectives o1, o2, o3;
  o1.error = 1;
  o2.error = 2;
  o3.error = 3;
  t.send(0, 2, {{p, o1}, {p, o2}});
  t.send(1, 2, {{p, o3}});
  EXPECT_TRUE(t.receive(0).empty());
  const auto got = t.receive(2);
  ASSERT_EQ(got.size(), 3u);
  EXPECT_EQ(got[0].obj.error, 1);
  EXPECT_EQ(got[1].obj.error, 2);
  EXPECT_EQ(got[2].obj.error, 3);
  EXPECT_TRUE(t.receive(2).empty());
  EXPECT_EQ(t.sent(), 3u);
  EXPECT_EQ(migrationTarget(2, 3), 0);
  EXPECT_EQ(migrationTarget(0, 3), 1);
}

}  // namespace
}  // namespace lgp

namespace lgp {
namespace {

TEST(Islands, ConfigKeysAreValidatedWithTheirPath) {
  nlohmann::json j = {{"data", {{"path", "t.csv"}}},
                      {"search",
                       {{"islands", {{"count", 3}, {"migration_interval", 5}, {"migrants", 2}}},
                        {"refine", {{"lm_iterations", 7}, {"archive_lm_iterations", 0}}},
                        {"variation", {{"wrap_share", 0.25}}}}}};
  auto c = parseRunConfig(j, ".");
  ASSERT_TRUE(c) << c.error();
  EXPECT_EQ(c->search.islands.count, 3);
  EXPECT_EQ(c->search.islands.migration_interval, 5);
  EXPECT_EQ(c->search.islands.migrants, 2);
  EXPECT_EQ(c->search.refine.lm_iterations, 7);
  EXPECT_EQ(c->search.refine.archive_lm_iterations, 0);
  EXPECT_EQ(c->search.variation.wrap_share, 0.25);
  // The keys round-trip through toJson.
  auto again = parseRunConfig(toJson(*c), ".");
  ASSERT_TRUE(again) << again.error();
  EXPECT_EQ(toJson(*again), toJson(*c));

  j["search"]["islands"]["count"] = 0;
  auto bad = parseRunConfig(j, ".");
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.error().find("/search/islands/count"), std::string::npos) << bad.error();
  j["search"]["islands"] = {{"count", 2}, {"migrate", 3}};
  bad = parseRunConfig(j, ".");
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.error().find("/search/islands/migrate"), std::string::npos) << bad.error();
  j["search"]["islands"] = {{"count", 2}};
  j["search"]["refine"] = {{"lm_iterations", -1}};
  bad = parseRunConfig(j, ".");
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.error().find("/search/refine/lm_iterations"), std::string::npos) << bad.error();
}

}  // namespace
}  // namespace lgp
