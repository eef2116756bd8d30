// Tampered checkpoints (hardening round 3, F2): a checkpoint is a file (or a database row)
// anyone can edit, and restore() evaluated what it decoded. A program without its constants,
// one longer than the run's max_length, an emptied or resized island and an oversized archive
// are refused with a message naming what is wrong; the search is left as it was.
#include <gtest/gtest.h>

#include <algorithm>
#include <string>

#include "lgp/io/checkpoint.hpp"
#include "lgp/search/search.hpp"
#include "test_tables.hpp"

namespace lgp {
namespace {

using nlohmann::json;

RunConfig smallConfig() {
  RunConfig c;
  c.data.path = "in-memory";
  c.search.population = 32;
  c.search.generations = 4;
  c.search.seed = 3;
  c.search.threads = 1;
  c.search.islands.count = 2;
  c.program.max_length = 32;
  c.program.num_constants = 8;
  return c;
}

// A checkpoint of a search that has run two generations.
json checkpointAfterTwo() {
  Search s(smallConfig(), test::gridTable(6));
  s.step();
  s.step();
  s.step();
  return s.checkpoint();
}

// The error of restoring `ck` into a fresh search of the same config ("" when accepted).
std::string restoreError(const json& ck) {
  Search s(smallConfig(), test::gridTable(6));
  auto st = s.restore(ck);
  return st ? "" : st.message();
}

bool has(const std::string& s, const std::string& what) {
  return s.find(what) != std::string::npos;
}

// Cuts a program's constants to the slots its code reads (a constant it reads past its own
// array is refused by the decoder anyway), so that only the run's shape tells it is short.
// False when the program reads its last slot.
bool shortenConstants(json& program) {
  int used = 0;
  for (const auto& row : program["code"])
    for (size_t a = 1; a < row.size(); ++a)
      if (row[a].get<std::string>()[0] == 'c')
        used = std::max(used, std::stoi(row[a].get<std::string>().substr(1)) + 1);
  if (used >= static_cast<int>(program["constants"].size())) return false;
  while (static_cast<int>(program["constants"].size()) > used)
    program["constants"].erase(program["constants"].size() - 1);
  return true;
}

// Shortens the constants of the first program in `members` that allows it; its slot count.
int shortenOne(json& members) {
  for (auto& m : members)
    if (shortenConstants(m["program"])) return static_cast<int>(m["program"]["constants"].size());
  return -1;
}

TEST(TamperedCheckpoint, AnUntouchedOneIsRestored) {
  EXPECT_EQ(restoreError(checkpointAfterTwo()), "");
}

TEST(TamperedCheckpoint, AProgramWithoutItsConstantsIsRefused) {
  json ck = checkpointAfterTwo();
  const int left = shortenOne(ck["islands"][0]["population"]);
  ASSERT_GE(left, 0);
  const std::string why = restoreError(ck);
  EXPECT_TRUE(has(why, "checkpoint: population: program: program has " + std::to_string(left) +
                           " constant slots, expected 8"))
      << why;
}

TEST(TamperedCheckpoint, AnArchiveMemberWithoutItsConstantsIsRefused) {
  json ck = checkpointAfterTwo();
  const int left = shortenOne(ck["archive"]);
  ASSERT_GE(left, 0);
  const std::string why = restoreError(ck);
  EXPECT_TRUE(has(
      why, "checkpoint: archive: program: program has " + std::to_string(left) + " constant slots"))
      << why;
}

TEST(TamperedCheckpoint, AProgramLongerThanMaxLengthIsRefused) {
  json ck = checkpointAfterTwo();
  json code = json::array({{"add", "x0", "x1"}});
  for (int i = 1; i < 255; ++i) code.push_back({"mul", "r" + std::to_string(i - 1), "x0"});
  ck["islands"][1]["population"][2]["program"]["code"] = code;
  ck["islands"][1]["population"][2]["program"]["outputs"] = {254};
  const std::string why = restoreError(ck);
  EXPECT_TRUE(has(why, "program has 255 opcodes, max_length is 32")) << why;
}

TEST(TamperedCheckpoint, AnEmptiedOrResizedIslandIsRefused) {
  json ck = checkpointAfterTwo();
  ck["islands"][0]["population"] = json::array();
  ck["islands"][0]["rank"] = json::array();
  ck["islands"][0]["crowd"] = json::array();
  std::string why = restoreError(ck);
  EXPECT_TRUE(has(why, "checkpoint: island 0 holds 0 programs, this run's population gives it 16"))
      << why;

  ck = checkpointAfterTwo();
  for (const char* key : {"population", "rank", "crowd"}) ck["islands"][1][key].erase(0);
  why = restoreError(ck);
  EXPECT_TRUE(has(why, "island 1 holds 15 programs")) << why;

  // More islands than the population has programs: every island would be empty.
  ck = checkpointAfterTwo();
  json empty = {{"population", json::array()},
                {"rank", json::array()},
                {"crowd", json::array()},
                {"best", nullptr},
                {"stagnant", 0}};
  ck["islands"] = json::array();
  for (int k = 0; k < 40; ++k) ck["islands"].push_back(empty);
  ck["island_total"] = 40;
  why = restoreError(ck);
  EXPECT_TRUE(has(why, "40 islands for a population of 32")) << why;
}

TEST(TamperedCheckpoint, AnArchiveOverItsBoundIsRefused) {
  RunConfig c = smallConfig();
  json ck = checkpointAfterTwo();
  ASSERT_FALSE(ck["archive"].empty());
  while (static_cast<int>(ck["archive"].size()) <= c.search.archive.max_size)
    ck["archive"].push_back(ck["archive"][0]);
  const std::string why = restoreError(ck);
  EXPECT_TRUE(has(why, "more than search.archive.max_size")) << why;
}

TEST(TamperedCheckpoint, ARefusedOneLeavesTheSearchAsItWas) {
  Search s(smallConfig(), test::gridTable(6));
  s.step();
  json before = s.checkpoint();
  json bad = checkpointAfterTwo();
  ASSERT_GE(shortenOne(bad["islands"][0]["population"]), 0);
  EXPECT_FALSE(s.restore(bad));
  json after = s.checkpoint();
  before.erase("elapsed_s");  // the clock goes on
  after.erase("elapsed_s");
  EXPECT_EQ(after.dump(), before.dump());
  s.step();  // and it goes on
  EXPECT_EQ(s.progress().generation, 1);
}

TEST(TamperedCheckpoint, CombiningRefusesATamperedPart) {
  RunConfig c = smallConfig();
  json part = checkpointAfterTwo();
  ASSERT_FALSE(part["archive"].empty());
  ASSERT_GE(shortenOne(part["archive"]), 0);
  Search s(c, test::gridTable(6));
  auto combined = combineCheckpoints(c, s.shape(), {part});
  ASSERT_FALSE(combined);
  EXPECT_TRUE(has(combined.error(), "checkpoint: archive: program: program has"))
      << combined.error();
}

}  // namespace
}  // namespace lgp

