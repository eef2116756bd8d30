// Multi-output search: error channels, linear scaling, seeding, and the two-step mode.
#include <gtest/gtest.h>

#include <cmath>

#include "lgp/config/config.hpp"
#include "lgp/io/result.hpp"
#include "lgp/search/search.hpp"
#include "lgp/search/two_step.hpp"

namespace lgp {
namespace {

// Two outputs over (x, y): A = x*y + 0.5, B = x*x.
Table twoOutputs(int n) {
  Table t;
  t.input_names = {"x", "y"};
  t.output_names = {"A", "B"};
  t.inputs.resize(2);
  t.outputs.resize(2);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      const double x = (i + 0.5) / n, y = (j + 0.5) / n;
      t.inputs[0].push_back(x);
      t.inputs[1].push_back(y);
      t.outputs[0].push_back(x * y + 0.5);
      t.outputs[1].push_back(x * x);
    }
  return t;
}

// A = x*y + 0.5 exactly (slot 0: 0.5), B = x*x + d (slot 1: d); outputs designated.
Program exactAPlusOffsetB(float d) {
  Program p;
  p.code.push_back(Instr{Op::Mad, {inputOperand(0), inputOperand(1), constOperand(0)}});
  p.code.push_back(Instr{Op::Mad, {inputOperand(0), inputOperand(0), constOperand(1)}});
  p.constants = {0.5f, d};
  p.outputs = {0, 1};
  return p;
}

std::vector<float> evalOutput(const Program& p, const Table& t, int o) {
  return Interpreter(64).evaluate(p, Dataset(t, 64))[o];
}

ErrorConfig channelConfig() {
  ErrorConfig ec;
  ec.channels = {{"F0=1", {1.0, 1.0}}, {"F0=0.04", {0.04, 1.0}}};
  return ec;
}

TEST(Channels, ErrorIsMeasuredOnTheWeightedSums) {
  const Table t = twoOutputs(16);
  Dataset ds(t, 64);
  const float d = 0.125f;  // exact in float: every channel is off by d
  Scorer s(ds, channelConfig(), 64);
  EXPECT_NEAR(s.error(exactAPlusOffsetB(d)), d, 1e-6);
  const auto cm = s.channelMetrics(exactAPlusOffsetB(d));
  ASSERT_EQ(cm.size(), 2u);
  EXPECT_NEAR(cm[0].rmse, d, 1e-6);
  EXPECT_NEAR(cm[1].max_abs, d, 1e-6);
  const auto ref = referenceChannelMetrics(exactAPlusOffsetB(d), t, channelConfig());
  EXPECT_NEAR(ref[0].rmse, d, 1e-7);
  EXPECT_NEAR(ref[1].mae, d, 1e-7);
  // Per-output metrics are still per output: A is exact, B is off by d.
  const auto om = s.metrics(exactAPlusOffsetB(d));
  EXPECT_LT(om[0].rmse, 1e-6);
  EXPECT_NEAR(om[1].rmse, d, 1e-6);
  // Max over channels, with a channel that weighs B more.
  ErrorConfig ec = channelConfig();
  ec.channels[1].weights = {1.0, 3.0};
  ec.combine = OutputCombine::Max;
  Scorer s2(ds, ec, 64);
  EXPECT_NEAR(s2.error(exactAPlusOffsetB(d)), 3 * d, 1e-6);
  EXPECT_NEAR(combineError(s2.channelMetrics(exactAPlusOffsetB(d)), ec), 3 * d, 1e-6);
}

TEST(Channels, ConfigNamesOutputsAndRejectsUnknownOnes) {
  const nlohmann::json base = {
      {"data", {{"path", "t.csv"}, {"outputs", {"A", "B"}}}},
      {"objectives", {{"channels", {{{"name", "F0=1"}, {"weights", {{"A", 1}, {"B", 1}}}}}}}}};
  auto c = parseRunConfig(base, ".");
  ASSERT_TRUE(c) << c.error();
  const auto ec = c->errorConfig({"A", "B"});
  ASSERT_EQ(ec.channels.size(), 1u);
  EXPECT_EQ(ec.channels[0].weights, (std::vector<double>{1, 1}));
  // Round trip through toJson.
  auto again = parseRunConfig(toJson(*c), ".");
  ASSERT_TRUE(again) << again.error();
  EXPECT_EQ(again->objectives.channels.size(), 1u);

  nlohmann::json bad = base;
  bad["objectives"]["channels"][0]["weights"]["C"] = 2;
  auto e = parseRunConfig(bad, ".");
  ASSERT_FALSE(e);
  EXPECT_NE(e.error().find("/objectives/channels/0/weights/C"), std::string::npos) << e.error();
  bad = base;
  bad["objectives"]["channels"][0]["weights"] = nlohmann::json::object();
  EXPECT_FALSE(parseRunConfig(bad, "."));
  bad = base;
  bad["data"].erase("outputs");
  e = parseRunConfig(bad, ".");
  ASSERT_FALSE(e);
  EXPECT_NE(e.error().find("data.outputs"), std::string::npos) << e.error();
}

TEST(LinearScaling, ClosedFormScaleAndOffsetAreMaterialisedExactly) {
  Table t;
  t.input_names = {"x"};
  t.output_names = {"y"};
  t.inputs = {{}};
  t.outputs = {{}};
  for (int i = 0; i < 100; ++i) {
    const double x = i / 99.0;
    t.inputs[0].push_back(x);
    t.outputs[0].push_back(3.0 * x * x - 2.0);
  }
  Program body;  // x*x
  body.code.push_back(Instr{Op::Square, {inputOperand(0)}});
  body.outputs = {0};
  Dataset ds(t, 64);
  ErrorConfig ec;
  ec.linear_scaling = true;
  Scorer scaled(ds, ec, 64);
  const double e = scaled.error(body);
  EXPECT_LT(e, 1e-6);
  ASSERT_EQ(scaled.scales().size(), 1u);
  EXPECT_NEAR(scaled.scales()[0].a, 3.0, 1e-5);
  EXPECT_NEAR(scaled.scales()[0].b, -2.0, 1e-5);
  // The materialised program computes exactly what error() measured, without scaling.
  const Program full = applyLinearScaling(body, scaled.scales());
  ASSERT_EQ(full.code.size(), 2u);
  EXPECT_EQ(full.code[1].op, Op::Mad);
  Scorer plain(ds, ErrorConfig{}, 64);
  EXPECT_EQ(plain.error(full), e);
  // The materialised mad and its constants are costed: the exported program costs more.
  const CostModel gen = CostModel::preset(CostTarget::GpuGeneric);
  EXPECT_GE(gen.programCost(full), gen.programCost(body) + gen.cost[static_cast<int>(Op::Mad)]);
  // metrics() never scales: the bare body is far off.
  EXPECT_GT(scaled.metrics(body)[0].rmse, 0.5);
}

TEST(LinearScaling, NonFiniteOutputsAndConstantsStayWellDefined) {
  const Table t = twoOutputs(8);
  Dataset ds(t, 64);
  ErrorConfig ec;
  ec.linear_scaling = true;
  Scorer s(ds, ec, 64);
  Program nanp;  // 0 * inf is not reachable (protected ops); use log2 of 0 -> finite floor
  nanp.code.push_back(Instr{Op::Sub, {inputOperand(0), inputOperand(0)}});  // exactly 0
  nanp.code.push_back(Instr{Op::Add, {inputOperand(1), inputOperand(1)}});
  nanp.outputs = {0, 1};
  const double e = s.error(nanp);
  EXPECT_TRUE(std::isfinite(e));
  EXPECT_EQ(s.scales()[0].a, 0.0f);  // a constant output: the offset alone is fitted
  // Offset = the mean of A.
  double mean = 0;
  for (double v : t.outputs[0]) mean += v;
  EXPECT_NEAR(s.scales()[0].b, mean / t.rows(), 1e-6);
}

TEST(LinearScaling, SearchFrontProgramsCarryTheirScaling) {
  RunConfig c;
  c.data.path = "in-memory";
  c.data.outputs = {"A", "B"};
  c.search.population = 60;
  c.search.generations = 6;
  c.search.threads = 1;
  c.search.linear_scaling = true;
  c.program.max_length = 12;
  c.program.output_mode = OutputMode::Designated;
  c.objectives.channels = {{"F0=1", {{"A", 1.0}, {"B", 1.0}}}};
  Search s(c, twoOutputs(10));
  s.run();
  const auto front = s.front();
  ASSERT_FALSE(front.empty());
  ErrorConfig plain = c.errorConfig({"A", "B"});
  const Table t = twoOutputs(10);
  Dataset ds(t, c.eval.block_size);
  Scorer sc(ds, plain, c.eval.block_size);
  CostModel cm = c.costModel();
  cm.domain = tableDomain(t);
  for (const auto& m : front) {
    // Re-measuring the exported program without scaling gives the searched error and cost.
    EXPECT_DOUBLE_EQ(sc.error(m.program), m.obj.error);
    EXPECT_DOUBLE_EQ(cm.programCost(m.program), m.obj.cost);
    ASSERT_EQ(m.channel_metrics.size(), 1u);
    EXPECT_NEAR(m.channel_metrics[0].rmse, m.channel_metrics_ref[0].rmse, 1e-5);
  }
  const auto j = frontToJson(s, front);
  EXPECT_EQ(j["error_channels"], nlohmann::json({"F0=1"}));
  EXPECT_TRUE(j["members"][0].contains("channels"));
}

TEST(Seeding, FitToShapeMovesOutputsLastOrExplainsWhy) {
  ProgramShape shape;
  shape.num_inputs = 2;
  shape.num_outputs = 2;
  shape.max_length = 8;
  shape.num_constants = 4;
  // B (opcode 0) then A (opcode 1): outputs [A, B] = [1, 0]; nothing reads them.
  Program p;
  p.code.push_back(Instr{Op::Mul, {inputOperand(0), inputOperand(0)}});
  p.code.push_back(Instr{Op::Mad, {inputOperand(0), inputOperand(1), constOperand(0)}});
  p.constants = {0.5f};
  p.outputs = {1, 0};
  auto q = fitToShape(p, shape);
  ASSERT_TRUE(q) << q.error();
  EXPECT_EQ(q->outputs, (std::vector<uint8_t>{0, 1}));
  EXPECT_EQ(q->constants.size(), 4u);
  const Table t = twoOutputs(4);
  EXPECT_EQ(evalOutput(*q, t, 0), evalOutput(p, t, 0));
  EXPECT_EQ(evalOutput(*q, t, 1), evalOutput(p, t, 1));

  // A reads B: "last" cannot hold it, "designated" can.
  Program r = p;
  r.code[1] = Instr{Op::Mad, {regOperand(0), inputOperand(1), constOperand(0)}};
  auto bad = fitToShape(r, shape);
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.error().find("designated"), std::string::npos);
  shape.output_mode = OutputMode::Designated;
  EXPECT_TRUE(fitToShape(r, shape));
  shape.max_length = 1;
  bad = fitToShape(r, shape);
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.error().find("max_length"), std::string::npos);
  shape.max_length = 8;
  shape.ops = OpSet();
  shape.ops.insert(Op::Add);
  bad = fitToShape(r, shape);
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.error().find("'mul'"), std::string::npos) << bad.error();
}

