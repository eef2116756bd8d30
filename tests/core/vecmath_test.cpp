// The vectorised transcendentals meet the bounds documented in vecmath.hpp.
#include <gtest/gtest.h>

#include <cfloat>
#include <cmath>

#include "lgp/eval/vecmath.hpp"

namespace lgp {
namespace {

double ulpsOf(float f, double ref) {
  const double ulp = std::ldexp(1.0, std::ilogb(static_cast<float>(ref)) - 23);
  return std::fabs(static_cast<double>(f) - ref) / ulp;
}

TEST(VecMath, Exp2WithinTwoUlp) {
  double worst = 0;
  for (double x = -126.0; x <= 126.0; x += 0.000731) {
    const float xf = static_cast<float>(x);
    worst = std::max(worst, ulpsOf(vm::exp2f(xf), std::exp2(static_cast<double>(xf))));
  }
  EXPECT_LE(worst, 2.0);
  EXPECT_EQ(vm::exp2f(0.0f), 1.0f);
  EXPECT_EQ(vm::exp2f(10.0f), 1024.0f);
}

TEST(VecMath, Log2AbsoluteAndRelativeBounds) {
  double worst_abs = 0, worst_ulp = 0;
  for (float x = FLT_MIN; x < 3e38f; x *= 1.0001931f) {
    const double ref = std::log2(static_cast<double>(x));
    const double err = std::fabs(vm::log2f(x) - ref);
    if (std::fabs(ref) < 1.0)
      worst_abs = std::max(worst_abs, err);
    else
      worst_ulp = std::max(worst_ulp, ulpsOf(vm::log2f(x), ref));
  }
  for (float x = 0.5f; x < 2.0f; x += 1.0f / 65536) {
    worst_abs = std::max(worst_abs, std::fabs(vm::log2f(x) - std::log2(static_cast<double>(x))));
  }
  EXPECT_LE(worst_abs, 2e-7);
  EXPECT_LE(worst_ulp, 2.0);
  EXPECT_EQ(vm::log2f(1.0f), 0.0f);
  EXPECT_EQ(vm::log2f(8.0f), 3.0f);
  EXPECT_TRUE(std::isinf(vm::log2f(INFINITY)));
}

TEST(VecMath, SinCosAbsoluteBound) {
  double worst = 0;
  for (double x = -8192.0; x <= 8192.0; x += 0.00377) {
    const float xf = static_cast<float>(x);
    worst = std::max(worst, std::fabs(vm::sinf(xf) - std::sin(static_cast<double>(xf))));
    worst = std::max(worst, std::fabs(vm::cosf(xf) - std::cos(static_cast<double>(xf))));
  }
  EXPECT_LE(worst, 2.5e-7);
}

TEST(VecMath, SinCosStayBoundedForHugeAndNaNForNonFinite) {
  for (float x : {1e5f, -3e7f, 1e20f, -3.4e38f, 3.4e38f}) {
    EXPECT_TRUE(std::isfinite(vm::sinf(x)));
    EXPECT_LE(std::fabs(vm::sinf(x)), 1.0f);
    EXPECT_LE(std::fabs(vm::cosf(x)), 1.0f);
  }
  EXPECT_TRUE(std::isnan(vm::sinf(NAN)));
  EXPECT_TRUE(std::isnan(vm::cosf(INFINITY)));
}

}  // namespace
}  // namespace lgp
