// The archive takes only members whose emitted formula computes what they compute (search-4:
// "what is exported is what was scored"). Found on the sphere-light normalization table after
// 480 M evaluations: pow(c, 1) - c is 0 for the simplifier but a few float32 ulps in the
// interpreter, so rcp of it is a large constant the program scales onto the table. The formula
// the simplifier makes of such a program is a constant: its cost (0.25, taken from the
// formula) and its genuine error dominated every cheap member out of the archive, and front
// assembly then dropped it, leaving the 20-minute front without any member below cost 8.75.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "lgp/config/config.hpp"
#include "lgp/core/formula.hpp"
#include "lgp/core/interval.hpp"
#include "lgp/eval/fidelity.hpp"
#include "lgp/io/checkpoint.hpp"
#include "lgp/search/search.hpp"
#include "test_tables.hpp"

namespace lgp {
namespace {

// The normalization table's domain (r in [0.1, 1], tan(theta_s / 2) in [0, 0.6]) with a
// smooth target of that shape.
Table normalizationLike() {
  Table t = test::gridTableOf(
      16, [](double, double) { return 0.0; }, "r", "t", "N");
  for (size_t i = 0; i < t.rows(); ++i) {
    const double r = 0.1 + 0.9 * t.inputs[0][i], s = 0.6 * t.inputs[1][i];
    t.inputs[0][i] = r;
    t.inputs[1][i] = s;
    t.outputs[0][i] = r * r / (r * r + s);
  }
  return t;
}

// The archive member of that run (2 inputs, 12 constants), as the checkpoint stored it.
Program formulaExploit() {
  const nlohmann::json j = {
      {"code",
       {{"sub", "x1", "x1"},
        {"exp", "r0"},
        {"mad", "r1", "c4", "c5"},
        {"min", "c8", "r0"},
        {"pow", "r2", "r1"},
        {"mad", "c6", "x1", "c1"},
        {"mul", "x0", "x0"},
        {"mul", "c5", "x1"},
        {"mul", "x1", "x0"},
        {"mul", "r6", "r8"},
        {"mad", "r9", "r8", "r9"},
        {"lerp", "r7", "c10", "r10"},
        {"mad", "r2", "r2", "x1"},
        {"sub", "r0", "r0"},
        {"mad", "c8", "r6", "x0"},
        {"lerp", "r11", "r14", "x0"},
        {"mad", "r5", "x0", "c7"},
        {"lerp", "c3", "r8", "c3"},
        {"mad", "x1", "c2", "r14"},
        {"add", "r18", "r16"},
        {"sqrt", "r19"},
        {"sqrt", "r15"},
        {"sqrt", "r21"},
        {"mad", "r17", "r6", "r3"},
        {"lerp", "r22", "r20", "c7"},
        {"sub", "r4", "r2"},
        {"rcp", "r25"},
        {"lerp", "r23", "r24", "r26"},
        {"add", "x0", "r27"},
        {"mul", "c0", "r1"},
        {"mad", "r28", "r25", "c0"},
        {"sub", "r30", "c5"}}},
      {"constants",
       {0.585868775844574, 0.5306891202926636, 31.03387451171875, 1.3819520473480225,
        118.44091033935547, 125.14290618896484, -39.72187042236328, -0.7507426142692566,
        22.625667572021484, -1.37728750705719, 66.4438705444336, -1.8350532054901123}},
      {"outputs", {31}}};
  ProgramShape shape;
  shape.num_inputs = 2;
  shape.max_length = 32;
  shape.num_constants = 12;
  auto p = programFromJson(j, shape);
  EXPECT_TRUE(p.hasValue()) << p.error();
  return *p;
}

TEST(ArchiveFormula, TheExploitsFormulaIsAConstantThatDoesNotReproduceIt) {
  const Table t = normalizationLike();
  const Program p = formulaExploit();
  const Dataset ds(t, 64);
  const Dag d = formulaDag(p, 2, tableDomain(t));
  const auto f = toProgram(d);
  ASSERT_TRUE(f.hasValue());
  EXPECT_EQ(printOutputs(d, t.input_names)[0].find_first_of("rt"), std::string::npos)
      << "the simplified formula reads no input: " << printOutputs(d, t.input_names)[0];
  EXPECT_GT(valueDeviation(p, f->program, ds, {}, fidelityTolerances(t)), 1.0);
}

// Seeded with the exploit, the archive never holds a member whose formula does not reproduce
// it, and the front keeps its cheap end (a constant, at cost 0.25).
TEST(ArchiveFormula, OnlyMembersWhoseFormulaReproducesThemAreArchived) {
  const Table t = normalizationLike();
  const nlohmann::json cj = {{"data", {{"path", "n.csv"}}},
                             {"program", {{"max_length", 32}, {"constants", 12}}},
                             {"search",
                              {{"population", 96},
                               {"generations", 10},
                               {"seed", 1},
                               {"threads", 1},
                               {"linear_scaling", true}}}};
  auto cfg = parseRunConfig(cj, ".");
  ASSERT_TRUE(cfg.hasValue()) << cfg.error();
  Search s(*cfg, t);
  s.addSeeds({{"exploit", formulaExploit()}});
  s.run();
  const nlohmann::json ck = checkpointToJson(s);
  const Dataset ds(t, 64);
  const auto tol = fidelityTolerances(t);
  const auto domain = tableDomain(t);
  ProgramShape shape = cfg->shape(2, 1);
  ASSERT_FALSE(ck["archive"].empty());
  for (const auto& m : ck["archive"]) {
    auto p = programFromJson(m["program"], shape);
    ASSERT_TRUE(p.hasValue()) << p.error();
    Scorer sc(
        ds,
        [] {
          ErrorConfig e;
          e.linear_scaling = true;
          return e;
        }(),
        64);
    sc.error(*p);
    const Program fp = applyLinearScaling(pruneIntrons(*p), sc.scales());
    const auto f = toProgram(formulaDag(fp, 2, domain));
    ASSERT_TRUE(f.hasValue());
    EXPECT_LE(valueDeviation(fp, f->program, ds, {}, tol), 1.0) << m["program"].dump();
  }
  const auto front = s.front();
  ASSERT_FALSE(front.empty());
  EXPECT_LE(front.front().obj.cost, 0.25) << front.front().formula;
}

}  // namespace
}  // namespace lgp
