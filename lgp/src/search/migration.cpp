#include "lgp/search/migration.hpp"

#include <iterator>

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

}  // namespace lgp
