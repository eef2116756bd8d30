// The scoreboard's rules (bench/scoreboard, issue 52): a published fit costs what its cheapest
// form of the same values costs, a median is the true median, the held-out set reaches the
// declared domain's edges, and a member that explodes on the domain is refused.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "board.hpp"
#include "lgp/emit/parser.hpp"
#include "report.hpp"

using namespace lgp;
using namespace lgp::board;

namespace {
Program parse(const std::string& text, std::vector<std::string> inputs = {"mu", "r"}) {
  emit::ParseOptions o;
  o.input_names = std::move(inputs);
  o.output_names = {"y"};
  auto pf = emit::parseFormula({text}, o);
  EXPECT_TRUE(pf.hasValue()) << (pf ? "" : pf.error());
  return pf->program;
}

Table grid2(int n) {
  Table t;
  t.input_names = {"mu", "r"};
  t.output_names = {"y"};
  t.inputs.assign(2, {});
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      t.inputs[0].push_back((i + 0.5) / n);
      t.inputs[1].push_back((j + 0.5) / n);
    }
  t.outputs.assign(1, std::vector<double>(t.inputs[0].size(), 0.0));
  return t;
}
}  // namespace

TEST(Scoreboard, MedianOfAnEvenCountIsTheMeanOfTheMiddleTwo) {
  EXPECT_DOUBLE_EQ(median({4, 1, 3, 2}), 2.5);
  EXPECT_DOUBLE_EQ(median({5, 1, 3}), 3.0);
  EXPECT_TRUE(std::isnan(median({})));
}

TEST(Scoreboard, AFitCostsWhatItsCheapestFormOfTheSameValuesCosts) {
  const Table t = grid2(8);
  // A monomial polynomial and its Horner form: the same values, the Horner one cheaper.
  const std::vector<Program> forms = {parse("0.5 + 0.25*mu + 0.125*mu*mu + 0.0625*mu*mu*mu"),
                                      parse("0.5 + mu*(0.25 + mu*(0.125 + mu*0.0625))")};
  auto k = cheapestForm(forms, {12, 7}, t, {"monomial", "horner"});
  ASSERT_TRUE(k.hasValue()) << k.error();
  EXPECT_EQ(*k, 1u);
  // Listed the other way round, it is still the cheaper one that counts.
  k = cheapestForm({forms[1], forms[0]}, {7, 12}, t, {"horner", "monomial"});
  ASSERT_TRUE(k.hasValue());
  EXPECT_EQ(*k, 0u);
  // An unmeasured form never wins over a measured one.
  k = cheapestForm(forms, {NAN, 9}, t, {"monomial", "horner"});
  ASSERT_TRUE(k.hasValue());
  EXPECT_EQ(*k, 1u);
}

TEST(Scoreboard, AFormThatComputesOtherValuesIsRefused) {
  const Table t = grid2(8);
  // A "cheaper form" that drops a term is another fit: it may not lend the fit its cost.
  const std::vector<Program> forms = {parse("0.5 + mu*(0.25 + mu*0.125)"), parse("0.5 + mu*0.25")};
  auto k = cheapestForm(forms, {9, 4}, t, {"full", "truncated"});
  ASSERT_FALSE(k.hasValue());
  EXPECT_NE(k.error().find("'truncated' computes other values than 'full'"), std::string::npos)
      << k.error();
}

TEST(Scoreboard, TheHeldOutSetReachesTheDeclaredEdges) {
  std::vector<double> train;
  for (int i = 1; i <= 32; ++i) train.push_back(i / 32.0);
  const auto v = heldoutAxis(train, 1e-4, 1.0, 8, 1);
  EXPECT_EQ(v.front(), 1e-4);
  EXPECT_EQ(v.back(), 1.0);
  EXPECT_TRUE(std::is_sorted(v.begin(), v.end()));
  // Geometric steps below the first training point: 2e-4 ... 0.0256 > 1/32 > 0.0128.
  for (double x = 2e-4; x < 1.0 / 32; x *= 2)
    EXPECT_TRUE(std::find(v.begin(), v.end(), x) != v.end()) << x;
  // Midpoints: none of the training values but the shared end.
  for (double x : v) {
    if (x != 1.0) {
      EXPECT_TRUE(std::find(train.begin(), train.end(), x) == train.end()) << x;
    }
  }
  EXPECT_TRUE(std::find(v.begin(), v.end(), 1.5 / 32) != v.end());
  // The same set every run, and a domain that starts at 0 gets points next to it.
  EXPECT_EQ(v, heldoutAxis(train, 1e-4, 1.0, 8, 1));
  const auto z = heldoutAxis(train, 0.0, 1.0, 0, 1);
  EXPECT_EQ(z.front(), 0.0);
  EXPECT_TRUE(std::find(z.begin(), z.end(), 1e-3) != z.end());
}

TEST(Scoreboard, AMemberThatExplodesAtGrazingAnglesIsRefused) {
  const std::vector<Interval> domain = {Interval{1e-4, 1.0, false}, Interval{0.01, 1.0, false}};
  const std::vector<std::pair<double, double>> allowed = {{-1.0, 2.0}};
  const std::vector<TargetTransform> none = {TargetTransform::None};
  // r/mu: bounded at every grid point from mu = 1/64, 100x the table's range at mu = 1e-4.
  auto c = checkOnDomain(parse("0.01*r/mu"), domain, allowed, none, 200);
  EXPECT_FALSE(c.safe);
  EXPECT_NE(c.why.find("output 0 is"), std::string::npos) << c.why;
  EXPECT_GT(c.hi, 2.0);
  // A pole inside the domain, between any grid's points.
  c = checkOnDomain(parse("0.01/(mu - 0.3001)"), domain, allowed, none, 200);
  EXPECT_FALSE(c.safe);
}

TEST(Scoreboard, ABoundedMemberIsAcceptedByProofOrBySweep) {
  const std::vector<Interval> domain = {Interval{1e-4, 1.0, false}, Interval{0.01, 1.0, false}};
  const std::vector<TargetTransform> none = {TargetTransform::None};
  // Proven: every interval of the program lies inside the allowed range.
  auto c = checkOnDomain(parse("0.5 + 0.25*mu*r"), domain, {{0.0, 1.0}}, none, 200);
  EXPECT_TRUE(c.safe) << c.why;
  EXPECT_EQ(c.method, "interval analysis");
  // mu - mu^2: its interval bound [-1, 1] is too loose for [-0.1, 0.5]; the sweep finds 0.25.
  c = checkOnDomain(parse("mu - mu*mu"), domain, {{-0.1, 0.5}}, none, 200);
  EXPECT_TRUE(c.safe) << c.why;
  EXPECT_EQ(c.method.rfind("sweep of", 0), 0u) << c.method;
  EXPECT_NEAR(c.hi, 0.25, 1e-3);
  // A member fitted through a transform is checked on the values it ships (e^y here).
  c = checkOnDomain(parse("-10*mu"), domain, {{0.0, 1.0}}, {TargetTransform::Log}, 200);
  EXPECT_TRUE(c.safe) << c.why;
  c = checkOnDomain(parse("10*mu"), domain, {{0.0, 1.0}}, {TargetTransform::Log}, 200);
  EXPECT_FALSE(c.safe);
}
