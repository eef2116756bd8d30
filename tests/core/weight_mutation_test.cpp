// The weight mutation (search-4, weighted operands): x becomes mul(c, x) with a coefficient of
// its own, set to 1 so the program computes exactly what it computed; a search with weights
// on is deterministic and exports what it scored.
#include <gtest/gtest.h>

#include <cstring>
#include <nlohmann/json.hpp>

#include "lgp/config/config.hpp"
#include "lgp/core/variation.hpp"
#include "lgp/eval/fidelity.hpp"
#include "lgp/eval/interpreter.hpp"
#include "lgp/search/search.hpp"
#include "test_tables.hpp"

namespace lgp {
namespace {

ProgramShape weightShape(OutputMode mode, int outputs) {
  ProgramShape shape;
  shape.num_inputs = 2;
  shape.num_outputs = outputs;
  shape.max_length = 24;
  shape.num_constants = 12;
  shape.output_mode = mode;
  return shape;
}

bool sameBits(const std::vector<std::vector<float>>& a, const std::vector<std::vector<float>>& b) {
  if (a.size() != b.size()) return false;
  for (size_t o = 0; o < a.size(); ++o)
    if (a[o].size() != b[o].size() ||
        std::memcmp(a[o].data(), b[o].data(), a[o].size() * sizeof(float)) != 0)
      return false;
  return true;
}

class WeightMutation : public ::testing::TestWithParam<std::tuple<OutputMode, int>> {};

// Every weighted program is valid, one opcode longer, computes the same bits on every row
// (protected operators, NaN and -0 included), and reads its new coefficient, a slot no opcode
// read before, through one new effective mul.
TEST_P(WeightMutation, NeutralValidAndOneNewCoefficient) {
  const auto [mode, outputs] = GetParam();
  const ProgramShape shape = weightShape(mode, outputs);
  // Inputs of both signs, so protected operators (log, sqrt, division) take their guards.
  const Table t = test::gridTableOf(6, [](double, double) { return 0.0; });
  Table wide = t;
  for (auto& col : wide.inputs)
    for (auto& v : col) v = 4 * v - 2;
  const Dataset ds(wide, 16);
  Interpreter it(16);
  Rng rng(7);
  int weighted = 0;
  for (int trial = 0; trial < 3000; ++trial) {
    Program p = randomProgram(shape, {2, 16, -2, 2}, rng);
    if (mode == OutputMode::Designated)
      for (auto& o : p.outputs) o = static_cast<uint8_t>(rng.below(p.code.size()));
    const Program before = p;
    if (!weightMutate(p, shape, rng)) {
      EXPECT_EQ(p, before);
      continue;
    }
    ++weighted;
    ASSERT_TRUE(validate(p, shape)) << validate(p, shape).message();
    ASSERT_EQ(p.code.size(), before.code.size() + 1);
    EXPECT_TRUE(sameBits(it.evaluate(before, ds), it.evaluate(p, ds))) << "trial " << trial;
    const auto live_before = effectiveConstants(before), live_after = effectiveConstants(p);
    ASSERT_EQ(live_after.size(), live_before.size() + 1);
    int added = -1;
    for (int c : live_after)
      if (std::find(live_before.begin(), live_before.end(), c) == live_before.end()) added = c;
    ASSERT_GE(added, 0);
    EXPECT_EQ(p.constants[added], 1.0f);
    for (const Instr& ins : before.code)  // no opcode read it, introns included
      for (int a = 0; a < arity(ins.op); ++a)
        EXPECT_FALSE(ins.args[a].kind == OperandKind::Const && ins.args[a].index == added);
    EXPECT_EQ(effectiveIndices(p).size(), effectiveIndices(before).size() + 1);
  }
  EXPECT_GT(weighted, 1500);  // most random programs have an operand to weight
}

INSTANTIATE_TEST_SUITE_P(Modes, WeightMutation,
                         ::testing::Combine(::testing::Values(OutputMode::Last,
                                                              OutputMode::Designated),
                                            ::testing::Values(1, 2)));

TEST(WeightMutationCases, AWeightIsNotWeightedAgain) {
  const ProgramShape shape = weightShape(OutputMode::Last, 1);
  Program p;
  p.code.push_back({Op::Mul, {constOperand(0), inputOperand(0)}});
  p.constants.assign(12, 0.5f);
  syncOutputs(p, shape);
  Rng rng(1);
  EXPECT_FALSE(weightMutate(p, shape, rng));  // the only opcode is a weight
  p.code.push_back({Op::Add, {regOperand(0), inputOperand(1)}});
  syncOutputs(p, shape);
  for (int k = 0; k < 20; ++k) {
    Program q = p;
    ASSERT_TRUE(weightMutate(q, shape, rng));
    // Only x1 qualifies: r0 is a weight already.
    ASSERT_EQ(q.code.size(), 3u);
    EXPECT_EQ(q.code[1].op, Op::Mul);
    EXPECT_EQ(q.code[1].args[1], inputOperand(1));
    EXPECT_EQ(q.code[2].args[0], regOperand(0));
    EXPECT_EQ(q.code[2].args[1], regOperand(1));
  }
}

TEST(WeightMutationCases, NoFreeSlotOrNoRoomLeavesTheProgram) {
  ProgramShape shape = weightShape(OutputMode::Last, 1);
  shape.num_constants = 1;
  Program p;
  p.code.push_back({Op::Add, {inputOperand(0), constOperand(0)}});
  p.constants = {0.25f};
  syncOutputs(p, shape);
  Rng rng(2);
  const Program before = p;
  EXPECT_FALSE(weightMutate(p, shape, rng));  // the one slot is read
  EXPECT_EQ(p, before);
  shape.num_constants = 2;
  p.constants = {0.25f, 3.0f};
  shape.max_length = 1;
  EXPECT_FALSE(weightMutate(p, shape, rng));  // at max_length
  shape.max_length = 2;
  ASSERT_TRUE(weightMutate(p, shape, rng));
  EXPECT_EQ(p.constants[1], 1.0f);
}

nlohmann::json weightConfig(double rate) {
  return {{"data", {{"path", "t.csv"}, {"outputs", {"y"}}}},
          {"program", {{"max_length", 16}, {"constants", 12}}},
          {"search",
           {{"population", 96},
            {"generations", 15},
            {"seed", 5},
            {"threads", 2},
            {"variation", {{"weight_rate", rate}, {"weight_min_length", 0}}}}}};
}

// The default is on (0.25, from 16 effective opcodes); 0 turns weights off and, like every
// value, is written, so a config round-trips.
TEST(WeightMutationSearch, ConfigDefaultIsOnAndRoundTrips) {
  const RunConfig defaults;
  EXPECT_EQ(defaults.search.variation.weight_rate, 0.25);
  EXPECT_EQ(defaults.search.variation.weight_min_length, 16);
  auto off = parseRunConfig(weightConfig(0), ".");
  ASSERT_TRUE(off.hasValue()) << off.error();
  EXPECT_EQ(toJson(*off)["search"]["variation"]["weight_rate"], 0);
  auto again = parseRunConfig(toJson(*off), ".");
  ASSERT_TRUE(again.hasValue()) << again.error();
  EXPECT_EQ(again->search.variation.weight_rate, 0);
  EXPECT_EQ(again->search.variation.weight_min_length, 0);
  auto on = parseRunConfig(weightConfig(0.25), ".");
  ASSERT_TRUE(on.hasValue()) << on.error();
  EXPECT_EQ(toJson(*on)["search"]["variation"]["weight_rate"], 0.25);
  auto bad = parseRunConfig(weightConfig(1.5), ".");
  ASSERT_FALSE(bad.hasValue());
  EXPECT_NE(bad.error().find("/search/variation/weight_rate"), std::string::npos) << bad.error();
}

// Same seed and threads, same front; every member exports what it scored (the float32 and
// double metrics agree within the fidelity bound), weights or not.
TEST(WeightMutationSearch, SameSeedSameFrontAndMembersReproduceTheirScore) {
  const Table t = test::gridTable(16);
  auto cfg = parseRunConfig(weightConfig(0.5), ".");
  ASSERT_TRUE(cfg.hasValue()) << cfg.error();
  std::vector<std::string> a, b;
  const double tol = fidelityTolerances(t)[0];
  for (auto* out : {&a, &b}) {
    Search s(*cfg, t);
    s.run();
    ASSERT_FALSE(s.front().empty());
    for (const auto& e : s.front()) {
      out->push_back(e.formula);
      EXPECT_NEAR(e.metrics[0].rmse, e.metrics_ref[0].rmse, tol) << e.formula;
    }
  }
  EXPECT_EQ(a, b);
  // Weights change the search: the front differs from the run without them.
  auto none = parseRunConfig(weightConfig(0), ".");
  Search s(*none, t);
  s.run();
  std::vector<std::string> c;
  for (const auto& e : s.front()) c.push_back(e.formula);
  EXPECT_NE(a, c);
}

}  // namespace
}  // namespace lgp

