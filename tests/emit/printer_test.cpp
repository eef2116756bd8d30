// Golden tests of the formula printer (lgp/core/formula.hpp): programs and the text the front,
// `lgp front`, `lgp score` and the emitters show for them. Every case is also checked by
// evaluation: the printed formula, parsed back with the emit parser, computes the same float32
// values as the program on every row of the domain grid, bit for bit (the simplifier's bound,
// expr.hpp), or within the pow error where a pow rewrite applies.
#include <gtest/gtest.h>

#include <cmath>
#include <regex>

#include "emit_test_util.hpp"
#include "lgp/core/formula.hpp"
#include "lgp/emit/emit.hpp"
#include "lgp/emit/parser.hpp"
#include "lgp/eval/interpreter.hpp"

namespace lgp::emit {
namespace {

struct Case {
  std::string program;  // parser syntax, read without mad fusion (one opcode per call)
  std::string expected;
  std::vector<Interval> domain = {};  // mu, r
  double max_ulp = 0;            // 0: bit-identical
};

const Interval kUnit{0.015625, 0.984375, false};  // the quickstart table's mu and r

// The program a text stands for, opcode for opcode (only constant-only calls are folded).
Program rawProgram(const std::string& text, const std::vector<std::string>& outs) {
  ParseOptions o;
  o.input_names = {"mu", "r"};
  o.output_names = outs;
  o.fuse_mad = false;
  auto pf = parseFormula({text}, o);
  EXPECT_TRUE(pf.hasValue()) << pf.error() << ": " << text;
  return pf ? pf->program : Program{};
}

// A grid over the domain, corners included.
Table grid(const std::vector<Interval>& dom, size_t k) {
  Table t;
  t.input_names = {"mu", "r"};
  t.inputs.resize(2);
  const int n = 17;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      t.inputs[0].push_back(dom[0].lo + (dom[0].hi - dom[0].lo) * i / (n - 1));
      t.inputs[1].push_back(dom[1].lo + (dom[1].hi - dom[1].lo) * j / (n - 1));
    }
  for (size_t o = 0; o < k; ++o) {
    t.output_names.push_back(k == 1 ? "B" : std::string(1, static_cast<char>('A' + o)));
    t.outputs.push_back(std::vector<double>(t.rows(), 0.0));
  }
  return t;
}

// Prints the program, parses the text back and compares values on the grid.
void check(const Case& c, const std::vector<std::string>& outs = {"B"}) {
  SCOPED_TRACE(c.program);
  const Program p = rawProgram(c.program, outs);
  const std::vector<Interval> dom = c.domain.empty() ? std::vector{kUnit, kUnit} : c.domain;
  const std::string text = programFormula(p, {"mu", "r"}, outs, dom);
  EXPECT_EQ(text, c.expected);
  // Never a double negation, a parenthesised negative literal or a chained assignment.
  EXPECT_FALSE(std::regex_search(text, std::regex(R"(-\(-|--|\(-[0-9.e+-]+\)|= \w+ =)"))) << text;
  ParseOptions po;
  po.input_names = {"mu", "r"};
  po.output_names = outs;
  auto back = parseFormula({text}, po);
  ASSERT_TRUE(back.hasValue()) << back.error() << ": " << text;
  const Table t = grid(dom, outs.size());
  const Dataset ds(t, 256);
  Interpreter interp(256);
  const auto a = interp.evaluate(p, ds);
  const auto b = interp.evaluate(back->program, ds);
  for (size_t j = 0; j < outs.size(); ++j)
    for (size_t r = 0; r < t.rows(); ++r)
      ASSERT_LE(test::ulpDistance(a[j][r], b[j][r]), c.max_ulp)
          << "output " << j << " row " << r << ": " << a[j][r] << " vs " << b[j][r];
}

TEST(Printer, TheQuickstartMember) {
  // What the quickstart front printed as exp2((-(-mad((-7), mu, mad((-4), square(r),
  // 1.0195341e-08))))): double negation gone, signs in the constants, mad as a*b + c.
  check({"exp2(-(-mad(-7, mu, mad(-4, square(r), 0))))", "B = exp2(-7*mu - 4*r^2)"});
  check({"exp2(-(-mad(-7, mu, mad(-4, square(r), 1.0195341e-08))))",
         "B = exp2(1.0195341e-08 - 4*r^2 - 7*mu)"});  // a + (b + c) written b + c + a
}

TEST(Printer, NegationsAndSigns) {
  check({"neg(neg(neg(r)))", "B = -r"});
  check({"mul(-7, mu)", "B = -7*mu"});
  check({"mul(mu, -7)", "B = -7*mu"});
  check({"add(mu, mul(-0.5, r))", "B = mu - 0.5*r"});
  check({"add(mul(-0.5, r), 1)", "B = 1 - 0.5*r"});
  check({"sub(mu, neg(r))", "B = mu + r"});
  check({"neg(add(mu, r))", "B = -(mu + r)"});
  check({"neg(sub(mu, r))", "B = -(mu - r)"});
  check({"mul(neg(mu), neg(r))", "B = mu*r"});
  check({"div(neg(mu), r)", "B = -mu/r"});
  check({"rcp(neg(mu))", "B = -1/mu"});
  check({"square(neg(mu))", "B = mu^2"});
  check({"abs(neg(mu))", "B = mu"});  // abs(-mu) = abs(mu) = mu on the domain
}

TEST(Printer, PrecedenceNeedsNoMoreParenthesesThanItMust) {
  check({"mad(mu, r, 0.5)", "B = mu*r + 0.5"});
  check({"mul(add(mu, r), sub(mu, r))", "B = (mu + r)*(mu - r)"});
  check({"sub(mu, sub(r, 1))", "B = mu - (r - 1)"});
  check({"sub(sub(mu, r), 1)", "B = mu - r - 1"});
  check({"add(mu, add(r, 1))", "B = r + 1 + mu"});
  check({"add(add(mu, r), add(r, 1))", "B = mu + r + (r + 1)"});
  check({"div(mu, add(r, 1))", "B = mu/(r + 1)"});
  check({"div(mul(mu, r), mul(r, 3))", "B = mu*r/(3*r)"});
  check({"mul(mu, mul(r, 3))", "B = 3*r*mu"});
  check({"rcp(mu)", "B = 1/mu"});
  check({"mul(2, rcp(mu))", "B = 2*(1/mu)"});
  check({"mul(square(mu), mu)", "B = mu^3"});
  check({"mul(add(mu, r), add(mu, r))", "B = (mu + r)^2"});  // x*x
  check({"mad(add(mu, r), add(mu, r), 1)", "B = (mu + r)^2 + 1"});
  check({"square(square(add(mu, r)))", "B = (mu + r)^4"});
  check({"square(mul(mu, r))", "B = (mu*r)^2"});
  check({"exp2(mul(-2, square(add(mu, r))))", "B = exp2(-2*(mu + r)^2)"});
  check({"add(sqrt(mu), log2(r))", "B = sqrt(mu) + log2(r)"});
  check({"lerp(mu, r, 0.25)", "B = lerp(mu, r, 0.25)"});
  check({"mul(0.33333334, mu)", "B = 1/3*mu"});  // exactly float(1/3)
  check({"mul(mu, 0.33333334)", "B = 1/3*mu"});
  check({"mul(mul(mu, r), 0.33333334)", "B = 1/3*(mu*r)"});
}

TEST(Printer, SelectAndPiecewise) {
  check({"select(mu, r, mul(mu, 2), r)", "B = mu > r ? 2*mu : r"});
  check({"add(select(mu, r, mu, r), 1)", "B = (mu > r ? mu : r) + 1"});
  check({"max(mu, r)", "B = max(mu, r)"});
  check({"max(mul(mu, 0.5), mul(mu, 0.5))", "B = 0.5*mu"});  // no max(c, c)
  check({"min(mu, add(r, 2))", "B = mu"});                   // r + 2 > mu on the domain
  check({"abs(mad(mu, 0.608, 0.608))", "B = 0.608*mu + 0.608"});
  check({"saturate(mul(mu, 0.5))", "B = 0.5*mu"});
  check({"saturate(sub(mu, r))", "B = saturate(mu - r)"});
  const std::vector<Interval> apart = {Interval{0.6, 1, false}, Interval{0, 0.5, false}};
  check({"select(mu, r, mul(mu, 2), r)", "B = 2*mu", apart});
  check({"select(r, mu, mul(mu, 2), r)", "B = r", apart});
}

TEST(Printer, SharedSubexpressionsBecomeTemporaries) {
  check({"t = exp2(mul(mu, 2.5)); sub(t, mul(t, t))", "t0 = exp2(2.5*mu); B = t0 - t0^2"});
  // A negated leaf is inlined, however often it is used.
  check({"n = neg(mu); add(mul(n, r), exp2(n))", "B = exp2(-mu) - mu*r"});
}

TEST(Printer, MultiOutputHasTemporariesFirstAndNoChainedAssignment) {
  const Case c{
      "m = mul(r, r); e = exp2(neg(mad(7, mu, mul(4, m))));"
      "A = sub(sub(1, e), mul(m, max(e, sub(min(r, mad(0.323, mu, 0.739)), 0.434)))); B = e",
      "t0 = r^2; t1 = exp2(-(7*mu + 4*t0)); A = 1 - t1 - t0*max(t1, min(r, 0.323*mu + 0.739) - "
      "0.434); B = t1"};
  check(c, {"A", "B"});
  // One output is the other's sub-expression; two outputs that are one node.
  check({"A = exp2(mu); B = mul(A, 2)", "t0 = exp2(mu); A = t0; B = 2*t0"}, {"A", "B"});
  check({"A = add(mu, r); B = A", "t0 = mu + r; A = t0; B = t0"}, {"A", "B"});
}

TEST(Printer, PowRewritesStayWithinThePowError) {
  // pow(x, 2) -> x^2 where x >= 0: the interpreter's pow is exp2(2*log2(x)), a few ulp off
  // (64 ulp is the bound emit/README.md asserts for native math).
  check({"pow(mu, 2)", "B = mu^2", {}, 64});
  check({"pow(add(mu, r), 0.5)", "B = sqrt(mu + r)", {}, 64});
}

TEST(Printer, OutputsStandAloneAndEmitterCommentsShowTheSameFormula) {
  const Program p = rawProgram("A = exp2(mul(mu, -2)); B = add(A, mul(A, r))", {"A", "B"});
  const Dag d = formulaDag(p, 2, {kUnit, kUnit});
  const auto texts = printOutputs(d, {"mu", "r"});
  ASSERT_EQ(texts.size(), 2u);
  EXPECT_EQ(texts[0], "exp2(-2*mu)");
  EXPECT_EQ(texts[1], "t0 = exp2(-2*mu); t0 + t0*r");
  EmitInput in;
  in.program = p;
  in.input_names = {"mu", "r"};
  in.output_names = {"A", "B"};
  in.domain = {kUnit, kUnit};
  auto e = emitProgram(in, Language::Hlsl, EmitOptions{});
  ASSERT_TRUE(e.hasValue()) << e.error();
  const std::string f = programFormula(p, {"mu", "r"}, {"A", "B"}, {kUnit, kUnit});
  EXPECT_EQ(e->formula, f);
  EXPECT_NE(e->code.find("// Formula: " + f + "\n"), std::string::npos) << e->code;
}

}  // namespace
}  // namespace lgp::emit
