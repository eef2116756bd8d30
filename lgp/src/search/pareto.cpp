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
  // Efficient non-dominated sort (ENS-SS, Zhang et al. 2015): in lexicographic order an
  // individual can only be dominated by one before it, so each is placed in the first front
  // none of whose members dominates it, scanning each front from its most recent member.
  const int n = static_cast<int>(objs.size());
  std::vector<int> order(n);
  std::iota(order.begin(), order.end(), 0);
  auto key = [&](int i) {
    return objs[i].finite() ? objs[i].error : std::numeric_limits<double>::infinity();
  };
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) {
    if (key(a) != key(b)) return key(a) < key(b);
    if (objs[a].cost != objs[b].cost) return objs[a].cost < objs[b].cost;
    return objs[a].discontinuity < objs[b].discontinuity;
  });
  std::vector<int> rank(n, 0);
  std::vector<std::vector<int>> fronts;
  for (const int i : order) {
    size_t f = 0;
    for (; f < fronts.size(); ++f) {
      bool dominated = false;
      for (auto it = fronts[f].rbegin(); it != fronts[f].rend(); ++it)
        if (dominates(objs[*it], objs[i])) {
          dominated = true;
          break;
        }
      if (!dominated) break;
    }
    if (f == fronts.size()) fronts.emplace_back();
    fronts[f].push_back(i);
    rank[i] = static_cast<int>(f);
  }
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
  // Error is compared on a log scale: the interesting trade-offs span decades.
  auto value = [&](int obj, int idx) {
    const Objectives& o = objs[front[idx]];
    if (obj == 0) return o.finite() ? std::log10(std::max(o.error, 1e-300)) : 1e300;
    return obj == 1 ? o.cost : o.discontinuity;
  };
  std::vector<int> order(m);
  for (int obj = 0; obj < 3; ++obj) {
    std::iota(order.begin(), order.end(), 0);
    std::stable_sort(order.begin(), order.end(),
                     [&](int a, int b) { return value(obj, a) < value(obj, b); });
    const double lo = value(obj, order.front()), hi = value(obj, order.back());
    dist[order.front()] = dist[order.back()] = std::numeric_limits<double>::infinity();
    if (!(hi > lo)) continue;
    for (size_t k = 1; k + 1 < m; ++k)
      dist[order[k]] += (value(obj, order[k + 1]) - value(obj, order[k - 1])) / (hi - lo);
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

bool Archive::insert(const Program& p, const Objectives& o, bool refined) {
  if (!o.finite() || !std::isfinite(o.cost) || !std::isfinite(o.discontinuity)) return false;
  const Box b = box(o);
  for (const auto& m : members_) {
    const Box mb = box(m.obj);
    if (boxDominates(mb.e, mb.c, mb.d, b.e, b.c, b.d)) return false;
    if (mb.e == b.e && mb.c == b.c && mb.d == b.d) {
      // Same box: keep the dominating one, else the one with lower error (then lower cost).
      if (dominates(m.obj, o) ||
          !(o.error < m.obj.error || (o.error == m.obj.error && o.cost < m.obj.cost)))
        return false;
    }
  }
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

}  // namespace lgp
