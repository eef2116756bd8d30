// Constant snapping: replaces fitted constants by the simplest nearby values a person would
// write (1.0195341e-08 -> 0, -6.9999 -> -7, 0.33333 -> 1/3, 0.73912 -> 0.74) when the
// error barely changes. Used by `lgp front --snap`, `lgp emit --snap` and the search's
// post-run pass, which offers the snapped twin of every front member to the archive.
//
// Rule: with e0 the program's error, each effective constant in turn (ascending slot) tries
// its candidates in order of simplicity and keeps the first one whose program has error
// <= e0 + max(tolerance * e0, abs_floor); changes accumulate, but every test is against e0, so
// the snapped program's error never exceeds that limit. A constant that already equals a
// candidate stops at it (nothing simpler passed). abs_floor is the error float32 rounding
// alone makes (float32ErrorFloor, eval/objectives.hpp): for a member that is exact up to
// rounding (error 5e-9 on the quickstart), a relative tolerance alone would keep a 1e-8
// constant that is only rounding noise.
//
// Candidates of v, in order: 0; the nearest integer; p/2; v to 1 significant digit; p/3, p/4;
// 2 digits; p/5 .. p/8; 3 digits; p/9 .. p/12; 4 digits (p the nearest numerator; fractions
// are float(p)/float(q), decimals the float nearest the rounded decimal).
#pragma once

#include <functional>
#include <vector>

#include "lgp/core/program.hpp"

namespace lgp {

// Default: the error may grow by 0.1 %, well inside the archive's 2.3 % error boxes.
inline constexpr double kSnapTolerance = 1e-3;

struct SnapOptions {
  double tolerance = kSnapTolerance;  // relative error growth allowed (>= 0)
  double abs_floor = 0;               // error growth always allowed (>= 0), in error units
};

struct SnapResult {
  Program program;
  double error_before = 0;
  double error_after = 0;
  int snapped = 0;  // constant slots changed
};

// Candidate values for v, simplest first (duplicates removed; may include v itself).
std::vector<float> snapCandidates(float v);

// Snaps the effective constants of `p` under `error` (any error function; +inf or NaN counts
// as failing). A program whose own error is not finite is returned unchanged.
SnapResult snapConstants(const Program& p, const std::function<double(const Program&)>& error,
                         const SnapOptions& o = {});

}  // namespace lgp
