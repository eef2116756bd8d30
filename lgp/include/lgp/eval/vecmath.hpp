// Vectorisable float32 transcendentals. Each function is straight-line code (no branches, no
// table look-ups, no libm), so a loop over a row block that calls it compiles to SIMD.
//
// Accuracy against double-precision libm, measured over dense sweeps in
// tests/core/vecmath_test.cpp (the test enforces these bounds):
//   exp2f  x in [-126, 126]                     max rel err <= 2 ulp (2.4e-7)
//   log2f  x in [FLT_MIN, FLT_MAX], normal       max abs err <= 2e-7 where |log2 x| < 1,
//                                                else max rel err <= 2 ulp
//   sinf/cosf |x| <= 8192                         max abs err <= 2.5e-7 (8 * 2^-25 scale)
//   sinf/cosf |x| > 8192                          finite and within [-1, 1]; the argument
//                                                reduction loses phase, as on GPUs
// Inputs outside the stated domains are clamped by the protected operators (ops.hpp) before
// they get here.
#pragma once

#include <bit>
#include <cstdint>

namespace lgp::vm {

#if defined(__FMA__) || defined(__FMA4__)
inline float fmadd(float a, float b, float c) {
  return __builtin_fmaf(a, b, c);
}
#else
inline float fmadd(float a, float b, float c) {
  return a * b + c;
}
#endif

// Round to nearest integer for |x| < 2^22 without SSE4.1 (adding and subtracting 1.5*2^23).
inline float roundNearest(float x) {
  constexpr float kMagic = 12582912.0f;
  return (x + kMagic) - kMagic;
}

// 2^x for x in [-126, 126].
inline float exp2f(float x) {
  const float n = roundNearest(x);
  const float f = x - n;  // [-0.5, 0.5]
  // Taylor series of e^(f ln 2), degree 7: truncation < 6e-9 on [-0.5, 0.5].
  float p = 1.5252733804059840e-5f;
  p = fmadd(p, f, 1.5403530393381609e-4f);
  p = fmadd(p, f, 1.3333558146428443e-3f);
  p = fmadd(p, f, 9.6181291076284772e-3f);
  p = fmadd(p, f, 5.5504108664821580e-2f);
  p = fmadd(p, f, 2.4022650695910071e-1f);
  p = fmadd(p, f, 6.9314718055994531e-1f);
  p = fmadd(p, f, 1.0f);
  const int32_t e = (static_cast<int32_t>(n) + 127) << 23;
  return p * std::bit_cast<float>(e);
}

// log2(x) for normal positive x; +inf maps to +inf.
inline float log2f(float x) {
  const int32_t i = std::bit_cast<int32_t>(x);
  int32_t e = ((i >> 23) & 0xff) - 127;
  float m = std::bit_cast<float>((i & 0x007fffff) | 0x3f800000);  // [1, 2)
  const bool hi = m > 1.41421356f;
  m = hi ? m * 0.5f : m;  // [sqrt(1/2), sqrt(2))
  e = hi ? e + 1 : e;
  const float t = (m - 1.0f) / (m + 1.0f);  // |t| <= 0.1716
  const float t2 = t * t;
  // 2/ln2 * atanh(t) series to t^11: truncation < 2e-10.
  float p = 0.26230819f;          // 2/(11 ln2)
  p = fmadd(p, t2, 0.32059890f);  // 2/(9 ln2)
  p = fmadd(p, t2, 0.41219858f);  // 2/(7 ln2)
  p = fmadd(p, t2, 0.57707802f);  // 2/(5 ln2)
  p = fmadd(p, t2, 0.96179669f);  // 2/(3 ln2)
  p = fmadd(p, t2, 2.88539008f);  // 2/ln2
  const float r = fmadd(p, t, static_cast<float>(e));
  return x == std::bit_cast<float>(0x7f800000) ? x : r;
}

namespace detail {
// sin(r) on [-pi/4, pi/4] (Taylor to r^11) and cos(r) (to r^12); both < 1e-9 truncation.
inline float sinPoly(float r) {
  const float r2 = r * r;
  float p = -2.5052108e-8f;
  p = fmadd(p, r2, 2.7557319e-6f);
  p = fmadd(p, r2, -1.9841270e-4f);
  p = fmadd(p, r2, 8.3333333e-3f);
  p = fmadd(p, r2, -1.6666667e-1f);
  return fmadd(p * r2, r, r);
}
inline float cosPoly(float r) {
  const float r2 = r * r;
  float p = 2.0876757e-9f;
  p = fmadd(p, r2, -2.7557319e-7f);
  p = fmadd(p, r2, 2.4801587e-5f);
  p = fmadd(p, r2, -1.3888889e-3f);
  p = fmadd(p, r2, 4.1666667e-2f);
  p = fmadd(p, r2, -0.5f);
  return fmadd(p, r2, 1.0f);
}
// Shared reduction: x = j*pi/2 + r, quadrant = j + shift.
inline float sinCosQuadrant(float x, int32_t shift) {
  // Clamp so the magic-number rounding stays exact; beyond this the phase is meaningless
  // anyway (documented above), but results stay finite and bounded.
  constexpr float kLimit = 4.0e6f;
  const float xc = x > kLimit ? kLimit : (x < -kLimit ? -kLimit : x);
  const float j = roundNearest(xc * 0.63661977236758134f);
  // Cody-Waite three-part pi/2.
  float r = fmadd(j, -1.5703125f, xc);
  r = fmadd(j, -4.837512969970703125e-4f, r);
  r = fmadd(j, -7.54978995489188216e-8f, r);
  const int32_t q = static_cast<int32_t>(j) + shift;
  const float s = sinPoly(r);
  const float c = cosPoly(r);
  float v = (q & 1) ? c : s;
  v = (q & 2) ? -v : v;
  v = v > 1.0f ? 1.0f : (v < -1.0f ? -1.0f : v);
  // NaN and +-inf inputs give NaN, as libm does.
  return (x - x) == 0.0f ? v : (x - x);
}
}  // namespace detail

inline float sinf(float x) {
  return detail::sinCosQuadrant(x, 0);
}
inline float cosf(float x) {
  return detail::sinCosQuadrant(x, 1);
}

}  // namespace lgp::vm
