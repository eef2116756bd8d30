// One generation of clones: c0 + c1 x, at its optimum on y = 0.5 + 2 x, adopted as the whole
// population and bred with neither crossover nor mutation, every offspring refined. Shared by
// the tests of what refinement spends on programs it has fitted before.
#pragma once

#include <vector>

#include "lgp/search/search.hpp"
#include "test_tables.hpp"

namespace lgp::test {

inline Table lineTable() {
  return sampledTable(200, 2, [](double x) { return 0.5 + 2 * x; });
}

// c0 + c1 x, at the optimum.
inline Program line() {
  Program p;
  p.constants = {0.5f, 2.0f};
  p.code = {{Op::Mul, {inputOperand(0), constOperand(1)}},
            {Op::Add, {regOperand(0), constOperand(0)}}};
  p.outputs = {1};
  return p;
}

// 40 individuals on 1 thread over add and mul, no variation, every offspring refined.
inline RunConfig cloneConfig() {
  RunConfig c;
  c.data.path = "in-memory";
  c.program.ops = {Op::Add, Op::Mul};
  c.program.num_constants = 2;
  c.program.max_length = 8;
  c.search.population = 40;
  c.search.threads = 1;
  c.search.variation.crossover_rate = 0;
  c.search.variation.macro_rate = 0;
  c.search.variation.micro_rate = 0;
  c.search.refine.offspring_share = 1.0;
  return c;
}

// Adopts population-many copies of line() and breeds one generation of them.
inline void stepClones(Search& s) {
  s.adopt(std::vector<Program>(s.config().search.population, line()), 0, 0, 0, "");
  s.step(false);
}

}  // namespace lgp::test
