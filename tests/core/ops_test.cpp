#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "lgp/core/ops.hpp"
#include "lgp/eval/cost_model.hpp"

namespace lgp {
namespace {

TEST(Ops, TableIsConsistent) {
  for (int i = 0; i < kNumOps; ++i) {
    const auto& info = allOps()[i];
    EXPECT_EQ(static_cast<int>(info.op), i) << info.name;
    EXPECT_GE(info.arity, 1);
    EXPECT_LE(info.arity, kMaxArity);
    EXPECT_EQ(opFromString(info.name), info.op);
    for (double c : info.cost) EXPECT_GE(c, 0.0) << info.name;
  }
  EXPECT_FALSE(opFromString("nope").has_value());
}

TEST(Ops, PiecewiseSetMatchesSpec) {
  for (const auto& info : allOps()) {
    const bool expected = info.op == Op::Min || info.op == Op::Max || info.op == Op::Abs ||
                          info.op == Op::Saturate || info.op == Op::Select;
    EXPECT_EQ(info.piecewise, expected) << info.name;
  }
}

// The nvidia column follows NVIDIA's documented issue rates (docs/cost-models.md): SFU ops 4,
// sqrt = rsq + rcp, div = rcp + mul, modifiers free.
TEST(Ops, NvidiaCostModelFollowsPublishedRatios) {
  auto c = [](Op op) { return opInfo(op).cost[static_cast<int>(CostTarget::Nvidia)]; };
  EXPECT_EQ(c(Op::Mad), 1);
  EXPECT_EQ(c(Op::Exp2), 4);
  EXPECT_EQ(c(Op::Rsqrt), 4);
  EXPECT_EQ(c(Op::Sqrt), 8);
  EXPECT_EQ(c(Op::Div), 5);
  EXPECT_EQ(c(Op::Abs), 0);
  EXPECT_EQ(costTargetFromString("nvidia"), CostTarget::Nvidia);
  EXPECT_FALSE(costTargetFromString("intel").has_value());
}

// The calibrated tables (rdna, gcn, and gpu-generic their mean; cost_model.hpp): prices are
// non-negative quarters, only protected operators have a guard price and every one on the GPU
// tables has one, and a compound operator costs at least its parts' primitive.
TEST(Ops, CalibratedCostTablesAreConsistent) {
  for (CostTarget t : {CostTarget::GpuGeneric, CostTarget::Gcn, CostTarget::Rdna}) {
    const int k = static_cast<int>(t);
    for (const auto& i : allOps()) {
      EXPECT_GE(i.cost[k], 0) << i.name;
      EXPECT_EQ(i.cost[k] * 4, std::round(i.cost[k] * 4)) << i.name;
      EXPECT_GE(i.guard_cost[k], 0) << i.name;
      if (!i.guarded) {
        EXPECT_EQ(i.guard_cost[k], 0) << i.name << " has no guard";
      }
      if (i.guarded && i.op != Op::Saturate) {
        EXPECT_GT(i.guard_cost[k], 0) << i.name;
      }
    }
    auto c = [&](Op op) { return opInfo(op).cost[k]; };
    EXPECT_GE(c(Op::Exp), c(Op::Exp2)) << toString(t);
    EXPECT_GE(c(Op::Log), c(Op::Log2)) << toString(t);
    EXPECT_GE(c(Op::Pow), std::max(c(Op::Exp2), c(Op::Log2))) << toString(t);
    EXPECT_GE(c(Op::Div), c(Op::Rcp)) << toString(t);
    EXPECT_GT(kCostExtras[k].literal, 0) << toString(t);
    ASSERT_TRUE(costCalibration(t).has_value()) << toString(t);
    EXPECT_LT(costCalibration(t)->rmse, 1.5) << toString(t);
  }
  // The hand tables price neither guards nor constants, and claim no calibration.
  for (CostTarget t : {CostTarget::Nvidia, CostTarget::Cpu}) {
    for (const auto& i : allOps()) EXPECT_EQ(i.guard_cost[static_cast<int>(t)], 0) << i.name;
    EXPECT_FALSE(costCalibration(t).has_value());
  }
}

}  // namespace
}  // namespace lgp
