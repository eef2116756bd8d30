// The protected semantics of every operator, written once as a template over the scalar type.
// The float32 SIMD kernels instantiate it with T = float (vectorised math from vecmath.hpp);
// the reference evaluator with T = double (libm). Both therefore apply the same guards,
// clamps and NaN conventions; they differ only by rounding and by the documented
// approximation error of the float transcendentals. See ops.hpp for the table.
#pragma once

#include <cmath>

#include "lgp/core/ops.hpp"
#include "lgp/eval/vecmath.hpp"

namespace lgp {

template <class T>
struct Math;

template <>
struct Math<float> {
  static float exp2(float x) { return vm::exp2f(x); }
  static float log2(float x) { return vm::log2f(x); }
  static float sin(float x) { return vm::sinf(x); }
  static float cos(float x) { return vm::cosf(x); }
  static float sqrt(float x) { return std::sqrt(x); }
};

template <>
struct Math<double> {
  static double exp2(double x) { return std::exp2(x); }
  static double log2(double x) { return std::log2(x); }
  static double sin(double x) { return std::sin(x); }
  static double cos(double x) { return std::cos(x); }
  static double sqrt(double x) { return std::sqrt(x); }
};

namespace sem {

template <class T>
inline T guard(T b) {
  const T g = static_cast<T>(kDivGuard);
  return std::fabs(b) < g ? std::copysign(g, b) : b;
}
template <class T>
inline T floorPos(T a) {
  const T m = static_cast<T>(kMinPos);
  return a > m ? a : m;
}
template <class T>
inline T clampExp(T a) {
  const T c = static_cast<T>(kExpClamp);
  return a > c ? c : (a < -c ? -c : a);  // NaN passes through
}
template <class T>
inline T plog2(T a) {
  return Math<T>::log2(floorPos(a));
}
template <class T>
inline T pexp2(T a) {
  return Math<T>::exp2(clampExp(a));
}

inline constexpr double kLog2E = 1.4426950408889634;
inline constexpr double kLn2 = 0.6931471805599453;

// Result of operator OP on operands a..d (unused operands are ignored).
template <Op OP, class T>
inline T apply(T a, [[maybe_unused]] T b, [[maybe_unused]] T c, [[maybe_unused]] T d) {
  if constexpr (OP == Op::Add)
    return a + b;
  else if constexpr (OP == Op::Sub)
    return a - b;
  else if constexpr (OP == Op::Mul)
    return a * b;
  else if constexpr (OP == Op::Div)
    return a / guard(b);
  else if constexpr (OP == Op::Mad)
    return a * b + c;
  else if constexpr (OP == Op::Neg)
    return -a;
  else if constexpr (OP == Op::Rcp)
    return T(1) / guard(a);
  else if constexpr (OP == Op::Sqrt)
    return Math<T>::sqrt(a > T(0) ? a : T(0));
  else if constexpr (OP == Op::Rsqrt)
    return T(1) / Math<T>::sqrt(floorPos(a));
  else if constexpr (OP == Op::Square)
    return a * a;
  else if constexpr (OP == Op::Exp2)
    return pexp2(a);
  else if constexpr (OP == Op::Log2)
    return plog2(a);
  else if constexpr (OP == Op::Exp)
    return pexp2(a * static_cast<T>(kLog2E));
  else if constexpr (OP == Op::Log)
    return plog2(a) * static_cast<T>(kLn2);
  else if constexpr (OP == Op::Pow)
    return pexp2(b * plog2(a));
  else if constexpr (OP == Op::Sin)
    return Math<T>::sin(a);
  else if constexpr (OP == Op::Cos)
    return Math<T>::cos(a);
  else if constexpr (OP == Op::Min)
    return a < b ? a : b;
  else if constexpr (OP == Op::Max)
    return a > b ? a : b;
  else if constexpr (OP == Op::Abs)
    return std::fabs(a);
  else if constexpr (OP == Op::Saturate)
    return a > T(0) ? (a < T(1) ? a : T(1)) : T(0);
  else if constexpr (OP == Op::Lerp)
    return a + (b - a) * c;
  else if constexpr (OP == Op::Select)
    return a > b ? c : d;
  else
    static_assert(OP == Op::Add, "operator without semantics");
}

// Runtime dispatch for scalar evaluation (reference evaluator, parser constant folding).
template <class T>
inline T applyDynamic(Op op, T a, T b, T c, T d) {
  switch (op) {
#define LGP_X_CASE(E, ...) \
  case Op::E:              \
    return apply<Op::E, T>(a, b, c, d);
    LGP_OPS(LGP_X_CASE)
#undef LGP_X_CASE
  }
  return T(0);
}

}  // namespace sem
}  // namespace lgp
