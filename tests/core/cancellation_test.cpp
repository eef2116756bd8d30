// The cancellation flag (lgp/core/cancellation.hpp): constants that cancel are flagged, a
// benign formula is not, and the front JSON carries the estimate where the page reads it
// (with the member's formula and a discontinuity that matches its constants).
#include <gtest/gtest.h>

#include "lgp/core/cancellation.hpp"
#include "lgp/core/formula.hpp"
#include "lgp/io/result.hpp"
#include "lgp/search/search.hpp"
#include "test_tables.hpp"

namespace lgp {
namespace {

constexpr auto X = inputOperand;
constexpr auto C = constOperand;
constexpr auto R = regOperand;

Table line(int n) {
  Table t;
  t.input_names = {"x"};
  t.output_names = {"y"};
  t.inputs.resize(1);
  t.outputs.resize(1);
  for (int i = 0; i < n; ++i) {
    t.inputs[0].push_back(i / (n - 1.0));
    t.outputs[0].push_back(0.0);
  }
  return t;
}

Cancellation of(const Program& p, const Table& t, const std::vector<TargetTransform>& tr = {}) {
  return cancellation(formulaDag(p, static_cast<int>(t.numInputs()), tableDomain(t)), t, tr);
}

// mad(mad(x, 1.3, 19659.578), 0.877, -17244.156): two terms near 17244 that cancel to a
// result of about -2.7 + 1.1 x.
Program cancelling() {
  Program p;
  p.code = {Instr{Op::Mad, {X(0), C(0), C(1)}}, Instr{Op::Mad, {R(0), C(2), C(3)}}};
  p.constants = {1.3f, 19659.578f, 0.877f, -17244.156f};
  p.outputs = {1};
  return p;
}

TEST(Cancellation, CancellingConstantsAreFlagged) {
  const auto c = of(cancelling(), line(101));
  EXPECT_GT(c.bits_lost, 12);  // ~4 * 17244 / 2.7: about 14.6 bits
  EXPECT_LT(c.bits_lost, 17);
  EXPECT_TRUE(c.flagged);
  ASSERT_EQ(c.per_output.size(), 1u);
  EXPECT_EQ(c.per_output[0], c.bits_lost);
  CancellationOptions lax;
  lax.flag_bits = 20;
  EXPECT_FALSE(cancellation(buildDag(cancelling(), 1), line(101), {}, lax).flagged);
}

TEST(Cancellation, BenignFormulasAreNot) {
  // exp2(-7 x - 4 x^2 + 0.5)
  Program p;
  p.code = {Instr{Op::Square, {X(0)}}, Instr{Op::Mad, {C(1), R(0), C(2)}},
            Instr{Op::Mad, {C(0), X(0), R(1)}}, Instr{Op::Exp2, {R(2)}}};
  p.constants = {-7.0f, -4.0f, 0.5f};
  p.outputs = {3};
  const auto c = of(p, line(101));
  EXPECT_LT(c.bits_lost, 4);
  EXPECT_FALSE(c.flagged);
  // x - 0.5 crosses zero: measured against its RMS it loses almost nothing.
  Program q;
  q.code = {Instr{Op::Sub, {X(0), C(0)}}};
  q.constants = {0.5f};
  q.outputs = {0};
  EXPECT_LT(of(q, line(101)).bits_lost, 3);
  // A plain input loses nothing.
  Program id;
  id.code = {Instr{Op::Mul, {X(0), C(0)}}};
  id.constants = {1.0f};
  id.outputs = {0};
  EXPECT_EQ(of(id, line(101)).bits_lost, 0);
}

TEST(Cancellation, CarriedThroughTheInverseTransform) {
  // log transform: the result is exp(y), so absolute error in y is relative error in exp(y).
  Program p;
  p.code = {Instr{Op::Mad, {X(0), C(0), C(1)}}};
  p.constants = {30.0f, -20.0f};  // y in [-20, 10]: exp(y) amplifies y's absolute error
  p.outputs = {0};
  const auto plain = of(p, line(101));
  const auto logged = of(p, line(101), {TargetTransform::Log});
  EXPECT_GT(logged.bits_lost, plain.bits_lost);
}

TEST(Cancellation, FrontMembersCarryFormulaAndFlag) {
  RunConfig c;
  c.data.path = "in-memory";
  c.search.population = 60;
  c.search.generations = 6;
  c.search.threads = 1;
  c.search.refine.archive_period = 2;  // Nelder-Mead moves archive members' constants
  Search s(c, test::gridTable(8));
  s.run();
  const auto j = frontToJson(s, s.front());
  ASSERT_FALSE(j["members"].empty());
  DiscontinuityModel disc = DiscontinuityModel::defaults();
  disc.domain = tableDomain(s.table());
  for (size_t i = 0; i < j["members"].size(); ++i) {
    const auto& m = j["members"][i];
    // The discontinuity depends on the constants now: it is the program's own, after
    // refinement moved them.
    auto prog = memberProgram(j, i);
    ASSERT_TRUE(prog.hasValue()) << prog.error();
    EXPECT_EQ(m["discontinuity"].get<double>(), disc.programDiscontinuity(*prog)) << i;
    ASSERT_TRUE(m["formula"].is_string());
    EXPECT_NE(m["formula"].get<std::string>().find("y = "), std::string::npos);
    EXPECT_EQ(m["formula"], *memberFormula(j, i));  // recomputed from the program, the same
    ASSERT_TRUE(m["cancellation"]["bits_lost"].is_number());
    ASSERT_TRUE(m["cancellation"]["flagged"].is_boolean());
    EXPECT_EQ(m["cancellation"]["flagged"].get<bool>(),
              m["cancellation"]["bits_lost"].get<double>() > kCancellationFlagBits);
  }
}

}  // namespace
}  // namespace lgp
