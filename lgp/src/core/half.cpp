// binary16 rounding and the half-precision protected semantics (see half.hpp): the
// operators' own semantics (eval/semantics.hpp) over a scalar that rounds to half.
#include "lgp/core/half.hpp"

#include <bit>
#include <cmath>
#include <cstdint>

#include "lgp/eval/semantics.hpp"

namespace lgp {

float roundToHalf(float x) {
  if (!std::isfinite(x)) return x;
  const float ax = std::fabs(x);
  if (ax >= 65520.0f) return std::copysign(INFINITY, x);  // rounds past the largest half
  // Spacing of halves around |x|: 2^(e-10) for normals, 2^-24 for subnormals. Scaling by a
  // power of two is exact, and nearbyint rounds ties to even.
  int e = 0;
  std::frexp(ax, &e);     // ax = m * 2^e, m in [0.5, 1)
  const int exp = e - 1;  // ax in [2^exp, 2^(exp+1))
  const int q = exp < -14 ? -24 : exp - 10;
  const float r = std::ldexp(std::nearbyint(std::ldexp(ax, -q)), q);
  return std::copysign(r, x);
}

namespace {
// A binary16 scalar for the operator semantics (eval/semantics.hpp): every arithmetic step
// and every function's result rounded to half, as a half shader computes. It converts to and
// from float, so that an operator computed by a float function (std::atan2) has half
// semantics with no entry here: the function runs in float on the half operands and its
// result is rounded once.
struct Half {
  float v = 0;
  Half() = default;
  Half(double x) : v(roundToHalf(static_cast<float>(x))) {}  // NOLINT: implicit by design
  operator float() const { return v; }                       // NOLINT: exact
  static Half from(float x) {                                // x is a half already
    Half h;
    h.v = x;
    return h;
  }
};
Half round(float x) {
  return Half::from(roundToHalf(x));
}
Half operator+(Half a, Half b) {
  return round(a.v + b.v);
}
Half operator-(Half a, Half b) {
  return round(a.v - b.v);
}
Half operator*(Half a, Half b) {
  return round(a.v * b.v);
}
Half operator/(Half a, Half b) {
  return round(a.v / b.v);
}
Half operator-(Half a) {
  return Half::from(-a.v);
}
bool operator<(Half a, Half b) {
  return a.v < b.v;
}
bool operator>(Half a, Half b) {
  return a.v > b.v;
}
Half fabs(Half a) {
  return Half::from(std::fabs(a.v));
}
Half copysign(Half a, Half b) {
  return Half::from(std::copysign(a.v, b.v));
}
}  // namespace

template <>
struct Math<Half> {
  static Half exp2(Half x) { return round(std::exp2(x.v)); }
  static Half log2(Half x) { return round(std::log2(x.v)); }
  static Half sin(Half x) { return round(std::sin(x.v)); }
  static Half cos(Half x) { return round(std::cos(x.v)); }
  static Half sqrt(Half x) { return round(std::sqrt(x.v)); }
  static Half rsqrt(Half x) { return round(1.0f / std::sqrt(x.v)); }  // one rounding, as a GPU
};

template <>
struct Guards<Half> {
  static constexpr double div = kHalfDivGuard;
  static constexpr double min_pos = kHalfMinPos;
  static constexpr double exp_clamp = kHalfExpClamp;
};

float applyHalf(Op op, float a, float b, float c, float d) {
  const Half x[4] = {a, b, c, d};
  switch (op) {
#define LGP_X_CASE(E, ...) \
  case Op::E:              \
    return sem::apply<Op::E, Half>(x[0], x[1], x[2], x[3]).v;
    LGP_OPS(LGP_X_CASE)
#undef LGP_X_CASE
  }
  return 0.0f;
}

}  // namespace lgp
