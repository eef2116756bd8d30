#include "lgp/core/ops.hpp"

namespace lgp {

std::optional<Op> opFromString(std::string_view name) {
  for (const auto& i : allOps())
    if (i.name == name) return i.op;
  return std::nullopt;
}

std::string fillOpTemplate(std::string_view tmpl, const std::vector<std::string>& args) {
  std::string out;
  out.reserve(tmpl.size() + 16);
  for (size_t i = 0; i < tmpl.size(); ++i) {
    if (tmpl[i] == '{' && i + 2 < tmpl.size() && tmpl[i + 2] == '}') {
      const int k = tmpl[i + 1] - '0';
      if (k >= 0 && k < static_cast<int>(args.size())) {
        out += args[k];
        i += 2;
        continue;
      }
    }
    out += tmpl[i];
  }
  return out;
}

std::optional<CostTarget> costTargetFromString(std::string_view name) {
  for (int i = 0; i < kNumCostTargets; ++i)
    if (kCostTargetNames[i] == name) return static_cast<CostTarget>(i);
  return std::nullopt;
}

}  // namespace lgp