TEST(Seeding, SeedsEnterTheInitialPopulation) {
  RunConfig c;
  c.data.path = "in-memory";
  c.data.outputs = {"A", "B"};
  c.search.population = 20;
  c.search.generations = 1;
  c.search.threads = 1;
  c.search.refine.archive_period = 0;
  c.program.output_mode = OutputMode::Designated;
  c.program.max_length = 32;
  Search s(c, twoOutputs(8));
  Program too_long;
  too_long.code.push_back(Instr{Op::Add, {inputOperand(0), inputOperand(1)}});
  for (int i = 1; i < 40; ++i)  // a chain: every opcode is effective
    too_long.code.push_back(Instr{Op::Add, {regOperand(i - 1), inputOperand(1)}});
  too_long.outputs = {38, 39};
  const auto skipped = s.addSeeds({{"exact", exactAPlusOffsetB(0.0f)}, {"long", too_long}});
  ASSERT_EQ(skipped.size(), 1u);
  EXPECT_NE(skipped[0].find("long"), std::string::npos);
  s.initialize();
  // The exact program is in the archive from generation 0.
  EXPECT_LT(s.progress().best_error, 1e-7);
}

TEST(TwoStep, ComposedProgramFeedsTheFirstExpression) {
  const Table t = twoOutputs(8);
  Program first;  // B ~ x*x + 0.01
  first.code.push_back(Instr{Op::Mad, {inputOperand(0), inputOperand(0), constOperand(0)}});
  first.constants = {0.01f};
  first.outputs = {0};
  Program rest;  // A ~ B_fit + y (input 2 is B_fit)
  rest.code.push_back(Instr{Op::Mul, {inputOperand(1), constOperand(0)}});
  rest.code.push_back(Instr{Op::Add, {regOperand(0), inputOperand(2)}});
  rest.constants = {2.0f};
  rest.outputs = {1};
  const Program both = composeTwoStep(first, rest, 2, /*first_index=*/1);
  ASSERT_EQ(both.outputs.size(), 2u);
  // Output 1 (B) is first's value; output 0 (A) is rest over the extended table.
  const auto b = evalOutput(first, t, 0);
  EXPECT_EQ(evalOutput(both, t, 1), b);
  Table ext = t;
  ext.input_names.push_back("B_fit");
  ext.inputs.push_back(std::vector<double>(b.begin(), b.end()));
  ext.output_names = {"A"};
  ext.outputs = {t.outputs[0]};
  EXPECT_EQ(evalOutput(both, t, 0), evalOutput(rest, ext, 0));
  // Its cost counts first's opcodes once: first's plus rest's.
  const CostModel gen = CostModel::preset(CostTarget::GpuGeneric);
  EXPECT_DOUBLE_EQ(gen.programCost(both), gen.programCost(first) + gen.programCost(rest));
}

