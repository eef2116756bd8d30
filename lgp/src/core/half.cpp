// binary16 rounding and the half-precision protected semantics (see half.hpp).
#include "lgp/core/half.hpp"

#include <bit>
#include <cmath>
#include <cstdint>

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
float guardH(float b) {
  return std::fabs(b) < kHalfDivGuard ? std::copysign(kHalfDivGuard, b) : b;
}
float floorH(float a) {
  return a > kHalfMinPos ? a : kHalfMinPos;
}
float clampH(float a) {
  return a > kHalfExpClamp ? kHalfExpClamp : (a < -kHalfExpClamp ? -kHalfExpClamp : a);
}
float h(float x) {
  return roundToHalf(x);
}
}  // namespace

float applyHalf(Op op, float a, float b, float c, float d) {
  a = h(a), b = h(b), c = h(c), d = h(d);
  constexpr float kLog2E = 1.44269504f, kLn2 = 0.693147181f;
  switch (op) {
    case Op::Add:
      return h(a + b);
    case Op::Sub:
      return h(a - b);
    case Op::Mul:
      return h(a * b);
    case Op::Div:
      return h(a / guardH(b));
    case Op::Mad:
      return h(h(a * b) + c);
    case Op::Neg:
      return -a;
    case Op::Rcp:
      return h(1.0f / guardH(a));
    case Op::Sqrt:
      return h(std::sqrt(a > 0.0f ? a : 0.0f));
    case Op::Rsqrt:
      return h(1.0f / std::sqrt(floorH(a)));
    case Op::Square:
      return h(a * a);
    case Op::Exp2:
      return h(std::exp2(clampH(a)));
    case Op::Log2:
      return h(std::log2(floorH(a)));
    case Op::Exp:
      return h(std::exp2(clampH(h(a * h(kLog2E)))));
    case Op::Log:
      return h(h(std::log2(floorH(a))) * h(kLn2));
    case Op::Pow:
      return h(std::exp2(clampH(h(b * h(std::log2(floorH(a)))))));
    case Op::Sin:
      return h(std::sin(a));
    case Op::Cos:
      return h(std::cos(a));
    case Op::Min:
      return a < b ? a : b;
    case Op::Max:
      return a > b ? a : b;
    case Op::Abs:
      return std::fabs(a);
    case Op::Saturate:
      return a > 0.0f ? (a < 1.0f ? a : 1.0f) : 0.0f;
    case Op::Lerp:
      return h(a + h(h(b - a) * c));
    case Op::Select:
      return a > b ? c : d;
  }
  return 0.0f;
}

}  // namespace lgp
