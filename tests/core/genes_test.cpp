// The linear output layer (program.genes, search-4): under linear scaling each output is
// b + sum_g a_g f_g over `genes` program results, fitted in closed form by the Scorer,
// materialised exactly by applyLinearScaling, and what a front exports.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <nlohmann/json.hpp>

#include "lgp/config/config.hpp"
#include "lgp/eval/fidelity.hpp"
#include "lgp/eval/interpreter.hpp"
#include "lgp/eval/objectives.hpp"
#include "lgp/search/search.hpp"

namespace lgp {
namespace {

// y = 0.3 + 2 x + 5 x^2 - 1.5 z on a 24 x 8 grid.
Table quadratic() {
  Table t;
  t.input_names = {"x", "z"};
  t.output_names = {"y"};
  t.inputs.resize(2);
  t.outputs.resize(1);
  for (int i = 0; i < 24; ++i)
    for (int j = 0; j < 8; ++j) {
      const double x = (i + 0.5) / 24, z = (j + 0.5) / 8;
      t.inputs[0].push_back(x);
      t.inputs[1].push_back(z);
      t.outputs[0].push_back(0.3 + 2 * x + 5 * x * x - 1.5 * z);
    }
  return t;
}

// Three genes: x, x^2 and z.
Program threeGenes() {
  Program p;
  p.code.push_back({Op::Mul, {inputOperand(0), inputOperand(0)}});
  p.code.push_back({Op::Max, {inputOperand(0), inputOperand(0)}});
  p.code.push_back({Op::Min, {inputOperand(1), inputOperand(1)}});
  p.outputs = {1, 0, 2};
  return p;
}

ErrorConfig layer(int genes) {
  ErrorConfig e;
  e.linear_scaling = true;
  e.genes = genes;
  return e;
}

TEST(Genes, LayerFitsALinearCombinationExactly) {
  const Table t = quadratic();
  const Dataset ds(t, 64);
  Scorer s(ds, layer(3), 64);
  const double e = s.error(threeGenes());
  EXPECT_LT(e, 1e-5);
  ASSERT_EQ(s.scales().size(), 3u);
  EXPECT_NEAR(s.scales()[0].a, 2.0, 1e-4);
  EXPECT_NEAR(s.scales()[0].b, 0.3, 1e-4);  // the offset sits on the lead gene
  EXPECT_NEAR(s.scales()[1].a, 5.0, 1e-4);
  EXPECT_NEAR(s.scales()[2].a, -1.5, 1e-4);

  // One gene (the first of the three) cannot: the layer is what carries the fit.
  Program one = threeGenes();
  one.outputs = {1};
  Scorer s1(ds, layer(1), 64);
  EXPECT_GT(s1.error(one), 0.1);
}

// A program with fewer results than the layer has genes is not scored (its missing outputs
// would read as 0 error).
TEST(Genes, AProgramOfAnotherShapeScoresInfinity) {
  const Table t = quadratic();
  const Dataset ds(t, 64);
  Scorer s(ds, layer(3), 64);
  Program one = threeGenes();
  one.outputs = {1};
  EXPECT_EQ(s.error(one), std::numeric_limits<double>::infinity());
  EXPECT_LT(s.error(threeGenes()), 1e-5);
}

TEST(Genes, MaterialisedLayerComputesWhatWasScored) {
  const Table t = quadratic();
  const Dataset ds(t, 64);
  Scorer s(ds, layer(3), 64);
  Program p = threeGenes();
  p.code[0] = {Op::Sqrt, {inputOperand(0)}};  // a gene that does not fit exactly
  const double e = s.error(p);
  const Program m = applyLinearScaling(p, s.scales(), 3);
  ASSERT_EQ(m.outputs.size(), 1u);
  Scorer plain(ds, ErrorConfig{}, 64);
  EXPECT_NEAR(plain.error(m), e, 1e-6 * (1 + e));
  // The layer is a closed-form fit: no gene combination with float coefficients near it
  // does better than rounding.
  EXPECT_LT(e, 0.5);
}

TEST(Genes, CollinearGenesGetZeroWeightNotNaN) {
  const Table t = quadratic();
  const Dataset ds(t, 64);
  Scorer s(ds, layer(3), 64);
  Program p = threeGenes();
  p.outputs = {1, 1, 0};  // genes 0 and 1 identical
  const double e = s.error(p);
  EXPECT_TRUE(std::isfinite(e));
  for (const auto& sc : s.scales()) EXPECT_TRUE(std::isfinite(sc.a) && std::isfinite(sc.b));
  EXPECT_EQ(s.scales()[1].a, 0.0f);
}

nlohmann::json configJson(int genes, bool scaling) {
  return {{"data", {{"path", "t.csv"}, {"outputs", {"y"}}}},
          {"program", {{"max_length", 12}, {"genes", genes}}},
          {"search",
           {{"population", 96},
            {"generations", 20},
            {"seed", 3},
            {"threads", 1},
            {"linear_scaling", scaling}}}};
}

TEST(Genes, ConfigNamesTheFieldAndItsReason) {
  auto bad = parseRunConfig(configJson(3, false), ".");
  ASSERT_FALSE(bad.hasValue());
  EXPECT_NE(bad.error().find("/program/genes"), std::string::npos) << bad.error();
  EXPECT_NE(bad.error().find("linear_scaling"), std::string::npos) << bad.error();
  auto big = parseRunConfig(configJson(17, true), ".");
  ASSERT_FALSE(big.hasValue());
  EXPECT_NE(big.error().find("/program/genes"), std::string::npos) << big.error();
  auto ok = parseRunConfig(configJson(3, true), ".");
  ASSERT_TRUE(ok.hasValue()) << ok.error();
  EXPECT_EQ(ok->shape(2, 1).num_outputs, 3);
  EXPECT_EQ(toJson(*ok)["program"]["genes"], 3);
  // One gene is the default and is not written (config digests stay as they were).
  auto one = parseRunConfig(configJson(1, true), ".");
  ASSERT_TRUE(one.hasValue());
  EXPECT_FALSE(toJson(*one)["program"].contains("genes"));
}

TEST(Genes, SearchFrontMembersExportOneOutputThatReproducesTheScoredError) {
  const Table t = quadratic();
  auto cfg = parseRunConfig(configJson(3, true), ".");
  ASSERT_TRUE(cfg.hasValue()) << cfg.error();
  Search s(*cfg, t);
  s.run();
  ASSERT_FALSE(s.front().empty());
  const double tol = fidelityTolerances(t)[0];
  double best = 1e9;
  for (const auto& e : s.front()) {
    ASSERT_EQ(e.program.outputs.size(), 1u) << e.formula;
    EXPECT_NEAR(e.metrics[0].rmse, e.metrics_ref[0].rmse, tol) << e.formula;
    EXPECT_NEAR(e.metrics[0].rmse, e.obj.error, 1e-5 * (1 + e.obj.error)) << e.formula;
    best = std::min(best, e.metrics[0].rmse);
  }
  EXPECT_LT(best, 1e-3);  // three genes make the quadratic an easy fit
}

TEST(Genes, SameSeedSameFront) {
  const Table t = quadratic();
  auto cfg = parseRunConfig(configJson(2, true), ".");
  ASSERT_TRUE(cfg.hasValue());
  std::vector<std::string> a, b;
  for (auto* out : {&a, &b}) {
    Search s(*cfg, t);
    s.run();
    for (const auto& e : s.front()) out->push_back(e.formula);
  }
  EXPECT_EQ(a, b);
}

}  // namespace
}  // namespace lgp
