// Multi-output fronts (error channels, linear scaling) evaluate, emit and score consistently,
// and reference refits are honest.
#include <gtest/gtest.h>

#include <cmath>

#include "lgp/emit/dag.hpp"
#include "lgp/emit/emit.hpp"
#include "lgp/emit/parser.hpp"
#include "lgp/emit/score.hpp"
#include "lgp/io/result.hpp"
#include "lgp/search/search.hpp"

namespace lgp::emit {
namespace {

Table dfgLike(int n) {
  Table t;
  t.input_names = {"mu", "r"};
  t.output_names = {"A", "B"};
  t.inputs.resize(2);
  t.outputs.resize(2);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      const double mu = (i + 1.0) / n, r = j / (n - 1.0);
      const double b = std::exp2(-(7 * mu + 4 * r * r));
      t.inputs[0].push_back(mu);
      t.inputs[1].push_back(r);
      t.outputs[0].push_back(1 - b - 0.3 * r * r * mu);
      t.outputs[1].push_back(b);
    }
  return t;
}

RunConfig channelRun() {
  RunConfig c;
  c.data.path = "in-memory";
  c.data.outputs = {"A", "B"};
  c.search.population = 80;
  c.search.generations = 8;
  c.search.threads = 2;
  c.search.linear_scaling = true;
  c.program.max_length = 16;
  c.program.output_mode = OutputMode::Designated;
  c.objectives.channels = {{"F0=1", {{"A", 1.0}, {"B", 1.0}}},
                           {"F0=0.04", {{"A", 0.04}, {"B", 1.0}}}};
  return c;
}

TEST(MultiOutput, FrontMembersEmitAndScoreAsSearched) {
  const Table t = dfgLike(12);
  const RunConfig c = channelRun();
  Search s(c, t);
  s.run();
  const auto front = frontToJson(s, s.front());
  ASSERT_GT(front["members"].size(), 2u);
  ScoreOptions so;
  so.error = c.errorConfig(t.output_names);
  so.cost = c.costModel();
  for (size_t i = 0; i < front["members"].size(); ++i) {
    const auto& m = front["members"][i];
    auto prog = memberProgram(front, i);
    ASSERT_TRUE(prog) << prog.error();
    // Scoring the exported program reproduces the searched error, cost and channel metrics.
    auto sc = scoreProgram(*prog, t, so, {});
    ASSERT_TRUE(sc) << sc.error();
    EXPECT_DOUBLE_EQ((*sc)["error"].get<double>(), m["error"].get<double>()) << i;
    EXPECT_DOUBLE_EQ((*sc)["cost"].get<double>(), m["cost"].get<double>()) << i;
    ASSERT_EQ((*sc)["channels"].size(), 2u);
    EXPECT_EQ((*sc)["channels"][0]["float32"], m["channels"][0]["float32"]) << i;
    // The emitted function computes both outputs as the interpreter does (bit-identical DAG
    // evaluation in float), and the printed infix parses back to the same values.
    auto em = emitInputFromFront(front, i);
    ASSERT_TRUE(em) << em.error();
    auto hlsl = emitProgram(*em, Language::Hlsl, EmitOptions{});
    ASSERT_TRUE(hlsl) << hlsl.error();
    EXPECT_NE(hlsl->code.find("A"), std::string::npos);
    ParseOptions po;
    po.input_names = t.input_names;
    po.output_names = t.output_names;
    std::vector<std::string> texts;
    for (const auto& o : m["outputs"]) texts.push_back(o["expression"]);
    auto parsed = parseFormula(texts, po);
    ASSERT_TRUE(parsed) << parsed.error() << " in " << texts[0] << " / " << texts[1];
    const Dag d = buildDag(*prog, 2);
    for (size_t r = 0; r < t.rows(); r += 17) {
      const double in[2] = {t.inputs[0][r], t.inputs[1][r]};
      const auto a = evaluateRow(d, in, Precision::Float);
      const auto b = evaluateRow(hlsl->dag, in, Precision::Float);
      const auto p = evaluateRow(parsed->dag, in, Precision::Float);
      for (int o = 0; o < 2; ++o) {
        EXPECT_EQ(a[o], b[o]) << "member " << i << " row " << r;
        EXPECT_NEAR(a[o], p[o], 1e-6 * (1 + std::fabs(a[o]))) << "member " << i << " row " << r;
      }
    }
  }
}

TEST(MultiOutput, RefitNeverWorsensAndIsListedBesideThePublishedForm) {
  const Table t = dfgLike(12);
  RunConfig c = channelRun();
  c.references = {{{"name", "I&P detuned"},
                   {"aliases", {{"NoV", "mu"}}},
                   {"refit", true},
                   {"expr", "m = r*r; B = exp2(-(5*NoV + 3*m)); A = 1 - B - 0.1*m*NoV"}}};
  const auto refs = scoreReferences(c, t);
  ASSERT_EQ(refs.size(), 2u) << refs.dump();
  EXPECT_EQ(refs[1]["name"], "I&P detuned (refit)");
  EXPECT_EQ(refs[1]["refit_of"], "I&P detuned");
  const double e0 = refs[0]["error"], e1 = refs[1]["error"];
  EXPECT_LT(e1, 0.2 * e0);  // the structure is right: refitting recovers most of the error
  EXPECT_EQ(refs[0]["cost"], refs[1]["cost"]);
  ASSERT_TRUE(refs[1].contains("channels"));
  // A reference without refit gets no second entry; a non-boolean refit is rejected.
  c.references[0]["refit"] = false;
  EXPECT_EQ(scoreReferences(c, t).size(), 1u);
  c.references[0]["refit"] = "yes";
  auto bad = parseReferences(c.references);
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.error().find("/references/0/refit"), std::string::npos);
}

TEST(MultiOutput, ReferencesSeedARun) {
  const Table t = dfgLike(10);
  RunConfig c = channelRun();
  c.search.linear_scaling = false;
  c.search.seed_references = true;
  c.search.generations = 1;
  c.references = {{{"name", "exact-ish"},
                   {"aliases", {{"NoV", "mu"}}},
                   {"expr", "m = r*r; B = exp2(-(7*NoV + 4*m)); A = 1 - B - 0.3*m*NoV"}}};
  auto progs = referencePrograms(c, t);
  ASSERT_TRUE(progs) << progs.error();
  ASSERT_EQ(progs->size(), 1u);
  Search s(c, t);
  EXPECT_TRUE(s.addSeeds(*progs).empty());
  s.initialize();
  EXPECT_LT(s.progress().best_error, 1e-5);
}

}  // namespace
}  // namespace lgp::emit
