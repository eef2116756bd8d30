// Exhaustive enumeration of small programs (search.exhaustive), after Bartlett, Desmond and
// Ferreira, "Exhaustive Symbolic Regression" (IEEE TEVC 2024): every distinct expression of up
// to `max_ops` operators over the run's inputs and free constants is built, its constants are
// fitted, and the best per operator count and the non-dominated ones are kept. They seed the
// islands, and the front JSON gets a certificate: within this grammar, no expression of at
// most k operators does better than the error stated for k (up to the constant fit, which is
// local: Levenberg-Marquardt, then the run's error on the whole table).
//
// Enumeration. Expression trees by operator count s: leaves (each input, and a free constant
// `c`) for s = 0; an operator over trees whose operator counts sum to s - 1. Each tree is
// evaluated at probe points (the table's box: corners, some rows, random points) with its free
// constants at two fixed draws of values; a tree whose values match an earlier tree's is the
// same function of its inputs and constants and is dropped (the earlier one, of no more
// operators, stands for it as an operand too). Also pruned: an operator whose operands are all
// constants, the second commutative operand ordered before the first (add, mul, min, max,
// mad's product), and a tree with free constants that is constant over the points (a free
// constant does as well). With linear scaling, a tree that is an affine image of an earlier
// one (a f + b: the same error once scaled) is kept as an operand but not fitted again. A tree
// becomes a program by common-subexpression elimination, so a repeated sub-tree costs one
// opcode. Screening: constants fitted on a row subset (from +1, 8 iterations), the best `keep`
// per operator count go on to the fit on every row (from the screened constants, +1 and -1).
//
// Equality at the probe points stands for equality everywhere: two different functions that
// agree at every probe point and both draws of constants (to about 9 digits) would be taken as
// one. For the analytic operators that needs a coincidence; for piecewise ones (min, max, abs,
// saturate) a kink outside the box at both draws.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "lgp/config/config.hpp"
#include "lgp/core/program.hpp"
#include "lgp/core/table.hpp"
#include "lgp/eval/objectives.hpp"

namespace lgp {

struct ExhaustiveMember {
  Program program;  // one output, Last mode, linear scaling applied when the run uses it
  Objectives obj;   // on the run's table, as the search scores
  int ops = 0;      // operators of the expression
  std::string formula;
};

struct ExhaustiveResult {
  std::vector<ExhaustiveMember> best_by_ops;  // [k]: the lowest error with <= k operators
  std::vector<ExhaustiveMember> front;        // non-dominated in (error, cost, discontinuity)
  std::vector<uint64_t> enumerated;           // [k]: distinct expressions with exactly k ops
  std::vector<uint64_t> screened;     // [k]: of those, the ones fitted (with linear scaling, one
                                      // per function up to an affine map)
  std::vector<double> level_seconds;  // [k]: seconds from the start until size k was done
  uint64_t fitted = 0;                // constant fits on every row
  int complete_ops = -1;              // every expression of <= this many operators was fitted
  // Why the sizes above complete_ops were not done: "seconds" (the budget), "expression
  // cap" (more distinct expressions of one size than the enumerator keeps) or "memory" (the
  // next size would not fit the memory bound); empty if all were.
  std::string stopped;
  double seconds = 0;
  // The certificate for the front JSON ("exhaustive"): grammar, counts, best per k.
  nlohmann::json toJson(const RunConfig& cfg, const Table& t) const;
};

// Runs the enumeration of cfg.search.exhaustive on `t` (one output). Errors name the field.
// `memory_bytes`: what the enumeration may hold (its expressions, their probe values and
// fingerprints, the screening's lists); a size that would need more stops it with "memory".
// 0: exhaustiveMemoryBudget().
Expected<ExhaustiveResult> exhaustiveSearch(const RunConfig& cfg, const Table& t,
                                            size_t memory_bytes = 0);
// Half of what this process may still allocate: the machine's available memory, and under an
// address-space or data limit (ulimit -v, ulimit -d) what is left of it.
size_t exhaustiveMemoryBudget();

}  // namespace lgp