TEST(TwoStep, RunPicksFeedsAndAssembles) {
  RunConfig c;
  c.data.path = "in-memory";
  c.data.outputs = {"A", "B"};
  c.search.population = 60;
  c.search.generations = 10;
  c.search.threads = 2;
  c.program.max_length = 10;
  c.search.multi_output.mode = MultiOutputMode::TwoStep;
  c.search.multi_output.first = "B";
  ASSERT_TRUE(c.validate()) << c.validate().message();
  const Table t = twoOutputs(10);
  TwoStepSearch ts(c, t);
  ts.run();
  // Step 2's table has the pick's float32 values as its extra input.
  const Table& t2 = ts.secondTable();
  ASSERT_EQ(t2.input_names.back(), "B_fit");
  EXPECT_EQ(t2.output_names, std::vector<std::string>{"A"});
  Table t1 = t;
  t1.output_names = {"B"};
  t1.outputs = {t.outputs[1]};
  const auto picked = evalOutput(ts.pick(), t1, 0);
  for (size_t r = 0; r < t.rows(); ++r) ASSERT_EQ(t2.inputs.back()[r], picked[r]);
  // Every assembled member computes B as the pick does.
  const auto front = ts.result().front();
  ASSERT_FALSE(front.empty());
  for (const auto& m : front) {
    ASSERT_EQ(m.program.outputs.size(), 2u);
    EXPECT_EQ(evalOutput(m.program, t, 1), picked);
  }
  EXPECT_EQ(ts.result().progress().generation, 10);  // 4 + 6 generations (first_share 0.4)
  EXPECT_NE(ts.result().progress().stop_reason.find("step 2"), std::string::npos);
  const auto j = frontToJson(ts.result(), front);
  EXPECT_EQ(j["table"]["outputs"], nlohmann::json({"A", "B"}));
}

