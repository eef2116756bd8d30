// Residual stages (search/stage.hpp): the residual table is what the base leaves, the
// composite computes base + correction (base * correction, base(x_i + correction)), and stage
// islands inside a search put composites into the archive, deterministically and through a
// resume.
#include <gtest/gtest.h>

#include <cmath>

#include "lgp/eval/interpreter.hpp"
#include "lgp/io/result.hpp"
#include "lgp/search/search.hpp"
#include "lgp/search/stage.hpp"
#include "test_tables.hpp"

namespace lgp {
namespace {

Instr instr(Op op, Operand a, Operand b = {}, Operand c = {}) {
  Instr in;
  in.op = op;
  in.args = {a, b, c, Operand{}};
  return in;
}

std::vector<std::vector<float>> run(const Program& p, const Table& t) {
  Dataset ds(t, 256);
  Interpreter in(256);
  return in.evaluate(p, ds);
}

TEST(Stage, TheResidualTableIsWhatTheBaseLeaves) {
  const Table t = test::gridTableOf(4, [](double x, double y) { return 1 + x * y; });
  std::vector<std::vector<float>> f(1);
  for (size_t r = 0; r < t.rows(); ++r) f[0].push_back(static_cast<float>(1 + t.inputs[0][r]));
  const Table add = residualTable(t, f, {}, StageMode::Add);
  ASSERT_EQ(add.input_names, (std::vector<std::string>{"mu", "r", "f_y"}));
  const Table mul = residualTable(t, f, {}, StageMode::Mul);
  for (size_t r = 0; r < t.rows(); ++r) {
    EXPECT_NEAR(add.outputs[0][r], t.outputs[0][r] - f[0][r], 1e-12);
    EXPECT_EQ(add.weights[r], 1.0);
    EXPECT_NEAR(mul.outputs[0][r], t.outputs[0][r] / f[0][r], 1e-12);
    // (y - f g)^2 = f^2 (y / f - g)^2
    EXPECT_NEAR(mul.weights[r], double(f[0][r]) * f[0][r], 1e-12);
  }
}

TEST(Stage, TheCompositeComputesBaseAndCorrection) {
  const Table t = test::gridTableOf(4, [](double x, double y) { return x + y; });
  // base f = 2 mu (constant slot 3 of 4), correction g = 0.5 f + r (reads input 2: f).
  Program base;
  base.constants = {0, 0, 0, 2.0f};
  base.code = {instr(Op::Mul, inputOperand(0), constOperand(3))};
  base.outputs = {0};
  Program corr;
  corr.constants = {0.5f};
  corr.code = {instr(Op::Mad, inputOperand(2), constOperand(0), inputOperand(1))};
  corr.outputs = {0};
  for (StageMode mode : {StageMode::Add, StageMode::Mul}) {
    const Program c = composeStage(base, corr, 2, mode);
    ASSERT_EQ(c.code.size(), 3u);
    EXPECT_EQ(c.constants.size(), 2u);  // renumbered densely: the base's slot 3 is slot 0
    const auto v = run(c, t);
    for (size_t r = 0; r < t.rows(); ++r) {
      const double mu = t.inputs[0][r], rr = t.inputs[1][r];
      const double f = 2 * mu, g = 0.5 * f + rr;
      EXPECT_NEAR(v[0][r], mode == StageMode::Add ? f + g : f * g, 1e-6);
    }
  }
}

// Inside: the target is the Gauss-Newton step (y - f) / f' weighted f'^2; a step past the
// input's span is no linearisation and has weight 0. f' comes from differences of f.
TEST(Stage, TheInsideResidualIsTheGaussNewtonStep) {
  const Table t = test::gridTableOf(5, [](double x, double y) { return x * x + y; });
  // base f = mu^2: slope 2 mu (central differences exact for a square up to float rounding;
  // one-sided at the span's ends, off by the step h = 1e-3 of the span).
  Program base;
  base.code = {instr(Op::Mul, inputOperand(0), inputOperand(0))};
  base.outputs = {0};
  const auto slope = inputSlope(base, t, 0, 256);
  const auto f = run(base, t);
  ASSERT_EQ(slope.size(), t.rows());
  double lo = INFINITY, hi = -INFINITY;
  for (double x : t.inputs[0]) lo = std::min(lo, x), hi = std::max(hi, x);
  for (size_t r = 0; r < t.rows(); ++r)
    EXPECT_NEAR(slope[r], 2 * t.inputs[0][r], 2e-3 * (hi - lo) + 1e-3) << r;
  const Table in = residualTable(t, f, {}, StageMode::Inside, 0, slope);
  ASSERT_EQ(in.input_names, (std::vector<std::string>{"mu", "r", "f_y"}));
  size_t used = 0;
  for (size_t r = 0; r < t.rows(); ++r) {
    const double step = (t.outputs[0][r] - f[0][r]) / slope[r];
    if (slope[r] != 0 && std::fabs(step) <= hi - lo) {
      ++used;
      EXPECT_NEAR(in.outputs[0][r], step, 1e-9);
      EXPECT_NEAR(in.weights[r], slope[r] * slope[r], 1e-12);
    } else {
      EXPECT_EQ(in.weights[r], 0.0) << r;  // small mu: the step r / (2 mu) leaves the span
      EXPECT_EQ(in.outputs[0][r], 0.0);
    }
  }
  EXPECT_GT(used, t.rows() / 2);
  EXPECT_LT(used, t.rows());
  // A base that does not read the input has slope 0 everywhere: no row is usable.
  Program flat;
  flat.code = {instr(Op::Mul, inputOperand(1), inputOperand(1))};
  flat.outputs = {0};
  for (double v : inputSlope(flat, t, 0, 256)) EXPECT_EQ(v, 0.0);
}

TEST(Stage, TheInsideCompositeCorrectsTheArgument) {
  const Table t = test::gridTableOf(4, [](double x, double y) { return x + y; });
  // base f = mu * mu + r; corrections g = 0.5 f + 0.1 (reads input 2: f) and g = 0.3 r.
  Program base;
  base.constants = {0, 7.0f};  // slot 1 unused: constants renumber densely
  base.code = {instr(Op::Mad, inputOperand(0), inputOperand(0), inputOperand(1))};
  base.outputs = {0};
  Program reads_f;
  reads_f.constants = {0.5f, 0.1f};
  reads_f.code = {instr(Op::Mad, inputOperand(2), constOperand(0), constOperand(1))};
  reads_f.outputs = {0};
  Program plain;
  plain.constants = {0.3f};
  plain.code = {instr(Op::Mul, inputOperand(1), constOperand(0))};
  plain.outputs = {0};
  const Program a = composeStage(base, reads_f, 2, StageMode::Inside, 0);
  const Program b = composeStage(base, plain, 2, StageMode::Inside, 0);
  const Program c = composeStage(base, plain, 2, StageMode::Inside, 1);
  ASSERT_EQ(a.code.size(), 4u);  // f, g, mu + g, f again
  ASSERT_EQ(b.code.size(), 3u);  // g, mu + g, f: the first f is an intron
  EXPECT_EQ(a.constants.size(), 2u);
  const auto va = run(a, t), vb = run(b, t), vc = run(c, t);
  for (size_t r = 0; r < t.rows(); ++r) {
    const double mu = t.inputs[0][r], rr = t.inputs[1][r];
    const double f = mu * mu + rr;
    const double ga = 0.5 * f + 0.1, gb = 0.3 * rr;
    EXPECT_NEAR(va[0][r], (mu + ga) * (mu + ga) + rr, 1e-5);
    EXPECT_NEAR(vb[0][r], (mu + gb) * (mu + gb) + rr, 1e-5);
    EXPECT_NEAR(vc[0][r], mu * mu + rr + gb, 1e-5);
  }
  // Only one output and an input of the run can be corrected.
  EXPECT_TRUE(composeStage(base, plain, 2, StageMode::Inside, 2).code.empty());
  Program two = base;
  two.outputs = {0, 0};
  Program two_g = plain;
  two_g.outputs = {0, 0};
  EXPECT_TRUE(composeStage(two, two_g, 2, StageMode::Inside, 0).code.empty());
}

// Islands limited to 3 opcodes cannot fit this table well; a stage correcting their best
// member with 8 more can, so its composites enter the archive.
RunConfig stagedConfig() {
  RunConfig c;
  c.data.path = "in-memory";
  c.search.population = 60;
  c.search.generations = 40;
  c.search.threads = 2;
  c.search.seed = 5;
  c.search.refine.offspring_share = 0.5;
  c.search.refine.archive_period = 5;
  c.search.structured.max_degree = 0;
  c.program.max_length = 24;
  c.search.islands.count = 2;
  c.search.islands.profiles = {{.max_length = 3, .constants = 4}};
  c.search.stages.islands = 1;
  c.search.stages.population = 60;
  c.search.stages.retarget = 12;
  c.search.stages.max_length = 8;
  c.search.stages.constants = 4;
  return c;
}

Table stagedTable() {
  return test::gridTableOf(
      10, [](double x, double y) { return x * y + 0.3 * std::exp2(-2 * x) + 0.2 * y * y; });
}

TEST(Stage, CompositesEnterTheArchive) {
  Search s(stagedConfig(), stagedTable());
  s.run();
  const auto info = s.stagesInfo();
  ASSERT_TRUE(info.is_array());
  ASSERT_EQ(info.size(), 1u);
  EXPECT_GE(info[0]["picks"].get<int>(), 2);
  EXPECT_GT(info[0]["composites"].get<int>(), 0);
  // Without the stage island, the same islands stay behind the composites.
  RunConfig off = stagedConfig();
  off.search.stages.islands = 0;
  Search plain(off, stagedTable());
  plain.run();
  EXPECT_TRUE(plain.stagesInfo().is_null());
  auto best = [](const std::vector<FrontEntry>& f) {
    double e = INFINITY;
    for (const auto& m : f) e = std::min(e, m.obj.error);
    return e;
  };
  const auto front = s.front();
  EXPECT_LT(best(front), 0.8 * best(plain.front()));
  for (const auto& m : front) EXPECT_TRUE(std::isfinite(m.obj.error));
}

TEST(Stage, StagedRunsAreDeterministicAndResume) {
  Search full(stagedConfig(), stagedTable());
  full.run();
  Search again(stagedConfig(), stagedTable());
  again.run();
  EXPECT_EQ(frontToJson(full, full.front())["members"],
            frontToJson(again, again.front())["members"]);
  Search first(stagedConfig(), stagedTable());
  for (int g = 0; g < 8; ++g) first.step();
  const auto cp = nlohmann::json::parse(first.checkpoint().dump());
  ASSERT_TRUE(cp.contains("stages"));
  ASSERT_FALSE(cp["stages"][0]["base"].is_null());
  Search resumed(stagedConfig(), stagedTable());
  const Status st = resumed.restore(cp);
  ASSERT_TRUE(st) << st.message();
  resumed.run();
  EXPECT_EQ(frontToJson(resumed, resumed.front())["members"],
            frontToJson(full, full.front())["members"]);
  EXPECT_EQ(resumed.progress().evaluations, full.progress().evaluations);
  // A stage member's claimed error is scored again on the stage's residual table.
  auto tampered = cp;
  tampered["stages"][0]["population"][0]["obj"][0] = 1e-9;
  Search t(stagedConfig(), stagedTable());
  const Status bad = t.restore(tampered);
  EXPECT_FALSE(bad);
  EXPECT_NE(bad.message().find("stage 0 member 0 claims error"), std::string::npos)
      << bad.message();
}

// pick = spread: bases from the front's error-cost staircase, evenly spaced from its cheapest
// step; dominated candidates are never picked. pick = accurate: the most accurate first.
TEST(Stage, SpreadBasesRunAlongTheStaircase) {
  // (error, cost): a staircase 0.5@1, 0.2@3, 0.1@6, 0.05@10, 0.01@20 and two dominated members.
  const std::vector<std::pair<double, double>> ec = {{0.1, 6}, {0.5, 1},   {0.3, 8}, {0.01, 20},
                                                     {0.2, 3}, {0.05, 10}, {0.6, 2}};
  EXPECT_EQ(stageBases(ec, 3, StagePick::Spread), (std::vector<size_t>{1, 0, 3}));
  EXPECT_EQ(stageBases(ec, 8, StagePick::Spread), (std::vector<size_t>{1, 4, 0, 5, 3}));
  EXPECT_EQ(stageBases(ec, 1, StagePick::Spread), (std::vector<size_t>{1}));
  EXPECT_EQ(stageBases(ec, 3, StagePick::Accurate), (std::vector<size_t>{3, 5, 0}));
  EXPECT_TRUE(stageBases({}, 3, StagePick::Spread).empty());
}

// A spread run puts composites into the archive and repeats.
TEST(Stage, SpreadStagesAreDeterministic) {
  RunConfig spread = stagedConfig();
  spread.search.stages.pick = StagePick::Spread;
  Search s(spread, stagedTable());
  s.run();
  EXPECT_GE(s.stagesInfo()[0]["picks"].get<int>(), 2);
  EXPECT_GT(s.stagesInfo()[0]["composites"].get<int>(), 0);
  Search again(spread, stagedTable());
  again.run();
  EXPECT_EQ(frontToJson(s, s.front())["members"], frontToJson(again, again.front())["members"]);
}

// Inside mode in a search: its composites enter the archive, runs repeat and resume (the
// corrected input in the checkpoint), and a checkpoint naming no input of the run is refused.
TEST(Stage, InsideStagesSearchCorrectedArguments) {
  RunConfig cfg = stagedConfig();
  cfg.search.stages.modes = {StageMode::Inside};
  Search full(cfg, stagedTable());
  full.run();
  const auto info = full.stagesInfo();
  ASSERT_TRUE(info.is_array());
  EXPECT_EQ(info[0]["mode"], "inside");
  EXPECT_GE(info[0]["picks"].get<int>(), 2);
  EXPECT_GT(info[0]["composites"].get<int>(), 0);
  for (const auto& m : full.front()) EXPECT_TRUE(std::isfinite(m.obj.error));
  Search first(cfg, stagedTable());
  for (int g = 0; g < 15; ++g) first.step();
  const auto cp = nlohmann::json::parse(first.checkpoint().dump());
  ASSERT_EQ(cp["stages"][0]["mode"], "inside");
  // The second pick corrects the second input.
  EXPECT_EQ(cp["stages"][0]["input"], 1);
  Search resumed(cfg, stagedTable());
  const Status st = resumed.restore(cp);
  ASSERT_TRUE(st) << st.message();
  resumed.run();
  EXPECT_EQ(frontToJson(resumed, resumed.front())["members"],
            frontToJson(full, full.front())["members"]);
  auto bad = cp;
  bad["stages"][0]["input"] = 2;
  Search t(cfg, stagedTable());
  const Status refused = t.restore(bad);
  EXPECT_FALSE(refused);
  EXPECT_NE(refused.message().find("stage 0: input must be an input index, 0 to 1"),
            std::string::npos)
      << refused.message();
}

}  // namespace
}  // namespace lgp
