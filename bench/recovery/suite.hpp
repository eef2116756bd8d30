// The recovery suite: public symbolic-regression problems with known closed forms, defined
// once for every engine (README.md lists them with their sources). A problem is its inputs
// with their sampling ranges, the formula in double precision, and the operator families an
// engine may use; suite.cpp holds the table and the per-engine operator spelling.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "lgp/core/ops.hpp"
#include "lgp/core/table.hpp"

namespace recovery {

// Operator families, mapped to each engine's own operators (lgpOps / operonSymbols).
enum class Fam : uint8_t { Arith, Sin, Cos, Exp, Log, Sqrt };

struct Input {
  const char* name;
  double lo, hi;  // sampled uniformly in [lo, hi]
};

struct Problem {
  const char* name;     // command-line key, e.g. "nguyen7"
  const char* group;    // "nguyen", "feynman" or "pbr"
  const char* title;    // e.g. "Nguyen-7"
  const char* formula;  // readable ground truth
  const char* source;   // citation key (see citation())
  std::vector<Input> inputs;
  double (*f)(const double* x);  // x[i] is inputs[i]
  std::vector<Fam> ops;
};

const std::vector<Problem>& suite();
const char* citation(const std::string& source_key);

// Problems named in a comma list of names or group names ("all" = everything). Unknown names
// are returned in `unknown`.
std::vector<const Problem*> select(const std::string& list, std::vector<std::string>& unknown);

// Engine operator sets for a problem's families. Both always include the four arithmetic
// operators; each engine also gets the operators that are compositions of them in its own
// encoding (see README.md, "Operators").
std::vector<lgp::Op> lgpOps(const Problem& p);
std::vector<std::string> operonSymbols(const Problem& p);

// `rows` points drawn uniformly from the problem's ranges; the target column is "target" (Nguyen
// problems have an input named y). The
// points depend only on (problem name, seed, stream): stream 0 is the training set, 1 the
// held-out set, so they are disjoint draws from one distribution.
lgp::Table sample(const Problem& p, uint64_t seed, int stream, int rows);

}  // namespace recovery
