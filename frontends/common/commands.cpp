#include "commands.hpp"

#include <algorithm>

namespace lgp::cli {

namespace {
std::vector<Command>& registry() {
  static std::vector<Command> r;  // function-local: safe during static initialisation
  return r;
}
}  // namespace

void registerCommand(const Command& c) {
  auto& r = registry();
  r.push_back(c);
  std::sort(r.begin(), r.end(), [](const Command& a, const Command& b) { return a.name < b.name; });
}

const std::vector<Command>& commands() {
  return registry();
}

}  // namespace lgp::cli
