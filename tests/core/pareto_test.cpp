#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "lgp/core/rng.hpp"
#include "lgp/search/pareto.hpp"

namespace lgp {
namespace {

Objectives O(double e, double c, double d = 0) {
  return {e, c, d};
}

TEST(Pareto, Dominance) {
  EXPECT_TRUE(dominates(O(1, 1), O(2, 1)));
  EXPECT_TRUE(dominates(O(1, 1, 0), O(1, 1, 1)));
  EXPECT_FALSE(dominates(O(1, 1), O(1, 1)));
  EXPECT_FALSE(dominates(O(1, 2), O(2, 1)));
  const Objectives bad = O(INFINITY, 0, 0);
  EXPECT_TRUE(dominates(O(1e9, 100, 9), bad));
  EXPECT_FALSE(dominates(bad, O(1e9, 100, 9)));
  EXPECT_FALSE(dominates(bad, bad));
}

TEST(Pareto, RanksAndCrowding) {
  std::vector<Objectives> objs = {O(1, 5), O(2, 3), O(3, 1), O(2, 5), O(4, 4), O(INFINITY, 0)};
  const auto r = nondominatedRanks(objs);
  EXPECT_EQ(r, (std::vector<int>{0, 0, 0, 1, 1, 2}));
  const auto d = crowdingDistance(objs, {0, 1, 2});
  EXPECT_TRUE(std::isinf(d[0]));
  EXPECT_TRUE(std::isinf(d[2]));
  EXPECT_GT(d[1], 0);
  EXPECT_FALSE(std::isinf(d[1]));
}

TEST(Pareto, RanksMatchBruteForceDefinition) {
  Rng rng(5);
  std::vector<Objectives> objs;
  for (int i = 0; i < 300; ++i)
    objs.push_back(
        O(rng.uniform(), static_cast<double>(rng.below(10)), static_cast<double>(rng.below(3))));
  const auto r = nondominatedRanks(objs);
  for (size_t i = 0; i < objs.size(); ++i) {
    int expect = 0;  // 1 + max rank of any dominator
    for (size_t j = 0; j < objs.size(); ++j)
      if (dominates(objs[j], objs[i])) expect = std::max(expect, r[j] + 1);
    EXPECT_EQ(r[i], expect);
    for (size_t j = 0; j < objs.size(); ++j) {
      if (r[j] == r[i]) {
        EXPECT_FALSE(dominates(objs[j], objs[i]));
      }
    }
  }
}

// The crowding distance as first written (log10 inside the comparator): the faster one must
// give the same distances bit for bit, ties in the same order.
std::vector<double> referenceCrowding(const std::vector<Objectives>& objs,
                                      const std::vector<int>& front) {
  const size_t m = front.size();
  std::vector<double> dist(m, 0.0);
  if (m <= 2) return std::vector<double>(m, INFINITY);
  auto value = [&](int obj, int idx) {
    const Objectives& o = objs[front[idx]];
    if (obj == 0) return o.finite() ? std::log10(std::max(o.error, 1e-300)) : 1e300;
    return obj == 1 ? o.cost : o.discontinuity;
  };
  std::vector<int> order(m);
  for (int obj = 0; obj < 3; ++obj) {
    for (size_t k = 0; k < m; ++k) order[k] = static_cast<int>(k);
    std::stable_sort(order.begin(), order.end(),
                     [&](int a, int b) { return value(obj, a) < value(obj, b); });
    const double lo = value(obj, order.front()), hi = value(obj, order.back());
    dist[order.front()] = dist[order.back()] = INFINITY;
    if (!(hi > lo)) continue;
    for (size_t k = 1; k + 1 < m; ++k)
      dist[order[k]] += (value(obj, order[k + 1]) - value(obj, order[k - 1])) / (hi - lo);
  }
  return dist;
}

TEST(Pareto, LargePopulationsRankAndCrowdAsDefined) {
  // Populations as the search makes them: few distinct costs and discontinuities, repeated
  // errors, duplicates and non-finite members.
  for (int n : {100, 700, 2000}) {
    Rng rng(n);
    std::vector<Objectives> objs;
    for (int i = 0; i < n; ++i) {
      const double e = rng.chance(0.05)  ? INFINITY
                       : rng.chance(0.2) ? 0.01 * static_cast<double>(rng.below(5))
                                         : std::exp(rng.uniform(-12.0, 0.0));
      objs.push_back(O(e, static_cast<double>(rng.below(30)), static_cast<double>(rng.below(4))));
      if (rng.chance(0.1)) {
        const Objectives dup = objs[rng.below(static_cast<uint32_t>(objs.size()))];
        objs.push_back(dup);
      }
    }
    const auto r = nondominatedRanks(objs);
    int fronts = 0;
    for (size_t i = 0; i < objs.size(); ++i) {
      int expect = 0;  // 1 + max rank of any dominator
      for (size_t j = 0; j < objs.size(); ++j)
        if (dominates(objs[j], objs[i])) expect = std::max(expect, r[j] + 1);
      ASSERT_EQ(r[i], expect) << "n " << n << " member " << i;
      fronts = std::max(fronts, r[i] + 1);
    }
    for (int f = 0; f < fronts; ++f) {
      std::vector<int> members;
      for (size_t i = 0; i < objs.size(); ++i)
        if (r[i] == f) members.push_back(static_cast<int>(i));
      const auto got = crowdingDistance(objs, members);
      const auto want = referenceCrowding(objs, members);
      ASSERT_EQ(got.size(), want.size());
      for (size_t k = 0; k < got.size(); ++k) EXPECT_EQ(got[k], want[k]) << "n " << n;
    }
  }
}

TEST(Archive, InvariantsHoldUnderRandomInsertion) {
  ArchiveConfig cfg;
  cfg.max_size = 40;
  Archive a(cfg);
  Rng rng(11);
  Program p;
  for (int i = 0; i < 5000; ++i) {
    const double e = std::pow(10.0, -6 * rng.uniform());
    Objectives o = O(e, static_cast<double>(rng.below(30)), static_cast<double>(rng.below(4)));
    if (i % 97 == 0) o.error = NAN;
    a.insert(p, o);
    ASSERT_LE(a.members().size(), 40u);
  }
  const auto& m = a.members();
  ASSERT_FALSE(m.empty());
  for (size_t i = 0; i < m.size(); ++i) {
    EXPECT_TRUE(m[i].obj.finite());
    for (size_t j = 0; j < m.size(); ++j) {
      if (i != j) {
        EXPECT_FALSE(dominates(m[j].obj, m[i].obj)) << i << " dominated by " << j;
      }
    }
  }
}

TEST(Archive, EpsilonBoxesCollapseNearDuplicates) {
  ArchiveConfig cfg;
  cfg.eps_log10_error = 0.01;
  Archive a(cfg);
  Program p;
  EXPECT_TRUE(a.insert(p, O(1.000, 5)));
  EXPECT_FALSE(a.insert(p, O(1.0001, 5)));  // same box, worse
  EXPECT_TRUE(a.insert(p, O(0.9999, 5)));   // same box, better: replaces
  EXPECT_EQ(a.members().size(), 1u);
  EXPECT_TRUE(a.insert(p, O(0.5, 6)));  // a new trade-off
  EXPECT_FALSE(a.insert(p, O(NAN, 0)));
  EXPECT_FALSE(a.insert(p, O(INFINITY, 0)));
  EXPECT_EQ(a.members().size(), 2u);
  EXPECT_TRUE(a.insert(p, O(0.1, 1)));  // dominates both
  EXPECT_EQ(a.members().size(), 1u);
}

TEST(Archive, SizeBoundKeepsExtremes) {
  ArchiveConfig cfg;
  cfg.max_size = 5;
  Archive a(cfg);
  Program p;
  for (int c = 0; c < 20; ++c) a.insert(p, O(std::pow(0.5, c), c));
  ASSERT_EQ(a.members().size(), 5u);
  double min_e = INFINITY, min_c = INFINITY;
  for (const auto& m : a.members()) {
    min_e = std::min(min_e, m.obj.error);
    min_c = std::min(min_c, m.obj.cost);
  }
  EXPECT_EQ(min_c, 0);
  EXPECT_DOUBLE_EQ(min_e, std::pow(0.5, 19));
}

}  // namespace
}  // namespace lgp
