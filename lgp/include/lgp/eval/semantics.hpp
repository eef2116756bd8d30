// The protected semantics of every operator, written once as a template over the scalar type.
// The float32 SIMD kernels instantiate it with T = float (vectorised math from vecmath.hpp);
// the reference evaluator with T = double (libm). Both therefore apply the same guards,
// clamps and NaN conventions; they differ only by rounding and by the documented
// approximation error of the float transcendentals. See ops.hpp for the table. The binary16
// semantics (core/half.cpp) instantiate it too, with a scalar that rounds every step to half
// and the half guards (Guards below).
#pragma once

#include <array>
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
  static float rsqrt(float x) { return 1.0f / std::sqrt(x); }
};

template <>
struct Math<double> {
  static double exp2(double x) { return std::exp2(x); }
  static double log2(double x) { return std::log2(x); }
  static double sin(double x) { return std::sin(x); }
  static double cos(double x) { return std::cos(x); }
  static double sqrt(double x) { return std::sqrt(x); }
  static double rsqrt(double x) { return 1.0 / std::sqrt(x); }
};

// The protected branches' constants per scalar type (binary16 has its own, half.hpp).
template <class T>
struct Guards {
  static constexpr double div = kDivGuard;
  static constexpr double min_pos = kMinPos;
  static constexpr double exp_clamp = kExpClamp;
};

