// Small tables shared by the search tests.
#pragma once

#include <cmath>

#include "lgp/core/table.hpp"

namespace lgp::test {

// An n x n grid over (mu, r) in (0, 1)^2 of a smooth two-input target with a rational and an
// exponential part: cheap to score, not trivially recovered.
inline Table gridTable(int n) {
  Table t;
  t.input_names = {"mu", "r"};
  t.output_names = {"y"};
  t.inputs.resize(2);
  t.outputs.resize(1);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      const double mu = (i + 0.5) / n, r = (j + 0.5) / n;
      t.inputs[0].push_back(mu);
      t.inputs[1].push_back(r);
      t.outputs[0].push_back(mu * r / (mu + 0.5) + 0.1 * std::exp2(-3 * mu));
    }
  return t;
}

}  // namespace lgp::test
