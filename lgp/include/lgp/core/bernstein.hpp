// Proven bounds of a polynomial over a box, from its Bernstein coefficients: on the box, the
// polynomial is a convex combination of them (the Bernstein basis is nonnegative and sums to
// one), so its values lie between the smallest and the largest. Subdividing the box tightens
// the bound. The structured fits use it to prove that a rational's denominator has no zero
// anywhere on the domain, not only at sampled points.
#pragma once

#include <cstddef>
#include <map>
#include <vector>

#include "lgp/core/interval.hpp"

namespace lgp {

// Coefficients by exponent vector (one exponent per variable).
using Polynomial = std::map<std::vector<int>, double>;

// The tensor of coefficients has prod (degree in x_i + 1) entries: past this many (many
// variables) no bound is computed.
inline constexpr size_t kMaxBernsteinCoefficients = size_t{1} << 22;

// [min, max] of the polynomial's Bernstein coefficients on `box` (one interval per variable,
// finite, lo <= hi): every value of the polynomial on the box lies in it. A polynomial
// without terms gives [0, 0]; one past kMaxBernsteinCoefficients the whole line, NaN possible
// (no bound).
Interval bernsteinRange(const Polynomial& p, const std::vector<Interval>& box);

}  // namespace lgp
