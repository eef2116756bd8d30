// The discontinuity objective of the search (objectives.hpp lists the three).
#pragma once

#include <array>
#include <vector>

#include "lgp/core/interval.hpp"
#include "lgp/core/ops.hpp"
#include "lgp/core/program.hpp"

namespace lgp {

// Discontinuity: the weighted count of effective piecewise operators whose branch may switch
// on `domain` (interval.hpp: abs of a value that keeps its sign, saturate of a value inside
// [0, 1], min/max with a dominated operand and a select whose comparison never changes count
// nothing). A pure function of the program and the domain, so the search stays deterministic.
struct DiscontinuityModel {
  std::array<double, kNumOps> weight{};  // default: 1 for piecewise ops, 0 otherwise
  std::vector<Interval> domain;          // per input (tableDomain); empty: every one counts
  static DiscontinuityModel defaults();
  double programDiscontinuity(const Program& p) const;
  double programDiscontinuity(const Program& p, const std::vector<int>& effective) const;
};

}  // namespace lgp
