// Metrics of a DAG evaluated row by row in a given precision (private to emit/).
#pragma once

#include <vector>

#include "lgp/core/table.hpp"
#include "lgp/emit/dag.hpp"
#include "lgp/eval/objectives.hpp"

namespace lgp::emit::detail {

// Same definitions as the Scorer (objectives.hpp): weighted RMSE, max-abs, MAE, mean relative
// error with denominator max(|y|, rel_floor), R^2, on the original scale (the inverse
// transform of each output applied to the DAG's value). Any non-finite value: all +inf.
// The same metrics of given values ([output][row], inverse transforms applied) against t.
std::vector<OutputMetrics> valueMetrics(const std::vector<std::vector<double>>& values,
                                        const Table& t, double rel_floor = 1e-6);
// A DAG's value on every row of t ([output][row]), inverse transforms applied.
Expected<std::vector<std::vector<double>>> dagValues(const Dag& d, const Table& t,
                                                     const std::vector<TargetTransform>& transforms,
                                                     Precision p);
Expected<std::vector<OutputMetrics>> dagMetrics(const Dag& d, const Table& t,
                                                const std::vector<TargetTransform>& transforms,
                                                Precision p, double rel_floor = 1e-6);

}  // namespace lgp::emit::detail