namespace sem {

template <class T>
inline T guard(T b) {
  using std::copysign, std::fabs;  // and the binary16 scalar's own
  const T g = static_cast<T>(Guards<T>::div);
  return fabs(b) < g ? copysign(g, b) : b;
}
template <class T>
inline T floorPos(T a) {
  const T m = static_cast<T>(Guards<T>::min_pos);
  return a > m ? a : m;
}
template <class T>
inline T clampExp(T a) {
  const T c = static_cast<T>(Guards<T>::exp_clamp);
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
    return Math<T>::rsqrt(floorPos(a));
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
  else if constexpr (OP == Op::Abs) {
    using std::fabs;
    return fabs(a);
  } else if constexpr (OP == Op::Saturate)
    return a > T(0) ? (a < T(1) ? a : T(1)) : T(0);
  else if constexpr (OP == Op::Lerp)
    return a + (b - a) * c;
  else if constexpr (OP == Op::Select)
    return a > b ? c : d;
  else
    static_assert(OP == Op::Add, "operator without semantics");
}

// The partial derivatives of operator OP at operands (a, b, c, d) whose value is
// v = apply<OP, T>(a, b, c, d), in the protected semantics: d v / d operand j is p[j] / den
// where on[j], and 0 where not (a branch that does not take the operand: the caller adds
// nothing for it, so an infinite derivative there cannot make a NaN). A guard, floor or clamp
// that holds the result constant gives p[j] = 0. den is 1 but for div (v = a / g(b): the
// Jacobian divides the sum of the terms by g once, as the kernel always has). inner: the
// magnitude of a value the operator rounds before its result (mad's product, lerp's
// (b - a) c), which the cancellation estimate adds. One definition for the float32 Jacobian
// (eval/jacobian.cpp) and the double cancellation estimate (core/cancellation.cpp).
template <class T>
struct Partials {
  std::array<T, kMaxArity> p{};
  std::array<bool, kMaxArity> on{};
  T den = T(1);
  T inner = T(0);
};

template <Op OP, class T>
inline Partials<T> partials(T v, T a, [[maybe_unused]] T b, [[maybe_unused]] T c,
                            [[maybe_unused]] T d) {
  using P = Partials<T>;
  constexpr T kGuard = static_cast<T>(kDivGuard), kClamp = static_cast<T>(kExpClamp);
  constexpr T kFloor = static_cast<T>(kMinPos);
  constexpr T kLn2T = static_cast<T>(kLn2), kLog2ET = static_cast<T>(kLog2E);
  constexpr std::array<bool, kMaxArity> a1{true, false, false, false}, a2{true, true, false, false},
      a3{true, true, true, false};
  (void)v;
  if constexpr (OP == Op::Add)
    return P{{T(1), T(1)}, a2};
  else if constexpr (OP == Op::Sub)
    return P{{T(1), T(-1)}, a2};
  else if constexpr (OP == Op::Mul)
    return P{{b, a}, a2};
  else if constexpr (OP == Op::Div)  // v = a / g(b): dv = (da - v db) / g(b), no db at the guard
    return P{{T(1), std::fabs(b) < kGuard ? T(0) : -v}, a2, guard(b)};
  else if constexpr (OP == Op::Mad)
    return P{{b, a, T(1)}, a3, T(1), a * b};
  else if constexpr (OP == Op::Neg)
    return P{{T(-1)}, a1};
  else if constexpr (OP == Op::Rcp)
    return P{{std::fabs(a) < kGuard ? T(0) : -v * v}, a1};
  else if constexpr (OP == Op::Sqrt)
    return P{{a > T(0) ? T(0.5) / v : T(0)}, a1};
  else if constexpr (OP == Op::Rsqrt)
    return P{{a > kFloor ? T(-0.5) * v / a : T(0)}, a1};
  else if constexpr (OP == Op::Square)
    return P{{a + a}, a1};
  else if constexpr (OP == Op::Exp2)
    return P{{std::fabs(a) < kClamp ? v * kLn2T : T(0)}, a1};
  else if constexpr (OP == Op::Log2)
    return P{{a > kFloor ? kLog2ET / a : T(0)}, a1};
  else if constexpr (OP == Op::Exp)  // the clamped exponent, as in apply
    return P{{std::fabs(a * kLog2ET) < kClamp ? v : T(0)}, a1};
  else if constexpr (OP == Op::Log)
    return P{{a > kFloor ? T(1) / a : T(0)}, a1};
  else if constexpr (OP == Op::Pow) {
    // v = 2^(b log2 a'), a' = max(a, kMinPos): dv/da = v b / a, dv/db = v ln2 log2 a'.
    const T l = plog2(a);
    const bool inside = std::fabs(b * l) < kClamp;
    return P{{inside && a > kFloor ? v * b / a : T(0), inside ? v * kLn2T * l : T(0)}, a2};
  } else if constexpr (OP == Op::Sin)
    return P{{Math<T>::cos(a)}, a1};
  else if constexpr (OP == Op::Cos)
    return P{{-Math<T>::sin(a)}, a1};
  else if constexpr (OP == Op::Min)
    return P{{T(1), T(1)}, {a < b, !(a < b), false, false}};
  else if constexpr (OP == Op::Max)
    return P{{T(1), T(1)}, {a > b, !(a > b), false, false}};
  else if constexpr (OP == Op::Abs)
    return P{{a < T(0) ? T(-1) : T(1)}, a1};
  else if constexpr (OP == Op::Saturate)
    return P{{a > T(0) && a < T(1) ? T(1) : T(0)}, a1};
  else if constexpr (OP == Op::Lerp)  // v = a + (b - a) c
    return P{{T(1) - c, c, b - a}, a3, T(1), (b - a) * c};
  else if constexpr (OP == Op::Select)  // a > b ? c : d: no derivative through the comparison
    return P{{T(0), T(0), T(1), T(1)}, {false, false, a > b, !(a > b)}};
  else
    static_assert(OP == Op::Add, "operator without partial derivatives");
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

template <class T>
inline Partials<T> partialsDynamic(Op op, T v, T a, T b, T c, T d) {
  switch (op) {
#define LGP_X_CASE(E, ...) \
  case Op::E:              \
    return partials<Op::E, T>(v, a, b, c, d);
    LGP_OPS(LGP_X_CASE)
#undef LGP_X_CASE
  }
  return Partials<T>{};
}

}  // namespace sem
}  // namespace lgp
