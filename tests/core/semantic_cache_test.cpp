// The semantic cache (search/semantic_cache.hpp): its key ignores exactly what cannot change
// a program's result, and a search with it gives the front, evaluation count and checkpoint
// resume of a search without it, while doing less work.
#include <gtest/gtest.h>

#include <bit>
#include <cstring>
#include <vector>

#include "clone_generation.hpp"
#include "lgp/core/variation.hpp"
#include "lgp/io/result.hpp"
#include "lgp/search/search.hpp"
#include "lgp/search/semantic_cache.hpp"
#include "test_tables.hpp"

namespace lgp {
namespace {

ProgramShape shape2() {
  ProgramShape s;
  s.num_inputs = 2;
  s.max_length = 16;
  s.num_constants = 4;
  return s;
}

// A random program with at least one intron, or nullopt.
std::vector<Program> programsWithIntrons(int want) {
  std::vector<Program> out;
  Rng rng(11);
  InitConfig init;
  init.min_length = 6;
  init.max_length = 16;
  while (static_cast<int>(out.size()) < want) {
    Program p = randomProgram(shape2(), init, rng);
    if (effectiveIndices(p).size() < p.code.size()) out.push_back(std::move(p));
  }
  return out;
}

TEST(SemanticCache, KeyIgnoresIntronsAndRegisterPositions) {
  for (const Program& p : programsWithIntrons(300)) {
    const Program q = pruneIntrons(p);  // effective opcodes only, registers renumbered
    ASSERT_NE(q.code.size(), p.code.size());
    EXPECT_EQ(effectiveKey(p), effectiveKey(q));
    // An intron rewritten: still the same key.
    Program r = p;
    const auto eff = effectiveIndices(p);
    for (int i = 0; i < static_cast<int>(r.code.size()); ++i)
      if (std::find(eff.begin(), eff.end(), i) == eff.end()) {
        r.code[static_cast<size_t>(i)].op =
            r.code[static_cast<size_t>(i)].op == Op::Add ? Op::Mul : Op::Add;
        break;
      }
    EXPECT_EQ(effectiveKey(r), effectiveKey(p));
  }
}

TEST(SemanticCache, KeyFollowsWhatChangesTheResult) {
  Program p;
  p.constants = {0.5f, 2.0f, 0.0f, 0.0f};
  p.code = {{Op::Mul, {inputOperand(0), constOperand(1)}},
            {Op::Sub, {regOperand(0), constOperand(0)}}};
  p.outputs = {1};
  const ProgramKey k = effectiveKey(p);
  Program unused = p;  // a slot no opcode reads
  unused.constants[3] = 7.0f;
  EXPECT_EQ(effectiveKey(unused), k);
  Program ulp = p;  // one float step in a constant that is read
  ulp.constants[1] = std::nextafter(2.0f, 3.0f);
  EXPECT_NE(effectiveKey(ulp), k);
  Program swapped = p;  // x0 * c1 - c0 against c0 - x0 * c1
  std::swap(swapped.code[1].args[0], swapped.code[1].args[1]);
  EXPECT_NE(effectiveKey(swapped), k);
  Program slot = p;  // the same value read from another slot: LM sees another column order
  slot.constants[2] = 0.5f;
  slot.code[1].args[1] = constOperand(2);
  EXPECT_NE(effectiveKey(slot), k);
  Program input = p;
  input.code[0].args[0] = inputOperand(1);
  EXPECT_NE(effectiveKey(input), k);
  Program op = p;
  op.code[1].op = Op::Add;
  EXPECT_NE(effectiveKey(op), k);
}

TEST(SemanticCache, StoresAndReplaces) {
  SemanticCache off(0);
  EXPECT_FALSE(off.enabled());
  SemanticCache c(1000);
  EXPECT_EQ(c.capacity(), 1024u);
  const ProgramKey a{5, 1}, b{5 + 1024, 2};  // the same slot
  SemanticCache::Entry e;
  EXPECT_FALSE(c.find(a, e));
  c.storeObjectives(a, Objectives{0.25, 3, 1});
  ASSERT_TRUE(c.find(a, e));
  EXPECT_FALSE(e.lm_known);
  SemanticCache::LmOutcome lm;
  lm.improved = true;
  lm.evaluations = 7;
  lm.count = 2;
  lm.after = {0.5f, -2.0f};
  c.storeLm(a, lm);
  ASSERT_TRUE(c.find(a, e));
  EXPECT_EQ(e.obj.error, 0.25);
  EXPECT_TRUE(e.lm_known);
  EXPECT_TRUE(e.lm.improved);
  EXPECT_EQ(e.lm.evaluations, 7u);
  EXPECT_EQ(e.lm.after[1], -2.0f);
  c.storeObjectives(a, Objectives{0.25, 3, 1});  // known already: the LM outcome stays
  ASSERT_TRUE(c.find(a, e));
  EXPECT_TRUE(e.lm_known);
  c.storeObjectives(b, Objectives{0.5, 4, 0});  // replaces a
  EXPECT_FALSE(c.find(a, e));
  ASSERT_TRUE(c.find(b, e));
  EXPECT_FALSE(e.lm_known);
  c.storeLm(a, lm);  // a is gone: nothing to attach to
  EXPECT_FALSE(c.find(a, e));
}

// The premise of the key: programs with one key get bit-identical objectives, with linear
// scaling (whose mad and constants are costed) and piecewise operators.
TEST(SemanticCache, OneKeyOneScore) {
  RunConfig c;
  c.data.path = "in-memory";
  c.search.linear_scaling = true;
  c.program.max_length = 16;
  c.program.num_constants = 4;
  const Table t = test::gridTable(12);
  int finite = 0;
  for (const Program& p : programsWithIntrons(60)) {
    Search a(c, t), b(c, t);
    a.adopt({p}, 0, 0, 0, "");
    b.adopt({pruneIntrons(p)}, 0, 0, 0, "");
    ASSERT_EQ(a.archiveMembers().size(), b.archiveMembers().size());
    if (a.archiveMembers().empty()) continue;
    ++finite;
    const Objectives& x = a.archiveMembers()[0].obj;
    const Objectives& y = b.archiveMembers()[0].obj;
    EXPECT_EQ(std::bit_cast<uint64_t>(x.error), std::bit_cast<uint64_t>(y.error));
    EXPECT_EQ(x.cost, y.cost);
    EXPECT_EQ(x.discontinuity, y.discontinuity);
  }
  EXPECT_GE(finite, 30);
}

RunConfig searchConfig(int cache, ErrorMetric metric, bool scaling,
                       LmObjective lm = LmObjective::Auto) {
  RunConfig c;
  c.search.refine.lm_metric = lm;
  c.data.path = "in-memory";
  c.objectives.metric = metric;
  c.search.population = 80;
  c.search.generations = 16;
  c.search.seed = 5;
  c.search.threads = 2;
  c.search.linear_scaling = scaling;
  c.search.refine.archive_period = 4;  // offspring_share: every offspring, the default
  c.search.semantic_cache = cache;
  c.program.max_length = 16;
  return c;
}

struct Outcome {
  nlohmann::json members;
  uint64_t evaluations;
  RefineStats stats;
};

Outcome runSearch(const RunConfig& c) {
  Search s(c, test::gridTable(12));
  s.run();
  return {frontToJson(s, s.front())["members"], s.progress().evaluations, s.refineStats()};
}

// On and off: the same front and the same evaluation count, for the metrics where LM fits the
// error (rmse, max_abs with reweighted rounds) and under linear scaling (least squares, and
// max_abs with lm_metric configured: projected scales); with hits.
TEST(SemanticCache, SearchWithCacheEqualsSearchWithout) {
  struct Case {
    ErrorMetric metric;
    bool scaling;
    LmObjective lm;
  };
  for (const Case k : {Case{ErrorMetric::Rmse, false, LmObjective::Auto},
                       Case{ErrorMetric::MaxAbs, false, LmObjective::Auto},
                       Case{ErrorMetric::Rmse, true, LmObjective::Auto},
                       Case{ErrorMetric::MaxAbs, true, LmObjective::Configured}}) {
    SCOPED_TRACE(std::string(toString(k.metric)) + (k.scaling ? " scaled" : ""));
    const Outcome on = runSearch(searchConfig(1 << 12, k.metric, k.scaling, k.lm));
    const Outcome off = runSearch(searchConfig(0, k.metric, k.scaling, k.lm));
    std::printf("%s%s: score hits %llu, LM replays %llu, LM fits %llu (without: %llu)\n",
                std::string(toString(k.metric)).c_str(), k.scaling ? " scaled" : "",
                static_cast<unsigned long long>(on.stats.cache_score_hits),
                static_cast<unsigned long long>(on.stats.cache_lm_replays),
                static_cast<unsigned long long>(on.stats.lm_fits),
                static_cast<unsigned long long>(off.stats.lm_fits));
    EXPECT_EQ(on.members, off.members);
    EXPECT_EQ(on.evaluations, off.evaluations);
    EXPECT_EQ(off.stats.cache_score_hits, 0u);
    // Clones and intron-only mutants are common: a tenth of the offspring at least.
    EXPECT_GE(on.stats.cache_score_hits, 16u * 80 / 10);
    if (!k.scaling) {
      EXPECT_GT(on.stats.cache_lm_replays, 0u);
      EXPECT_LT(on.stats.lm_fits, off.stats.lm_fits);
    }
  }
}

// Clones of one program at LM's optimum: one LM fit does for all of them, and the count of
// evaluations is the one without the cache.
TEST(SemanticCache, ClonesAreFittedOnce) {
  auto run = [](int cache) {
    RunConfig c = test::cloneConfig();
    c.search.semantic_cache = cache;
    Search s(c, test::lineTable());
    test::stepClones(s);
    return std::make_pair(s.progress().evaluations, s.refineStats());
  };
  const auto [on_evals, on] = run(64);
  const auto [off_evals, off] = run(0);
  EXPECT_EQ(on_evals, off_evals);
  EXPECT_EQ(off.lm_fits, 40u);
  EXPECT_EQ(on.lm_fits, 1u);
  EXPECT_EQ(on.cache_lm_replays, 39u);
  // The adopted 40 (all but the first), then the 40 offspring.
  EXPECT_EQ(on.cache_score_hits, 79u);
}

// The cache starts empty after a resume, and is not part of the config digest: a checkpoint
// taken with the cache resumes without it, to the uninterrupted run's front.
TEST(SemanticCache, CheckpointResumesWithCacheOnOrOff) {
  const RunConfig on = searchConfig(1 << 12, ErrorMetric::Rmse, false);
  RunConfig off = on;
  off.search.semantic_cache = 0;
  Search full(on, test::gridTable(12));
  full.run();
  Search first(on, test::gridTable(12));
  for (int g = 0; g < 7; ++g) first.step();
  Search resumed(off, test::gridTable(12));
  ASSERT_TRUE(resumed.restore(nlohmann::json::parse(first.checkpoint().dump())));
  resumed.run();
  EXPECT_EQ(frontToJson(resumed, resumed.front())["members"],
            frontToJson(full, full.front())["members"]);
  EXPECT_EQ(resumed.progress().evaluations, full.progress().evaluations);
}

}  // namespace
}  // namespace lgp
