// The periodic archive refinement: which unrefined members it serves first
// (search.refine.archive_order) and how the refined members rejoin the islands
// (search.islands.deal).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <set>

#include "lgp/search/migration.hpp"
#include "lgp/search/pareto.hpp"
#include "lgp/search/search.hpp"
#include "test_tables.hpp"

namespace lgp {
namespace {

ArchiveMember member(double error, double cost, bool refined = false) {
  ArchiveMember m;
  m.obj.error = error;
  m.obj.cost = cost;
  m.refined = refined;
  return m;
}

// Five long-lived cheap members are stored first, the accurate end last (as after it changed).
std::vector<ArchiveMember> cheapFirst() {
  return {member(0.5, 1), member(0.4, 2, true), member(0.3, 3),   member(0.2, 4),
          member(0.1, 5), member(0.05, 6),      member(1e-3, 40), member(1e-4, 60)};
}

TEST(RefineQueue, OldestServesStorageOrder) {
  EXPECT_EQ(refineQueue(cheapFirst(), 3, ArchiveRefineOrder::Oldest), (std::vector<int>{0, 2, 3}));
}

TEST(RefineQueue, AccurateServesTheAccurateEndFirst) {
  EXPECT_EQ(refineQueue(cheapFirst(), 3, ArchiveRefineOrder::Accurate),
            (std::vector<int>{7, 6, 5}));
  // Refined members are never queued; max 0 queues none.
  const auto all = refineQueue(cheapFirst(), 100, ArchiveRefineOrder::Accurate);
  EXPECT_EQ(all, (std::vector<int>{7, 6, 5, 4, 3, 2, 0}));
  EXPECT_TRUE(refineQueue(cheapFirst(), 0, ArchiveRefineOrder::Accurate).empty());
}

TEST(RefineQueue, TiesGoToTheCheaperThenTheEarlierMember) {
  std::vector<ArchiveMember> m = {member(0.1, 9), member(0.1, 3), member(0.1, 3)};
  EXPECT_EQ(refineQueue(m, 3, ArchiveRefineOrder::Accurate), (std::vector<int>{1, 2, 0}));
}

TEST(DealIslands, InterleavedDealsInTurn) {
  std::vector<Objectives> o(6);
  for (int j = 0; j < 6; ++j) o[j].cost = 10 - j;
  EXPECT_EQ(dealIslands(o, 4, IslandDeal::Interleaved), (std::vector<int>{0, 1, 2, 3, 0, 1}));
}

TEST(DealIslands, ByCostGivesEachIslandItsOwnCostSlice) {
  std::vector<Objectives> o(9);
  const double costs[9] = {7, 1, 9, 3, 8, 2, 6, 4, 5};
  for (int j = 0; j < 9; ++j) o[j].cost = costs[j];
  const auto to = dealIslands(o, 3, IslandDeal::ByCost);
  // Costs 1-3 to island 0, 4-6 to island 1, 7-9 to island 2.
  for (int j = 0; j < 9; ++j) EXPECT_EQ(to[j], (static_cast<int>(costs[j]) - 1) / 3) << j;
  // Fewer members than islands: one each, the cheapest to the first.
  EXPECT_EQ(dealIslands({o[0], o[1]}, 4, IslandDeal::ByCost), (std::vector<int>{2, 0}));
}

constexpr int kBefore = 20;  // generations before the one observed

RunConfig leverConfig(int islands) {
  RunConfig c;
  c.data.path = "in-memory";
  c.search.population = 96;
  c.search.generations = kBefore + 1;
  c.search.seed = 11;
  c.search.threads = 1;
  c.search.islands.count = islands;
  c.search.islands.migration_interval = 0;
  c.search.refine.offspring_share = 0;           // constants left to the archive refinement
  c.search.refine.archive_period = kBefore + 1;  // the observed generation refines, first
  c.program.max_length = 16;
  return c;
}

// A search kBefore generations in, its archive stored cheapest first (the accurate end last, as
// behind long-lived cheap members), then one more generation: the first archive refinement.
Search& refinedOnce(Search& s) {
  Search before(s.config(), s.table());
  for (int g = 0; g <= kBefore; ++g) before.step();
  nlohmann::json ck = before.checkpoint();
  auto& arch = ck["archive"];
  std::stable_sort(arch.begin(), arch.end(), [](const nlohmann::json& a, const nlohmann::json& b) {
    return a["obj"][1].get<double>() < b["obj"][1].get<double>();
  });
  EXPECT_TRUE(s.restore(ck));
  s.step();
  return s;
}

bool lowestErrorRefined(const Search& s) {
  const auto& m = s.archiveMembers();
  const auto it = std::min_element(
      m.begin(), m.end(), [](const auto& a, const auto& b) { return a.obj.error < b.obj.error; });
  return it->refined;
}

TEST(ArchiveOrder, AccurateEndIsRefinedInTheFirstPass) {
  RunConfig c = leverConfig(4);
  c.search.refine.archive_max = 1;
  // Storage order refines the cheapest member and leaves the accurate end waiting...
  c.search.refine.archive_order = ArchiveRefineOrder::Oldest;
  Search oldest(c, test::gridTable(10));
  ASSERT_GE(refinedOnce(oldest).archiveMembers().size(), 3u);  // more than one pass refines
  EXPECT_FALSE(lowestErrorRefined(oldest));
  // ...the accurate order refines it (or a refined improvement of it leads now).
  c.search.refine.archive_order = ArchiveRefineOrder::Accurate;
  Search accurate(c, test::gridTable(10));
  EXPECT_TRUE(lowestErrorRefined(refinedOnce(accurate)));
}

// The costs of the refined members each island holds after one dealing (the islands' only
// refined members: offspring and migrants are not fully refined).
std::vector<std::vector<double>> refinedCosts(const Search& s, std::set<std::string>& programs,
                                              int& repeated) {
  std::vector<std::vector<double>> out;
  const nlohmann::json ck = s.checkpoint();
  for (const auto& isl : ck["islands"]) {
    out.emplace_back();
    std::set<std::string> here;
    for (const auto& ind : isl["population"])
      if (ind["refined"].get<bool>()) {
        out.back().push_back(ind["obj"][1].get<double>());
        here.insert(ind["program"].dump());
      }
    for (const auto& p : here) repeated += !programs.insert(p).second;
  }
  return out;
}

// Island k's refined members all cost at most island k+1's.
bool costSlices(const std::vector<std::vector<double>>& costs) {
  double floor = -1;
  for (const auto& c : costs) {
    if (c.empty()) continue;
    if (*std::min_element(c.begin(), c.end()) < floor) return false;
    floor = *std::max_element(c.begin(), c.end());
  }
  return true;
}

TEST(IslandDealing, EachRefinedMemberJoinsOneIslandAndByCostKeepsThemApart) {
  // Two islands: the runs are small, and so are their fronts.
  RunConfig c = leverConfig(2);
  c.search.refine.archive_max = 16;
  // A run whose first refinement has several members to deal (seeds 1-20 all deal 3-8; this
  // one 6-7, so the checks below have room).
  c.search.seed = 3;
  for (IslandDeal deal : {IslandDeal::Interleaved, IslandDeal::ByCost}) {
    c.search.islands.deal = deal;
    Search s(c, test::gridTable(10));
    std::set<std::string> programs;
    int repeated = 0;
    const auto costs = refinedCosts(refinedOnce(s), programs, repeated);
    ASSERT_EQ(costs.size(), 2u);
    int islands_with_refined = 0, refined = 0;
    for (const auto& k : costs) {
      islands_with_refined += !k.empty();
      refined += static_cast<int>(k.size());
    }
    // No island holds another's refined member, and several islands got some.
    EXPECT_EQ(repeated, 0);
    EXPECT_EQ(islands_with_refined, 2);
    EXPECT_GE(refined, 4);
    // In turn, every island gets a sample of the whole batch (overlapping cost ranges); by
    // cost, island k gets the k-th stretch of the front.
    EXPECT_EQ(costSlices(costs), deal == IslandDeal::ByCost) << toString(deal);
  }
}

Objectives objective(double error, double cost) {
  Objectives o;
  o.error = error;
  o.cost = cost;
  return o;
}

TEST(StratifiedSurvivors, OffKeepsTheNsgaOrder) {
  const std::vector<Objectives> pool = {objective(0.1, 1), objective(0.05, 2),
                                        objective(0.045, 10)};
  EXPECT_EQ(stratifiedSurvivors(pool, {0, 1, 2}, 2, 0), (std::vector<int>{0, 1}));
}

TEST(StratifiedSurvivors, TheBestOfAnExpensiveSliceSurvivesWhereNsgaDropsIt) {
  // (0.045, 10) is dominated by (0.04, 3): NSGA-II order puts it last and a survival of 3
  // drops it; with two cost slices it is the best of the upper one.
  const std::vector<Objectives> pool = {objective(0.1, 1), objective(0.05, 2), objective(0.04, 3),
                                        objective(0.045, 10)};
  const std::vector<int> order = {0, 1, 2, 3};
  EXPECT_EQ(stratifiedSurvivors(pool, order, 3, 0), (std::vector<int>{0, 1, 2}));
  EXPECT_EQ(stratifiedSurvivors(pool, order, 3, 2), (std::vector<int>{2, 3, 0}));
}

TEST(StratifiedSurvivors, DuplicatesAndNonFiniteMembersAreNotReserved) {
  // One slice and keep 8: the 2 lowest-error distinct finite members are reserved. The NaN
  // member would sort anywhere; (0.045, 10) twice counts once.
  std::vector<Objectives> pool = {
      objective(0.1, 1),  objective(0.05, 2),  objective(0.045, 10),        objective(0.045, 10),
      objective(0.06, 9), objective(0.2, 9.5), objective(std::nan(""), 10), objective(0.3, 5)};
  const std::vector<int> order = {0, 1, 4, 5, 7, 2, 3, 6};
  EXPECT_EQ(stratifiedSurvivors(pool, order, 8, 1), (std::vector<int>{2, 1, 0, 4, 5, 7, 3, 6}));
  // keep is capped at the pool, and a short keep takes the reserved ones first.
  EXPECT_EQ(stratifiedSurvivors(pool, order, 20, 1).size(), 8u);
  EXPECT_EQ(stratifiedSurvivors(pool, order, 3, 1), (std::vector<int>{2, 0, 1}));
}

}  // namespace
}  // namespace lgp