namespace lgp {
namespace {

std::vector<std::string> frontFormulas(const nlohmann::json& j) {
  auto cfg = parseRunConfig(j, ".");
  EXPECT_TRUE(cfg.hasValue()) << cfg.error();
  Search s(*cfg, test::gridTable(16));
  s.run();
  std::vector<std::string> out;
  for (const auto& e : s.front()) out.push_back(e.formula);
  return out;
}

// weight_min_length: children with fewer effective opcodes get no weight (and draw nothing),
// so a threshold no child reaches is the run without weights, and one in between is neither.
TEST(WeightMutationSearch, MinLengthLeavesSmallChildrenUnweighted) {
  auto with = [](double rate, int min_length) {
    nlohmann::json j = weightConfig(rate);
    j["search"]["variation"]["weight_min_length"] = min_length;
    return j;
  };
  const auto none = frontFormulas(with(0, 0));
  const auto all = frontFormulas(with(0.5, 0));
  EXPECT_EQ(frontFormulas(with(0.5, 256)), none);
  const auto large = frontFormulas(with(0.5, 3));
  EXPECT_NE(large, none);
  EXPECT_NE(large, all);
  auto cfg = parseRunConfig(with(0.5, 6), ".");
  ASSERT_TRUE(cfg.hasValue());
  EXPECT_EQ(toJson(*cfg)["search"]["variation"]["weight_min_length"], 6);
  EXPECT_EQ(toJson(*parseRunConfig(with(0.5, 0), "."))["search"]["variation"]["weight_min_length"],
            0);
  auto bad = parseRunConfig(with(0.5, 300), ".");
  ASSERT_FALSE(bad.hasValue());
  EXPECT_NE(bad.error().find("/search/variation/weight_min_length"), std::string::npos)
      << bad.error();
}

}  // namespace
}  // namespace lgp
