#include "lgp/search/pareto.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

namespace lgp {

bool dominates(const Objectives& a, const Objectives& b) {
  if (!a.finite()) return false;
  if (!b.finite()) return true;
  const bool no_worse =
      a.error <= b.error && a.cost <= b.cost && a.discontinuity <= b.discontinuity;
  const bool better = a.error < b.error || a.cost < b.cost || a.discontinuity < b.discontinuity;
  return no_worse && better;
}

std::vector<int> nondominatedRanks(const std::vector<Objectives>& objs) {
  // Efficient non-dominated sort (Zhang et al. 2015): in lexicographic order (error, cost,
  // discontinuity) an individual can only be dominated by one before it, so each is placed in
  // the first front none of whose members dominates it. The fronts are searched by bisection
  // (their ENS-BS): every member of front k is dominated by one of front k-1, so if front k
  // dominates an individual, so do all fronts before k. With three objectives, an earlier j
  // (error_j <= error_i) dominates i exactly when cost_j <= cost_i and disc_j <= disc_i, unless
  // the two are equal in all three; so each front is queried through its staircase of
  // (cost, disc)-minimal members, by binary search. The rank is 1 + the highest rank of the
  // individual's dominators whatever the search, so results do not change.
  struct Key {
    double e, c, d;
    int i;
  };
  const int n = static_cast<int>(objs.size());
  std::vector<Key> keys;
  keys.reserve(n);
  std::vector<int> rank(n, 0);
  std::vector<int> bad;  // non-finite error: dominated by every finite one, dominate none
  for (int i = 0; i < n; ++i) {
    if (objs[i].finite())
      keys.push_back({objs[i].error, objs[i].cost, objs[i].discontinuity, i});
    else
      bad.push_back(i);
  }
  std::sort(keys.begin(), keys.end(), [](const Key& a, const Key& b) {
    if (a.e != b.e) return a.e < b.e;
    if (a.c != b.c) return a.c < b.c;
    if (a.d != b.d) return a.d < b.d;
    return a.i < b.i;
  });
  // A front's staircase: its (cost, disc)-minimal members by ascending cost (so descending
  // disc), each with the lowest error seen at that (cost, disc).
  struct Step {
    double c, d, e;
  };
  std::vector<std::vector<Step>> fronts;
  auto dominated = [](const std::vector<Step>& st, const Key& k) {
    // The lowest disc among members with cost <= k.c is that of the last such step.
    auto it = std::upper_bound(st.begin(), st.end(), k.c,
                               [](double c, const Step& s) { return c < s.c; });
    if (it == st.begin()) return false;
    const Step& p = *(it - 1);
    if (!(p.d <= k.d)) return false;
    return p.c != k.c || p.d != k.d || p.e < k.e;
  };
  auto insert = [](std::vector<Step>& st, const Key& k) {
    auto it = std::lower_bound(st.begin(), st.end(), k.c,
                               [](const Step& s, double c) { return s.c < c; });
    if (it != st.end() && it->c == k.c && it->d == k.d) return;  // keeps the lower error
    // k is not dominated here, so the steps it covers (cost >= k.c, disc >= k.d) follow it.
    auto last = it;
    while (last != st.end() && last->d >= k.d) ++last;
    it = st.erase(it, last);
    st.insert(it, Step{k.c, k.d, k.e});
  };
  for (const Key& k : keys) {
    size_t lo = 0, hi = fronts.size();  // the first non-dominating front is in [lo, hi]
    while (lo < hi) {
      const size_t mid = lo + (hi - lo) / 2;
      if (dominated(fronts[mid], k))
        lo = mid + 1;
      else
        hi = mid;
    }
    if (lo == fronts.size()) fronts.emplace_back();
    insert(fronts[lo], k);
    rank[k.i] = static_cast<int>(lo);
  }
  for (int i : bad) rank[i] = static_cast<int>(fronts.size());
  return rank;
}

std::vector<double> crowdingDistance(const std::vector<Objectives>& objs,
                                     const std::vector<int>& front) {
  const size_t m = front.size();
  std::vector<double> dist(m, 0.0);
  if (m <= 2) {
    std::fill(dist.begin(), dist.end(), std::numeric_limits<double>::infinity());
    return dist;
  }
  // Error is compared on a log scale: the interesting trade-offs span decades. Keys are
  // computed once per objective, not in the comparator.
  std::vector<std::pair<double, int>> key(m);
  for (int obj = 0; obj < 3; ++obj) {
    for (size_t k = 0; k < m; ++k) {
      const Objectives& o = objs[front[k]];
      const double v = obj == 0   ? (o.finite() ? std::log10(std::max(o.error, 1e-300)) : 1e300)
                       : obj == 1 ? o.cost
                                  : o.discontinuity;
      key[k] = {v, static_cast<int>(k)};
    }
    std::stable_sort(key.begin(), key.end(),
                     [](const auto& a, const auto& b) { return a.first < b.first; });
    const double lo = key.front().first, hi = key.back().first;
    dist[key.front().second] = dist[key.back().second] = std::numeric_limits<double>::infinity();
    if (!(hi > lo)) continue;
    for (size_t k = 1; k + 1 < m; ++k)
      dist[key[k].second] += (key[k + 1].first - key[k - 1].first) / (hi - lo);
  }
  return dist;
}

Status ArchiveConfig::validate() const {
  if (max_size < 1) return Status::error("max_size: must be >= 1");
  if (!(eps_log10_error >= 0)) return Status::error("eps_log10_error: must be >= 0");
  if (!(eps_cost >= 0)) return Status::error("eps_cost: must be >= 0");
  if (!(eps_discontinuity >= 0)) return Status::error("eps_discontinuity: must be >= 0");
  return Status::ok();
}

Archive::Archive(ArchiveConfig cfg) : cfg_(cfg) {}

Archive::Box Archive::box(const Objectives& o) const {
  auto q = [](double v, double eps) {
    if (eps <= 0) return static_cast<long long>(std::llround(v * 1e6));  // exact up to 1e-6
    return static_cast<long long>(std::floor(v / eps));
  };
  const double le = std::log10(std::max(o.error, 1e-30));
  return {q(le, cfg_.eps_log10_error), q(o.cost, cfg_.eps_cost),
          q(o.discontinuity, cfg_.eps_discontinuity)};
}

namespace {
bool boxDominates(long long ae, long long ac, long long ad, long long be, long long bc,
                  long long bd) {
  return ae <= be && ac <= bc && ad <= bd && (ae < be || ac < bc || ad < bd);
}
}  // namespace

bool Archive::rejects(const Objectives& o) const {
  if (!o.finite() || !std::isfinite(o.cost) || !std::isfinite(o.discontinuity)) return true;
  const Box b = box(o);
  for (const auto& m : members_) {
    const Box mb = box(m.obj);
    if (boxDominates(mb.e, mb.c, mb.d, b.e, b.c, b.d)) return true;
    if (mb.e == b.e && mb.c == b.c && mb.d == b.d) {
      // Same box: keep the dominating one, else the one with lower error (then lower cost).
      if (dominates(m.obj, o) ||
          !(o.error < m.obj.error || (o.error == m.obj.error && o.cost < m.obj.cost)))
        return true;
    }
  }
  return false;
}

bool Archive::insert(const Program& p, const Objectives& o, bool refined) {
  if (rejects(o)) return false;
  const Box b = box(o);
  std::vector<ArchiveMember> kept;
  kept.reserve(members_.size() + 1);
  for (auto& m : members_) {
    const Box mb = box(m.obj);
    const bool same = mb.e == b.e && mb.c == b.c && mb.d == b.d;
    if (same || boxDominates(b.e, b.c, b.d, mb.e, mb.c, mb.d)) continue;
    kept.push_back(std::move(m));
  }
  kept.push_back({p, o, refined});
  members_.swap(kept);
  enforceSize();
  return true;
}

void Archive::enforceSize() {
  while (static_cast<int>(members_.size()) > cfg_.max_size) {
    std::vector<Objectives> objs;
    for (const auto& m : members_) objs.push_back(m.obj);
    std::vector<int> all(members_.size());
    std::iota(all.begin(), all.end(), 0);
    auto dist = crowdingDistance(objs, all);
    // Protect the extremes of error and cost explicitly.
    size_t best_e = 0, best_c = 0;
    for (size_t i = 1; i < members_.size(); ++i) {
      if (objs[i].error < objs[best_e].error) best_e = i;
      if (objs[i].cost < objs[best_c].cost) best_c = i;
    }
    dist[best_e] = dist[best_c] = std::numeric_limits<double>::infinity();
    size_t worst = 0;
    for (size_t i = 1; i < dist.size(); ++i)
      if (dist[i] < dist[worst]) worst = i;
    members_.erase(members_.begin() + worst);
  }
}

void Archive::rebuild() {
  auto old = std::move(members_);
  members_.clear();
  // Insert in a canonical order so the result does not depend on the previous layout.
  std::stable_sort(old.begin(), old.end(), [](const ArchiveMember& a, const ArchiveMember& b) {
    if (a.obj.error != b.obj.error) return a.obj.error < b.obj.error;
    return a.obj.cost < b.obj.cost;
  });
  for (auto& m : old) insert(m.program, m.obj, m.refined);
}

std::vector<ArchiveMember> Archive::sorted() const {
  auto out = members_;
  std::stable_sort(out.begin(), out.end(), [](const ArchiveMember& a, const ArchiveMember& b) {
    if (a.obj.cost != b.obj.cost) return a.obj.cost < b.obj.cost;
    if (a.obj.error != b.obj.error) return a.obj.error < b.obj.error;
    return a.obj.discontinuity < b.obj.discontinuity;
  });
  return out;
}

std::vector<int> refineQueue(const std::vector<ArchiveMember>& members, int max,
                             ArchiveRefineOrder order) {
  std::vector<int> todo;
  for (int i = 0; i < static_cast<int>(members.size()); ++i)
    if (!members[i].refined) todo.push_back(i);
  if (order == ArchiveRefineOrder::Accurate)
    std::stable_sort(todo.begin(), todo.end(), [&](int a, int b) {
      const Objectives &x = members[a].obj, &y = members[b].obj;
      if (x.error != y.error) return x.error < y.error;
      if (x.cost != y.cost) return x.cost < y.cost;
      return x.discontinuity < y.discontinuity;
    });
  if (static_cast<int>(todo.size()) > max) todo.resize(std::max(0, max));
  return todo;
}

std::vector<int> stratifiedSurvivors(const std::vector<Objectives>& pool,
                                     const std::vector<int>& order, int keep, int strata) {
  keep = std::min(keep, static_cast<int>(order.size()));
  if (strata <= 0) return {order.begin(), order.begin() + keep};
  constexpr double kInf = std::numeric_limits<double>::infinity();
  const int n = static_cast<int>(pool.size());
  double lo = kInf, hi = -kInf;
  for (const auto& o : pool)
    if (o.finite()) {
      lo = std::min(lo, o.cost);
      hi = std::max(hi, o.cost);
    }
  std::vector<uint8_t> taken(n, 0);
  std::vector<int> out;
  out.reserve(keep);
  if (lo < hi) {
    const int per = std::max(1, keep / (4 * strata));
    std::vector<std::vector<int>> slices(strata);
    for (int i = 0; i < n; ++i)
      if (pool[i].finite())
        slices[std::min(strata - 1, static_cast<int>((pool[i].cost - lo) / (hi - lo) * strata))]
            .push_back(i);
    for (auto& slice : slices) {
      std::stable_sort(slice.begin(), slice.end(),
                       [&](int a, int b) { return pool[a].error < pool[b].error; });
      int got = 0;
      const Objectives* last = nullptr;
      for (int i : slice) {
        if (got == per || static_cast<int>(out.size()) == keep) break;
        const Objectives& o = pool[i];
        if (last && o.error == last->error && o.cost == last->cost &&
            o.discontinuity == last->discontinuity)
          continue;
        out.push_back(i);
        taken[i] = 1;
        last = &o;
        ++got;
      }
    }
  }
  for (int i : order) {
    if (static_cast<int>(out.size()) == keep) break;
    if (!taken[i]) out.push_back(i);
  }
  return out;
}

}  // namespace lgp
