// How many float32 bits a formula's result loses to cancellation: the flag on front members
// whose constants cancel (e.g. mad(x, 0.877, -17244.156) fed by mad(.., .., 19659.578)), which
// are fragile in float32 on a GPU with or without FMA contraction.
//
// Estimate (first-order rounding analysis, Higham, "Accuracy and Stability of Numerical
// Algorithms", 2002, ch. 3): on each sampled row the DAG is evaluated in double and
// differentiated in reverse mode. Rounding every node's value v_n (inputs and constants
// included) to float32 moves the output y by at most u * E with u = 2^-24 and
//   E = sum over nodes |v_n * dy/dv_n|  (+ |a*b * dy/dmad| for the product inside each mad,
//                                        + |(b-a)*t * dy/dlerp| for the one inside lerp),
// the condition number of y with respect to its constants, inputs and intermediate results,
// times |y|. Large terms that cancel make E much larger than |y|. With a target transform,
// E is carried through the inverse transform g (E_result = |g'(y)| E). Per output,
//   bits lost = log2( max over rows  E_result / max(|result|, RMS of |result| over the rows) )
// clamped at 0: the bits of the result, relative to its own magnitude, that rounding may
// corrupt; rows where the result is below its RMS are measured against the RMS, so a result
// that merely crosses zero on the domain does not count. A member's value is the largest over
// its outputs. Typical clean formulas lose 0-3 bits; flagged members lose more than
// kCancellationFlagBits (float32 keeps 24).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "lgp/core/expr.hpp"
#include "lgp/core/table.hpp"

namespace lgp {

enum class TargetTransform : uint8_t;  // eval/objectives.hpp

// Default threshold: a member that loses more than 10 of float32's 24 bits (its rounding
// noise exceeds 2^-14 ~ 6e-5 of its value, the size of the errors fronts reach) is flagged.
inline constexpr double kCancellationFlagBits = 10.0;

struct CancellationOptions {
  double flag_bits = kCancellationFlagBits;  // flagged when bits_lost > flag_bits
  size_t max_rows = 4096;                    // rows sampled evenly from the table
};

struct Cancellation {
  double bits_lost = 0;            // largest over outputs
  bool flagged = false;            // bits_lost > flag_bits
  std::vector<double> per_output;  // bits lost per output
};

// The estimate above for DAG `d` (normally formulaDag of the program) on the table's rows.
// `transforms`: per output (empty = none).
Cancellation cancellation(const Dag& d, const Table& t,
                          const std::vector<TargetTransform>& transforms,
                          const CancellationOptions& o = {});

}  // namespace lgp
