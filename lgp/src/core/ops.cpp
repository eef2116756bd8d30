#include "lgp/core/ops.hpp"

namespace lgp {

std::optional<Op> opFromString(std::string_view name) {
  for (const auto& i : allOps())
    if (i.name == name) return i.op;
  return std::nullopt;
}

std::optional<CostTarget> costTargetFromString(std::string_view name) {
  for (int i = 0; i < kNumCostTargets; ++i)
    if (kCostTargetNames[i] == name) return static_cast<CostTarget>(i);
  return std::nullopt;
}

}  // namespace lgp
