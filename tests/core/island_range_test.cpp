// Island ranges: what an MPI rank runs (Search::setIslandRange), without MPI. Two half
// searches joined by an in-process transport stand for two ranks; their checkpoints combine
// into one that an in-process search resumes, and that ranks of another layout redistribute.
#include <gtest/gtest.h>

#include "lgp/io/checkpoint.hpp"
#include "lgp/io/result.hpp"
#include "lgp/search/migration.hpp"
#include "lgp/search/search.hpp"
#include "test_tables.hpp"

namespace lgp {
namespace {

RunConfig rangeConfig() {
  RunConfig c;
  c.data.path = "in-memory";
  c.search.population = 96;
  c.search.generations = 12;
  c.search.seed = 5;
  c.search.threads = 1;
  c.search.islands.count = 4;
  c.search.islands.migration_interval = 3;
  c.search.islands.migrants = 3;
  c.search.refine.archive_period = 5;
  c.program.max_length = 16;
  return c;
}

// One LocalTransport shared by several searches (the "ranks" of this process).
class SharedTransport final : public MigrationTransport {
 public:
  explicit SharedTransport(LocalTransport& t) : t_(t) {}
  void send(int from, int to, std::vector<Migrant> m) override {
    sent_ += m.size();
    t_.send(from, to, std::move(m));
  }
  std::vector<Migrant> receive(int to) override { return t_.receive(to); }
  uint64_t sent() const override { return sent_; }

