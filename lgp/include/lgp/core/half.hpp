// IEEE binary16 emulation for `--precision half`: the error of an emitted half function is
// re-measured by evaluating its DAG with every operand, constant and result rounded to half
// (round to nearest even), and with half-sized protection constants, since the float32 ones
// are not representable: guard and floor 2^-14 (smallest normal half), exp clamp +-15
// (2^15 < 65504). The emitted half helpers use exactly these constants.
#pragma once

#include "lgp/core/ops.hpp"

namespace lgp {

inline constexpr float kHalfDivGuard = 6.103515625e-05f;  // 2^-14
inline constexpr float kHalfMinPos = 6.103515625e-05f;    // 2^-14
inline constexpr float kHalfExpClamp = 15.0f;
inline constexpr float kHalfMax = 65504.0f;
inline constexpr float kHalfMinSubnormal = 5.9604644775390625e-08f;  // 2^-24

// Nearest binary16 value (ties to even), as a float; overflow gives +-inf, NaN stays NaN.
float roundToHalf(float x);

// Operator `op` with the half-precision protection constants, computed in float on
// half-rounded operands and rounded to half.
float applyHalf(Op op, float a, float b, float c, float d);

}  // namespace lgp