TEST(TwoStep, ConfigIsValidated) {
  nlohmann::json j = {{"data", {{"path", "t.csv"}, {"outputs", {"A", "B"}}}},
                      {"search", {{"multi_output", {{"mode", "two_step"}, {"first", "C"}}}}}};
  auto c = parseRunConfig(j, ".");
  ASSERT_FALSE(c);
  EXPECT_NE(c.error().find("/search/multi_output/first"), std::string::npos) << c.error();
  j["search"]["multi_output"]["first"] = "B";
  EXPECT_TRUE(parseRunConfig(j, "."));
  j["search"]["multi_output"]["mode"] = "both";
  c = parseRunConfig(j, ".");
  ASSERT_FALSE(c);
  EXPECT_NE(c.error().find("/search/multi_output/mode"), std::string::npos);
  j["search"]["multi_output"] = {{"mode", "two_step"}, {"first", "B"}, {"first_share", 1.0}};
  EXPECT_FALSE(parseRunConfig(j, "."));
  j["search"] = {{"refine", {{"method", "de+nm"}, {"de_evaluations", 50}}}};
  c = parseRunConfig(j, ".");
  ASSERT_TRUE(c) << c.error();
  EXPECT_EQ(c->search.refine.method, RefineMethod::DeThenNm);
  j["search"] = {{"refine", {{"method", "bfgs"}}}};
  EXPECT_FALSE(parseRunConfig(j, "."));
}

TEST(Refine, DifferentialEvolutionThenNelderMeadIsDeterministic) {
  RunConfig c;
  c.data.path = "in-memory";
  c.data.outputs = {"A", "B"};
  c.search.population = 40;
  c.search.generations = 6;
  c.search.threads = 2;
  c.search.refine.archive_period = 2;
  c.search.refine.method = RefineMethod::DeThenNm;
  c.search.refine.de_evaluations = 60;
  Search a(c, twoOutputs(8)), b(c, twoOutputs(8));
  a.run();
  b.run();
  EXPECT_EQ(frontToJson(a, a.front())["members"], frontToJson(b, b.front())["members"]);
}

}  // namespace
}  // namespace lgp
