#include <gtest/gtest.h>

#include "lgp/core/ops.hpp"

namespace lgp {
namespace {

TEST(Ops, TableIsConsistent) {
  EXPECT_EQ(kNumOps, 23);
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

// The gpu-generic column of the cost table in docs/cost-models.md (transcendentals 4,
// modifiers abs/neg/saturate 0), which gives the vendor documents it is derived from.
TEST(Ops, GenericCostModelFollowsPublishedRatios) {
  auto c = [](Op op) { return opInfo(op).cost[static_cast<int>(CostTarget::GpuGeneric)]; };
  EXPECT_EQ(c(Op::Mad), 1);
  EXPECT_EQ(c(Op::Add), 1);
  EXPECT_EQ(c(Op::Exp2), 4);
  EXPECT_EQ(c(Op::Rsqrt), 4);
  EXPECT_EQ(c(Op::Abs), 0);
  EXPECT_EQ(c(Op::Neg), 0);
  EXPECT_EQ(c(Op::Saturate), 0);
  EXPECT_EQ(costTargetFromString("nvidia"), CostTarget::Nvidia);
  EXPECT_FALSE(costTargetFromString("intel").has_value());
}

}  // namespace
}  // namespace lgp
