#include "lgp/search/migration.hpp"

#include <algorithm>
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

}  // namespace lgp
