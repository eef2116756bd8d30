// Residual stages (search/stage.hpp): the residual table is what the base leaves, the
// composite computes base + correction (or base * correction), and stage islands inside a
// search put composites into the archive, deterministically and through a resume.
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

}  // namespace
}  // namespace lgp
