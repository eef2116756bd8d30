#include "lgp/search/migration.hpp"

#include <algorithm>
#include <cmath>
#include <iterator>
#include <numeric>

namespace lgp {

void LocalTransport::send(int /*from*/, int to, std::vector<Migrant> migrants) {
  sent_ += migrants.size();
  auto& box = inbox_.at(to);
  box.insert(box.end(), std::make_move_iterator(migrants.begin()),
             std::make_move_iterator(migrants.end()));
}

std::vector<Migrant> LocalTransport::receive(int to) {
  std::vector<Migrant> out;
  out.swap(inbox_.at(to));
  return out;
}

std::vector<int> dealIslands(const std::vector<Objectives>& objs, int islands, IslandDeal deal) {
  const int n = static_cast<int>(objs.size());
  std::vector<int> to(n, 0);
  if (islands < 1) return to;
  if (deal == IslandDeal::Interleaved) {
    for (int j = 0; j < n; ++j) to[j] = j % islands;
    return to;
  }
  std::vector<int> order(n);
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) {
    if (objs[a].cost != objs[b].cost) return objs[a].cost < objs[b].cost;
    return objs[a].error < objs[b].error;
  });
  // Slices as even as the count allows (sizes differ by one at most).
  for (int p = 0; p < n; ++p)
    to[order[p]] = static_cast<int>(static_cast<int64_t>(p) * islands / n);
  return to;
}

namespace {

// `total` dealt as `exact` says (exact sums to total): each entry gets floor(exact[k]), at
// least `at_least`, and what is left goes one each to the largest fractional parts (ties to the
// lower index); where `at_least` raised entries past `total`, the largest entries (ties: the
// lowest index) give the excess back one at a time.
std::vector<int> largestRemainders(int total, const std::vector<double>& exact, int at_least) {
  const int n = static_cast<int>(exact.size());
  std::vector<int> count(n);
  std::vector<double> frac(n);
  int given = 0;
  for (int k = 0; k < n; ++k) {
    count[k] = std::max(at_least, static_cast<int>(std::floor(exact[k])));
    frac[k] = exact[k] - std::floor(exact[k]);
    given += count[k];
  }
  std::vector<int> order(n);
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return frac[a] > frac[b]; });
  for (int j = 0; given < total && n > 0; j = (j + 1) % n, ++given) ++count[order[j]];
  while (given > total) {
    --*std::max_element(count.begin(), count.end());
    --given;
  }
  return count;
}

}  // namespace

std::vector<int> islandSizes(int population, int islands,
                             const std::vector<IslandProfile>& profiles) {
  if (islands < 1) return {};
  std::vector<double> share(islands, 1.0);
  if (!profiles.empty())
    for (int k = 0; k < islands; ++k)
      share[k] = profiles[static_cast<size_t>(k) % profiles.size()].share;
  const double sum = std::accumulate(share.begin(), share.end(), 0.0);
  std::vector<double> exact(islands);
  for (int k = 0; k < islands; ++k) exact[k] = population * share[k] / sum;
  std::vector<int> size = largestRemainders(population, exact, 0);
  for (int& s : size) s = std::max(s, 4);
  return size;
}

std::vector<int> offspringCounts(const std::vector<int>& sizes, const std::vector<double>& credit,
                                 double adaptive) {
  const int islands = static_cast<int>(sizes.size());
  const int total = std::accumulate(sizes.begin(), sizes.end(), 0);
  double sum = 0;
  for (double c : credit) sum += std::isfinite(c) && c > 0 ? c : 0;
  if (islands < 2 || adaptive <= 0 || !(sum > 0) || credit.size() != sizes.size()) return sizes;
  std::vector<double> exact(islands);
  for (int k = 0; k < islands; ++k) {
    const double c = std::isfinite(credit[k]) && credit[k] > 0 ? credit[k] : 0;
    exact[k] = total * ((1 - adaptive) * sizes[k] / total + adaptive * c / sum);
  }
  return largestRemainders(total, exact, 1);
}

ProgramShape islandShape(const ProgramShape& run, const IslandProfile& profile) {
  ProgramShape s = run;
  if (profile.max_length > 0)
    s.max_length = std::max(run.num_outputs, std::min(run.max_length, profile.max_length));
  if (profile.constants > 0) s.num_constants = std::min(run.num_constants, profile.constants);
  return s;
}

namespace {

bool fits(const Program& p, const ProgramShape& island) {
  if (static_cast<int>(p.code.size()) > island.max_length) return false;
  for (const Instr& in : p.code)
    for (int a = 0; a < arity(in.op); ++a)
      if (in.args[a].kind == OperandKind::Const && in.args[a].index >= island.num_constants)
        return false;
  return true;
}

}  // namespace

bool fitToIsland(Program& p, const ProgramShape& run, const ProgramShape& island) {
  if (fits(p, island)) return true;
  Program q = pruneIntrons(p);
  // The slots read, in ascending order, become 0, 1, ...: the same values in the first slots.
  const std::vector<int> used = effectiveConstants(q);
  if (static_cast<int>(q.code.size()) > island.max_length ||
      static_cast<int>(used.size()) > island.num_constants)
    return false;
  std::vector<int> slot(q.constants.size(), -1);
  std::vector<float> values(static_cast<size_t>(run.num_constants), 0.0f);
  for (size_t k = 0; k < used.size(); ++k) {
    slot[used[k]] = static_cast<int>(k);
    values[k] = q.constants[used[k]];
  }
  for (Instr& in : q.code)
    for (int a = 0; a < arity(in.op); ++a)
      if (in.args[a].kind == OperandKind::Const)
        in.args[a].index = static_cast<uint8_t>(slot[in.args[a].index]);
  q.constants = std::move(values);
  p = std::move(q);
  return true;
}

std::vector<int> migrationTargets(int islands, const std::vector<IslandProfile>& profiles,
                                  MigrationTopology topology) {
  std::vector<int> to(std::max(islands, 0));
  for (int k = 0; k < islands; ++k) {
    to[k] = migrationTarget(k, islands);
    if (topology != MigrationTopology::ByProfile || profiles.empty()) continue;
    const auto& mine = profiles[static_cast<size_t>(k) % profiles.size()];
    for (int step = 1; step <= islands; ++step) {
      const int j = (k + step) % islands;
      if (profiles[static_cast<size_t>(j) % profiles.size()] == mine) {
        to[k] = j;  // step == islands: j == k, alone with its profile
        break;
      }
    }
  }
  return to;
}

std::vector<int> migrationSources(const std::vector<int>& targets) {
  std::vector<int> from(targets.size());
  for (size_t k = 0; k < targets.size(); ++k) from[targets[k]] = static_cast<int>(k);
  return from;
}

}  // namespace lgp