namespace lgp {
namespace {

// Hardening round 4, F12: a checkpoint's objectives were trusted on restore (a front claimed
// 1e-12, or -1, while the member's program scores 0.165), and generation -2^31 resumed for 2^31
// generations. Every recorded error is scored again, and the counters must be counts.
TEST(TamperedCheckpoint, ClaimedErrorsAreScoredAgain) {
  for (double claim : {1e-12, -1.0}) {
    json ck = checkpointAfterTwo();
    ASSERT_FALSE(ck["archive"].empty());
    ck["archive"][0]["obj"][0] = claim;
    const std::string e = restoreError(ck);
    EXPECT_TRUE(has(e, "archive member 0 claims error")) << e;
    EXPECT_TRUE(has(e, "its program scores")) << e;
  }
  json ck = checkpointAfterTwo();
  ck["islands"][1]["population"][3]["obj"][0] = 1e-9;
  EXPECT_TRUE(has(restoreError(ck), "island 1 member 3 claims error")) << restoreError(ck);
  ck = checkpointAfterTwo();
  ck["archive"][0]["obj"][1] = -5.0;  // a negative cost
  EXPECT_TRUE(has(restoreError(ck), "cost and discontinuity must be finite")) << restoreError(ck);
}

TEST(TamperedCheckpoint, CountersMustBeCounts) {
  for (const char* key : {"generation", "evaluations"}) {
    json ck = checkpointAfterTwo();
    ck[key] = -2147483648LL;
    EXPECT_TRUE(has(restoreError(ck), std::string("/") + key + ": must be an integer >= 0"))
        << key << ": " << restoreError(ck);
  }
  json ck = checkpointAfterTwo();
  ck["elapsed_s"] = -1.0;
  EXPECT_TRUE(has(restoreError(ck), "/elapsed_s")) << restoreError(ck);
  ck = checkpointAfterTwo();
  ck["islands"][0]["stagnant"] = -3;
  EXPECT_TRUE(has(restoreError(ck), "/stagnant")) << restoreError(ck);
}

}  // namespace
}  // namespace lgp
