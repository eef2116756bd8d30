// Members that fit only through float32 rounding are invalid (search-4's defect): the Scorer
// gives them the worst error, no front holds one, and the cancellation estimate flags them.
// The exploit: (x + 2^23) - 2^23 rounds x to the nearest integer in float32, a step the search
// can scale onto a step-shaped table; in double (and in every simplifier and emitted shader)
// the same program is x.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <nlohmann/json.hpp>

#include "lgp/config/config.hpp"
#include "lgp/core/cancellation.hpp"
#include "lgp/core/expr.hpp"
#include "lgp/eval/fidelity.hpp"
#include "lgp/eval/interpreter.hpp"
#include "lgp/eval/objectives.hpp"
#include "lgp/search/search.hpp"

namespace lgp {
namespace {

// y = step(x - 0.5) on 256 cell centres of [0, 1] (no row sits on the step).
Table stepTable() {
  Table t;
  t.input_names = {"x"};
  t.output_names = {"y"};
  t.inputs.resize(1);
  t.outputs.resize(1);
  for (int i = 0; i < 256; ++i) {
    const double x = (i + 0.5) / 256.0;
    t.inputs[0].push_back(x);
    t.outputs[0].push_back(x > 0.5 ? 1.0 : 0.0);
  }
  return t;
}

Program roundingExploit() {
  Program p;
  p.constants = {8388608.0f};  // 2^23: float32 spacing 1 above it
  p.code.push_back({Op::Add, {inputOperand(0), constOperand(0)}});
  p.code.push_back({Op::Sub, {regOperand(0), constOperand(0)}});
  p.outputs = {1};
  return p;
}

Program square() {
  Program p;
  p.code.push_back({Op::Mul, {inputOperand(0), inputOperand(0)}});
  p.outputs = {0};
  return p;
}

ErrorConfig scaled() {
  ErrorConfig e;
  e.linear_scaling = true;
  return e;
}

TEST(Fidelity, ScorerWithoutTheCheckIsFooledByRounding) {
  const Table t = stepTable();
  const Dataset ds(t, 64);
  Scorer s(ds, scaled(), 64);
  EXPECT_LT(s.error(roundingExploit()), 1e-6);  // float32 rounding fits the step exactly
}

TEST(Fidelity, ScorerGivesTheExploitTheWorstError) {
  const Table t = stepTable();
  const Dataset ds(t, 64);
  Scorer s(ds, scaled(), 64);
  FidelityCheck check(t, scaled(), kFidelitySampleRows);
  s.setFidelity(&check);
  EXPECT_EQ(s.error(roundingExploit()), std::numeric_limits<double>::infinity());
  EXPECT_EQ(s.fidelityRejects(), 1u);
  EXPECT_GT(check.lastRatio(), 1e3);  // off by the height of a step, not by an ulp

  // A genuine program keeps its error, and the check's ratio is at rounding level.
  const double e = s.error(square());
  EXPECT_TRUE(std::isfinite(e));
  EXPECT_LT(check.lastRatio(), 1e-2);
  EXPECT_EQ(s.fidelityRejects(), 1u);
}

TEST(Fidelity, EveryRowCheckSeesWhatTheSampleMisses) {
  // Rounding at 2^20 quantises x to steps of 1/8: small next to the target, caught on rows.
  Program p = roundingExploit();
  p.constants = {1048576.0f};
  const Table t = stepTable();
  FidelityCheck all(t, ErrorConfig{}, 0);
  EXPECT_EQ(all.rows(), t.rows());
  BoundProgram bp;
  bp.bind(p, 1);
  EXPECT_FALSE(all.passes(bp, {}));
}

TEST(Fidelity, ValueDeviationComparesTwoPrograms) {
  const Table t = stepTable();
  const Dataset ds(t, 64);
  const auto tol = fidelityTolerances(t);
  ASSERT_EQ(tol.size(), 1u);
  EXPECT_NEAR(tol[0], std::ldexp(std::sqrt(0.5), -kFidelityBits), 1e-9);
  // The exploit and what a simplifier makes of it (x) are different functions.
  Program x;
  x.code.push_back({Op::Mul, {inputOperand(0), inputOperand(0)}});
  x.code.push_back({Op::Max, {inputOperand(0), inputOperand(0)}});
  x.outputs = {1};
  EXPECT_GT(valueDeviation(roundingExploit(), x, ds, {}, tol), 1e3);
  EXPECT_LE(valueDeviation(square(), square(), ds, {}, tol), 0.0);
}

TEST(Fidelity, CancellationFlagsTheExploit) {
  const Table t = stepTable();
  const Program p = roundingExploit();
  const auto c = cancellation(buildDag(p, 1), t, {});
  EXPECT_TRUE(c.flagged) << c.bits_lost;
  EXPECT_GT(c.bits_lost, 20.0);
  EXPECT_LT(cancellation(buildDag(square(), 1), t, {}).bits_lost, 3.0);
}

// A search with linear scaling on the step table, seeded with the exploit, must hold none in
// its front: each member's float32 and double metrics agree within the bound.
TEST(Fidelity, FrontsHoldNoRoundingExploit) {
  const Table t = stepTable();
  const double tol = fidelityTolerances(t)[0];
  for (uint64_t seed : {1u, 2u, 3u}) {
    nlohmann::json cj = {{"data", {{"path", "step.csv"}}},
                         {"program", {{"max_length", 8}, {"constants", 4}}},
                         {"search",
                          {{"population", 96},
                           {"generations", 30},
                           {"seed", seed},
                           {"threads", 1},
                           {"linear_scaling", true}}}};
    auto cfg = parseRunConfig(cj, ".");
    ASSERT_TRUE(cfg.hasValue()) << cfg.error();
    Search s(*cfg, t);
    // Seeded with the exploit itself: without the check it is exact at cost 2 and dominates.
    s.addSeeds({{"exploit", roundingExploit()}});
    s.run();
    ASSERT_FALSE(s.front().empty());
    for (const auto& e : s.front()) {
      ASSERT_EQ(e.metrics.size(), 1u);
      EXPECT_LE(std::abs(e.metrics[0].rmse - e.metrics_ref[0].rmse), tol)
          << "seed " << seed << ": " << e.formula;
      EXPECT_LE(std::abs(e.metrics[0].max_abs - e.metrics_ref[0].max_abs), tol)
          << "seed " << seed << ": " << e.formula;
    }
    EXPECT_GT(s.refineStats().fidelity_rejects, 0u) << "seed " << seed;
  }
}

}  // namespace
}  // namespace lgp
