// Interval analysis over the operator table: the range of every value a program computes
// when each input stays inside the table's domain (its per-column min and max).
//
// Real-number interval arithmetic, widened after every operation by a relative 2^-20 (and an
// absolute 2^-126) so that float32 rounding and the interpreter's transcendental error stay
// inside: every value the float32 interpreter (or the double reference) computes on a row of
// the table lies in its node's interval. Inputs without a domain are the whole line.
//
// Used by the discontinuity objective (a piecewise operator whose branch never switches on the
// domain counts nothing), by the simplifier (such an operator is removed; expr.hpp) and by the
// emitters' --fast (a protected branch proven unreachable is emitted raw).
#pragma once

#include <cmath>
#include <limits>
#include <vector>

#include "lgp/core/ops.hpp"

namespace lgp {

struct Program;
struct Table;

// Interval [lo, hi] of a value over the input domain, plus whether it may be NaN.
struct Interval {
  double lo = -std::numeric_limits<double>::infinity();
  double hi = std::numeric_limits<double>::infinity();
  bool nan = true;  // the value may be NaN (only the whole-line interval of an unknown input
                    // or an operation on non-finite operands)
  bool finite() const { return std::isfinite(lo) && std::isfinite(hi); }
  // Zero is outside [lo, hi]: the value is never +0 nor -0.
  bool excludesZero() const { return !nan && (lo > 0 || hi < 0); }
};

// The table's domain: per input column [min, max] (NaN-free; an empty table gives the whole
// line). A column holding -0 whose minimum is zero gets lo = -0, so that the simplifier knows a
// zero input may carry a sign.
std::vector<Interval> tableDomain(const Table& t);

// An input's interval as the interpreter reads it: the bounds rounded outward to float.
Interval inputInterval(const Interval& domain);

// Interval of op(a, b, c, d) (only the first arity(op) operands are read), widened for float
// rounding.
Interval opInterval(Op op, const Interval* args);

// True when the branch of piecewise operator `op` may switch for operands in `args` (abs:
// the argument may change sign; saturate: it may cross 0 or 1, or be NaN; min/max: neither
// operand dominates; select: the comparison may go both ways). False for operators that are
// not piecewise.
bool branchMaySwitch(Op op, const Interval* args);

// True when, for every value in the intervals of its operands, `op` never takes a protected
// branch (div/rcp guard, sqrt/rsqrt/log/pow floor, exp clamp, saturate's NaN; min/max need
// NaN-free operands for the raw C++ std::min/max): the raw operator then computes exactly the
// protected one.
bool provenUnguarded(Op op, const Interval* args);

// Interval of every opcode of `p` (indexed by opcode; only `effective` ones, ascending, are
// computed), given one interval per input. `out` is resized and reused.
void programIntervals(const Program& p, const std::vector<Interval>& domain,
                      const std::vector<int>& effective, std::vector<Interval>& out);

}  // namespace lgp