 private:
  LocalTransport& t_;
  uint64_t sent_ = 0;
};

struct TwoRanks {
  LocalTransport shared{4};
  std::unique_ptr<Search> a, b;
  explicit TwoRanks(const RunConfig& c) {
    a = std::make_unique<Search>(c, test::gridTable(10));
    b = std::make_unique<Search>(c, test::gridTable(10));
    a->setIslandRange(0, 2, 4);
    b->setIslandRange(2, 2, 4);
    a->setTransport(std::make_unique<SharedTransport>(shared));
    b->setTransport(std::make_unique<SharedTransport>(shared));
    a->initialize();
    b->initialize();
  }
  void run() {
    while (!a->done() || !b->done()) {
      a->step();
      b->step();
    }
  }
};

TEST(IslandRange, HalvesShareThePopulationAndMigrateAcross) {
  TwoRanks r(rangeConfig());
  r.run();
  const auto pa = r.a->progress(), pb = r.b->progress();
  EXPECT_EQ(pa.generation, 12);
  EXPECT_EQ(pb.generation, 12);
  EXPECT_EQ(pa.islands, 2);
  // Each half evaluates about half of what the whole would.
  EXPECT_GT(pa.evaluations, 12u * 40u);
  EXPECT_GT(pb.migrants, 0u);
  // Island 1 (on a) sends to island 2 (on b) and island 3 (b) to 0 (a): batches cross.
  const auto ca = r.a->checkpoint(), cb = r.b->checkpoint();
  EXPECT_EQ(ca["island_first"], 0);
  EXPECT_EQ(cb["island_first"], 2);
  EXPECT_EQ(cb["island_total"], 4);
  EXPECT_EQ(ca["islands"].size(), 2u);
}

TEST(IslandRange, CombinedCheckpointResumesInOneProcess) {
  const RunConfig c = rangeConfig();
  TwoRanks r(c);
  r.run();
  auto combined = combineCheckpoints(c, r.a->shape(), {r.a->checkpoint(), r.b->checkpoint()});
  ASSERT_TRUE(combined) << combined.error();
  EXPECT_EQ((*combined)["islands"].size(), 4u);
  EXPECT_EQ((*combined)["ranks"], 2);
  EXPECT_EQ((*combined)["parts"].size(), 2u);
  const uint64_t evals = r.a->progress().evaluations + r.b->progress().evaluations;
  EXPECT_EQ((*combined)["evaluations"].get<uint64_t>(), evals);

  RunConfig longer = c;
  longer.search.generations = 18;
  Search whole(longer, test::gridTable(10));
  ASSERT_TRUE(whole.restore(*combined));
  EXPECT_EQ(whole.progress().generation, 12);
  EXPECT_EQ(whole.progress().islands, 4);
  EXPECT_EQ(whole.progress().evaluations, evals);
  // The merged archive holds no dominated member, and the run goes on from there.
  const auto& m = whole.archiveMembers();
  ASSERT_FALSE(m.empty());
  for (size_t i = 0; i < m.size(); ++i)
    for (size_t j = 0; j < m.size(); ++j) {
      if (i != j) {
        EXPECT_FALSE(dominates(m[j].obj, m[i].obj));
      }
    }
  whole.run();
  EXPECT_EQ(whole.progress().generation, 18);
  EXPECT_GT(whole.progress().evaluations, evals);
}

TEST(IslandRange, AnotherLayoutTakesItsSliceAndTheWholeArchive) {
  const RunConfig c = rangeConfig();
  TwoRanks r(c);
  r.run();
  auto combined = combineCheckpoints(c, r.a->shape(), {r.a->checkpoint(), r.b->checkpoint()});
  ASSERT_TRUE(combined);
  // Three "ranks" over the same four islands: 0..0, 1..1, 2..3.
  Search mid(c, test::gridTable(10));
  mid.setIslandRange(1, 1, 4);
  ASSERT_TRUE(mid.restore(*combined, false));
  EXPECT_EQ(mid.progress().islands, 1);
  EXPECT_EQ(mid.progress().evaluations, 0u);  // counters stay with rank 0
  EXPECT_EQ(mid.archiveMembers().size(), (*combined)["archive"].size());
  EXPECT_EQ(mid.checkpoint()["islands"][0], (*combined)["islands"][1]);
  // Another island count is refused, naming both.
  Search other(c, test::gridTable(10));
  other.setIslandRange(0, 1, 2);
  const auto st = other.restore(*combined);
  ASSERT_FALSE(st);
  EXPECT_NE(st.message().find("4 islands"), std::string::npos) << st.message();
}

TEST(IslandRange, OnePartAloneIsNotAWholeCheckpoint) {
  const RunConfig c = rangeConfig();
  TwoRanks r(c);
  r.run();
  Search whole(c, test::gridTable(10));
  const auto st = whole.restore(r.b->checkpoint());
  ASSERT_FALSE(st);
  EXPECT_NE(st.message().find("one rank of an MPI run"), std::string::npos) << st.message();
  // Parts must cover the islands in order.
  auto bad = combineCheckpoints(c, r.a->shape(), {r.b->checkpoint(), r.a->checkpoint()});
  EXPECT_FALSE(bad);
  auto half = combineCheckpoints(c, r.a->shape(), {r.a->checkpoint()});
  ASSERT_FALSE(half);
  EXPECT_NE(half.error().find("2 of 4 islands"), std::string::npos) << half.error();
}

TEST(IslandRange, ACheckpointFileRoundTrips) {
  const RunConfig c = rangeConfig();
  Search s(c, test::gridTable(10));
  s.run();
  const auto path =
      std::filesystem::temp_directory_path() /
      ("lgp_ckpt_" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) + ".json");
  ASSERT_TRUE(writeCheckpointFile(s.checkpoint(), path));
  auto back = readCheckpointFile(path);
  ASSERT_TRUE(back) << back.error();
  Search t(c, test::gridTable(10));
  ASSERT_TRUE(t.restore(*back));
  EXPECT_EQ(frontToJson(s, s.front())["members"], frontToJson(t, t.front())["members"]);
  std::filesystem::remove(path);
  auto missing = readCheckpointFile(path);
  ASSERT_FALSE(missing);
  EXPECT_NE(missing.error().find(path.string()), std::string::npos);
}

}  // namespace
}  // namespace lgp
