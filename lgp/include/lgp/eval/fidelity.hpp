// What is exported is what was scored. The search scores programs in float32, like the
// shaders it writes. A program can fit a table through float32 rounding alone: constants that
// cancel (x + 1.8e11 - 1.8e11) quantise an input into steps, and the output scale turns the
// steps into a fit. Its exact value, its simplified formula and the shader written from it
// compute another function. Such a program is invalid, like one with a NaN output: the Scorer
// gives it the worst error (Scorer::setFidelity), the archive refuses it and no front holds it.
//
// The rule. For every output o of the program as exported (introns pruned, the output layer
// applied, the inverse target transform applied) and every row x checked,
//     |f32(x) - f64(x)| <= 2^-kFidelityBits * S_o
// where f32 is the float32 interpreter, f64 the same program (same float constants) in double
// precision with the same protected semantics, and S_o the weighted RMS of output o's target
// (1 where that is 0). Then, by the triangle inequality, the program's float32 and double rmse,
// mae and max_abs differ by at most 2^-kFidelityBits * S_o on the rows checked. A formula that
// loses no more than about 10 of float32's 24 bits to cancellation (core/cancellation.hpp flags
// more) passes; a rounding exploit is off by the height of its steps.
//
// Where it is checked. Every score the search takes (offspring, refinements) is checked on
// kFidelitySampleRows rows spread evenly over the table: cheap next to the score itself. A
// program entering the archive is checked on every row, and a front member's emitted formula
// (simplified on the table's domain) must reproduce the scored values within the same bound
// (Search::front()).
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "lgp/core/table.hpp"
#include "lgp/eval/interpreter.hpp"

namespace lgp {

struct ErrorConfig;  // eval/objectives.hpp
struct LinearScale;
enum class TargetTransform : uint8_t;

inline constexpr int kFidelityBits = 14;
inline constexpr size_t kFidelitySampleRows = 32;

// The tolerance of output o: 2^-kFidelityBits times the weighted RMS of its target (1 where it
// is 0).
std::vector<double> fidelityTolerances(const Table& t);

// Checks bound programs on a fixed set of rows in both precisions. Not thread-safe: one per
// thread (it owns an interpreter and the double scratch).
class FidelityCheck {
 public:
  // `rows` rows of `t` spread evenly (row i * n / rows), or every row when rows is 0 or at
  // least t.rows(). `cfg` gives the transforms and the output layer's gene count.
  FidelityCheck(const Table& t, const ErrorConfig& cfg, size_t rows);
  ~FidelityCheck();
  FidelityCheck(const FidelityCheck&) = delete;
  FidelityCheck& operator=(const FidelityCheck&) = delete;

  // Whether `bp` passes the rule with the output layer `scales` (one per program output, as
  // Scorer::scales(); empty = identity).
  bool passes(const BoundProgram& bp, const std::vector<LinearScale>& scales);
  // The largest |f32 - f64| / tolerance over the rows and outputs of the last passes() call
  // (+inf where a value was not finite): passes() is this <= 1.
  double lastRatio() const { return last_ratio_; }
  size_t rows() const { return rows_; }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  size_t rows_ = 0;
  double last_ratio_ = 0;
};

// The largest |a(x) - b(x)| / tolerance[o] over the rows of `ds` and the outputs of two
// programs with the same outputs, both through the float32 interpreter and the inverse
// transforms (+inf where exactly one of the two values is not finite). A front member's
// emitted formula must reproduce the scored program: deviation <= 1 with fidelityTolerances.
double valueDeviation(const Program& a, const Program& b, const Dataset& ds,
                      const std::vector<TargetTransform>& transforms,
                      const std::vector<double>& tolerance);

}  // namespace lgp
