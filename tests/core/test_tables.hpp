// Small tables shared by the search tests.
#pragma once

#include <cmath>
#include <cstdint>
#include <string>

#include "lgp/core/rng.hpp"
#include "lgp/core/table.hpp"

namespace lgp::test {

// An n x n grid of cell centres over (0, 1)^2, the first input varying slowest, with the
// output f(a, b).
template <class F>
Table gridTableOf(int n, F f, const std::string& a = "mu", const std::string& b = "r",
                  const std::string& out = "y") {
  Table t;
  t.input_names = {a, b};
  t.output_names = {out};
  t.inputs.resize(2);
  t.outputs.resize(1);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      const double u = (i + 0.5) / n, v = (j + 0.5) / n;
      t.inputs[0].push_back(u);
      t.inputs[1].push_back(v);
      t.outputs[0].push_back(f(u, v));
    }
  return t;
}

// An n x n grid over (mu, r) in (0, 1)^2 of a smooth two-input target with a rational and an
// exponential part: cheap to score, not trivially recovered.
inline Table gridTable(int n) {
  return gridTableOf(
      n, [](double mu, double r) { return mu * r / (mu + 0.5) + 0.1 * std::exp2(-3 * mu); });
}

// `rows` samples of x uniform in [-1, 1] (Rng(seed)) with the output y = f(x).
template <class F>
Table sampledTable(int rows, uint64_t seed, F f) {
  Table t;
  Rng rng(seed);
  t.input_names = {"x"};
  t.output_names = {"y"};
  t.inputs.resize(1);
  t.outputs.resize(1);
  for (int r = 0; r < rows; ++r) {
    const double x = rng.uniform(-1, 1);
    t.inputs[0].push_back(x);
    t.outputs[0].push_back(f(x));
  }
  return t;
}

}  // namespace lgp::test
