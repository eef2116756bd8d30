// Parser: syntax and meaning, error messages, emit -> parse -> emit fixed points, and the
// published DFG formulas (docs/published.md) parsing and scoring on the DFG table.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <functional>
#include <regex>

#include "emit_test_util.hpp"
#include "lgp/emit/emit.hpp"
#include "lgp/emit/parser.hpp"
#include "lgp/emit/score.hpp"
#include "lgp/eval/interpreter.hpp"

namespace lgp::emit {
namespace {

ParseOptions xy(std::vector<std::string> outs = {"y0"}) {
  ParseOptions o;
  o.input_names = {"x", "y"};
  o.output_names = std::move(outs);
  return o;
}

// The parsed DAG, node for node, in the function-call spelling of ops.hpp (`infix` column),
// fully parenthesised: what these tests check is the structure the parser builds (a fused
// mad, a mul then an add), which the readable printer deliberately writes alike. Nodes used
// twice are bound as tN in front of the output that first needs them.
std::vector<std::string> structureOf(const Dag& d, const std::vector<std::string>& names) {
  const auto uses = d.useCounts();
  std::vector<std::string> name(d.nodes.size());
  int counter = 0;
  std::string lets;
  std::function<std::string(int)> render = [&](int id) -> std::string {
    const Node& n = d.nodes[id];
    if (n.kind == Node::Kind::Var)
      return n.index < static_cast<int>(names.size()) ? names[n.index]
                                                      : "x" + std::to_string(n.index);
    if (n.kind == Node::Kind::Const) return formatFloat(static_cast<float>(n.value));
    if (!name[id].empty()) return name[id];
    std::vector<std::string> a(kMaxArity);
    for (int k = 0; k < arity(n.op); ++k) a[k] = render(n.args[k]);
    const std::string e = fillOpTemplate(opInfo(n.op).infix, a);
    if (uses[id] < 2) return e;
    name[id] = "t" + std::to_string(counter++);
    lets += name[id] + " = " + e + "; ";
    return name[id];
  };
  std::vector<std::string> out;
  for (int o : d.outputs) {
    lets.clear();
    const std::string e = render(o);
    out.push_back(lets + e);
  }
  return out;
}

std::vector<std::string> infixOf(const std::vector<std::string>& texts, const ParseOptions& o) {
  auto pf = parseFormula(texts, o);
  EXPECT_TRUE(pf.hasValue()) << pf.error();
  return pf ? structureOf(pf->dag, o.input_names) : std::vector<std::string>{};
}
// What the parser reports as the formula's printed text (the front printer).
std::vector<std::string> printedOf(const std::vector<std::string>& texts, const ParseOptions& o) {
  auto pf = parseFormula(texts, o);
  EXPECT_TRUE(pf.hasValue()) << pf.error();
  return pf ? pf->infix : std::vector<std::string>{};
}
std::string infix1(const std::string& text) {
  return infixOf({text}, xy())[0];
}

std::string parseError(const std::vector<std::string>& texts, const ParseOptions& o) {
  auto pf = parseFormula(texts, o);
  EXPECT_FALSE(pf.hasValue());
  return pf ? "" : pf.error();
}

TEST(EmitParser, OperatorsAndPrecedence) {
  EXPECT_EQ(infix1("x + y * 2"), "mad(y, 2, x)");  // unparenthesised product fuses
  EXPECT_EQ(infix1("x * y + 2"), "mad(x, y, 2)");
  EXPECT_EQ(infix1("(x * y) + 2"), "((x * y) + 2)");  // parenthesised: mul then add
  EXPECT_EQ(infix1("x - y * 2"), "(x - (y * 2))");    // no fusion for '-'
  EXPECT_EQ(infix1("-x * y"), "((-x) * y)");
  EXPECT_EQ(infix1("-2.5 * x"), "(-2.5 * x)");  // negative literal folded
  EXPECT_EQ(infix1("1 / x"), "rcp(x)");         // identical semantics, cheaper
  EXPECT_EQ(infix1("2 / x"), "(2 / x)");
  EXPECT_EQ(infix1("x^2 + y^3"), "(square(x) + (square(y) * y))");
  EXPECT_EQ(infix1("x^0.7"), "pow(x, 0.7)");
  EXPECT_EQ(infix1("2 * 3 + x"), "(6 + x)");  // constant folding
  EXPECT_EQ(infix1("x > y ? x : 2"), "select(x, y, x, 2)");
  EXPECT_EQ(infix1("x < y ? x : 2"), "select(y, x, x, 2)");
  EXPECT_EQ(infix1("((x > y) ? x : 2)"), "select(x, y, x, 2)");
  EXPECT_EQ(infix1("clamp(x, 0, 1) + clamp(y, -1, 2)"), "(saturate(x) + min(max(y, -1), 2))");
  EXPECT_EQ(infix1("std::exp2(x) + lgp_div(x, y) + fabs(y)"), "((exp2(x) + (x / y)) + abs(y))");
  EXPECT_EQ(infix1("mix(x, y, 0.5) + inversesqrt(x) + fma(x, y, 1.0f)"),
            "((lerp(x, y, 0.5) + rsqrt(x)) + mad(x, y, 1))");
  EXPECT_EQ(infix1("x0 * x1"), "(x * y)");  // positional names
  EXPECT_EQ(infix1("m = x*x; // comment\n m + m /* c */"), "t0 = (x * x); (t0 + t0)");
  EXPECT_EQ(infix1("float t = x;\nconst float u = t * 2.0f;\nreturn u"), "(x * 2)");
}

TEST(EmitParser, NewlinesContinueAfterAnOperator) {
  EXPECT_EQ(infix1("a = x +\n y\n a * 3"), "((x + y) * 3)");
  EXPECT_EQ(infix1("a = (x\n + y)\n a"), "(x + y)");
}

TEST(EmitParser, OutputsByPositionByNameAndVector) {
  const auto o = xy({"A", "B"});
  EXPECT_EQ(infixOf({"x + 1", "y * 2"}, o), (std::vector<std::string>{"(x + 1)", "(y * 2)"}));
  // Named in swapped order: matched by name.
  EXPECT_EQ(infixOf({"B = y * 2", "A = x + 1"}, o),
            (std::vector<std::string>{"(x + 1)", "(y * 2)"}));
  EXPECT_EQ(infixOf({"B = y * 2; A = x + B"}, o),
            (std::vector<std::string>{"t0 = (y * 2); (x + t0)", "t0"}));
  EXPECT_EQ(infixOf({"t = x * y; return float2(t, t + 1)"}, o),
            (std::vector<std::string>{"t0 = (x * y); t0", "(t0 + 1)"}));
  EXPECT_EQ(infixOf({"x; y"}, o), (std::vector<std::string>{"x", "y"}));
  // Later texts see earlier names.
  EXPECT_EQ(infixOf({"s = x + y; s * s", "s - 1"}, o),
            (std::vector<std::string>{"t0 = (x + y); (t0 * t0)", "(t0 - 1)"}));
}

TEST(EmitParser, AliasesMapFormulaNamesToTableInputs) {
  ParseOptions o;
  o.input_names = {"mu", "rough"};
  o.output_names = {"y"};
  o.aliases = {{"NoV", "mu"}, {"r", "rough"}};
  EXPECT_EQ(infixOf({"NoV * r"}, o)[0], "(mu * rough)");
  o.aliases = {{"NoV", "nope"}};
  EXPECT_NE(parseError({"NoV"}, o).find("alias NoV=nope: 'nope' is not a table input"),
            std::string::npos);
}

TEST(EmitParser, ErrorsSayWhatAndWhere) {
  EXPECT_NE(parseError({"x + foo"}, xy()).find("column 5: unknown name 'foo' (table inputs: x, y"),
            std::string::npos);
  EXPECT_NE(parseError({"min(x)"}, xy()).find("'min' takes 2 arguments, got 1"), std::string::npos);
  EXPECT_NE(parseError({"frob(x)"}, xy()).find("unknown function 'frob'"), std::string::npos);
  EXPECT_NE(parseError({"x + "}, xy()).find("unexpected end of formula"), std::string::npos);
  EXPECT_NE(parseError({"(x + y"}, xy()).find("expected ')'"), std::string::npos);
  EXPECT_NE(parseError({"x y"}, xy()).find("expected ';' or the end"), std::string::npos);
  EXPECT_NE(parseError({"x $ y"}, xy()).find("unexpected character '$'"), std::string::npos);
  EXPECT_NE(parseError({"x = 2"}, xy()).find("cannot assign to the input 'x'"), std::string::npos);
  EXPECT_NE(parseError({"x > y"}, xy()).find("followed by '? a : b'"), std::string::npos);
  EXPECT_NE(parseError({""}, xy()).find("empty formula"), std::string::npos);
  EXPECT_NE(parseError({"A = x"}, xy({"A", "B"})).find("missing: B"), std::string::npos);
  EXPECT_NE(parseError({"x", "y", "x"}, xy({"A", "B"})).find("got 3 expressions for 2 outputs"),
            std::string::npos);
  EXPECT_NE(parseError({"1.5.5"}, xy()).find("malformed number"), std::string::npos);
  // Decimal only, as in tables: strtod alone reads these as 16 and 8.
  for (const char* hex : {"0x10*x", "2*0X1p3", "x + 0x.8"})
    EXPECT_NE(parseError({hex}, xy()).find("hexadecimal numbers are not accepted"),
              std::string::npos)
        << hex;
}

TEST(EmitParser, UnknownOutputsRepeatedOutputsAndOutOfRangeConstantsAreNamed) {
  // Issue 21: `lgp score -e 'C = mu'` on a table whose output is B was scored as B = mu,
  // 'B = mu; B = r' silently dropped the first assignment, and 1e39 gave "internal error".
  const auto b = xy({"B"});
  EXPECT_NE(parseError({"C = x"}, b)
                .find("assigns 'C', which is not an output of the table "
                      "(outputs: B)"),
            std::string::npos)
      << parseError({"C = x"}, b);
  EXPECT_NE(parseError({"B = x; B = y"}, b)
                .find("the output 'B' is assigned again before its "
                      "value is used"),
            std::string::npos)
      << parseError({"B = x; B = y"}, b);
  const auto ab = xy({"A", "B"});
  EXPECT_NE(parseError({"A = x", "A = y"}, ab).find("the output 'A' is assigned again"),
            std::string::npos);
  // Read in between (a swap): both assignments count.
  EXPECT_EQ(infixOf({"A = x; B = y; t = A; A = B; B = t"}, ab),
            (std::vector<std::string>{"y", "x"}));
  EXPECT_NE(parseError({"A = x; B = y; C = x"}, ab).find("assigns 'C'"), std::string::npos);
  for (const char* c : {"1e39", "-1e39 + x", "1e400"}) {
    const std::string e = parseError({c}, xy());
    EXPECT_NE(e.find("is outside the range of float"), std::string::npos) << c << ": " << e;
    EXPECT_EQ(e.find("internal error"), std::string::npos) << c << ": " << e;
  }
  EXPECT_NE(parseError({"1e39"}, xy()).find("the constant 1e39"), std::string::npos);
  // Still accepted: temporaries, an output assigned last, the largest float.
  EXPECT_EQ(infixOf({"t = x * y; B = t + 1"}, b).size(), 1u);
  EXPECT_EQ(infixOf({"B = 3.4028234e38 * x"}, b).size(), 1u);
}

TEST(EmitParser, LeafOutputsAndLongFormulasBecomeValidPrograms) {
  auto pf = parseFormula({"x", "2.5"}, xy({"A", "B"}));
  ASSERT_TRUE(pf.hasValue()) << pf.error();
  EXPECT_EQ(pf->program.code.size(), 2u);  // add(x, -0) and add(2.5, -0)
  // 300 chained mads, one per statement (as deep a DAG as 300 nested parentheses, which the
  // nesting limit refuses first; parser_limits_test.cpp).
  std::string big = "t = x";
  for (int i = 0; i < 300; ++i) big += "; t = t * y + " + std::to_string(i % 7 + 1);
  EXPECT_NE(parseError({big + "; t"}, xy()).find("formula too long: 300 opcodes"),
            std::string::npos)
      << parseError({big + "; t"}, xy());
}

// emit -> parse -> emit: the printed infix and the HLSL/GLSL function bodies are fixed points.
TEST(EmitParser, EmitParseReemitIsAFixedPoint) {
  std::mt19937 rng(3);
  int checked = 0;
  for (int i = 0; i < 300; ++i) {
    std::optional<Op> first;
    if (i < kNumOps) first = static_cast<Op>(i);
    const int k = 1 + i % 3;
    const int len = std::max(k, std::uniform_int_distribution<int>(1, 14)(rng));
    const Program p = test::randomProgram(rng, 2, len, k, false, first);
    std::vector<std::string> outs;
    for (int j = 0; j < k; ++j) outs.push_back("o" + std::to_string(j));
    const std::vector<Interval> dom = {Interval{0.25, 4, false}, Interval{-1, 1, false}};
    SimplifyOptions so;
    so.domain = dom;
    const Dag d = simplify(buildDag(p, 2), so);
    const auto text = dagInfix(d, {"x", "y"});
    const auto again = printedOf(text, xy(outs));
    ASSERT_EQ(again, text) << "program " << i;
    for (Language lang : {Language::Hlsl, Language::Glsl})
      for (bool fast : {false, true}) {
        EmitInput in;
        in.program = p;
        in.input_names = {"x", "y"};
        in.output_names = outs;
        in.domain = dom;
        EmitOptions eo;
        eo.function_name = "f";
        eo.header = eo.helpers = false;
        eo.fast = fast;
        auto e1 = emitProgram(in, lang, eo);
        ASSERT_TRUE(e1.hasValue()) << e1.error();
        const std::string& code = e1->code;
        const std::string body =
            code.substr(code.find("{\n") + 2, code.rfind('}') - code.find("{\n") - 2);
        auto pf = parseFormula({body}, xy(outs));
        ASSERT_TRUE(pf.hasValue()) << pf.error() << "\n" << code;
        in.program = pf->program;
        auto e2 = emitProgram(in, lang, eo);
        ASSERT_TRUE(e2.hasValue()) << e2.error();
        ASSERT_EQ(e2->code, code) << "program " << i;
        ++checked;
      }
  }
  EXPECT_EQ(checked, 1200);
}

// The expressions a front prints (core toInfix) parse back into programs that the
// interpreter evaluates bit-identically.
TEST(EmitParser, FrontExpressionsParseBackExactly) {
  std::mt19937 rng(8);
  const Table t = test::edgeTable(1);
  const Dataset ds(t, 256);
  Interpreter interp(256);
  for (int i = 0; i < 300; ++i) {
    const int k = 1 + i % 2;
    const Program p = test::randomProgram(rng, 2, std::max(k, 1 + i % 15), k, false);
    std::vector<std::string> outs;
    for (int j = 0; j < k; ++j) outs.push_back("o" + std::to_string(j));
    const auto texts = toInfix(p, {"x", "y"});
    auto pf = parseFormula(texts, xy(outs));
    ASSERT_TRUE(pf.hasValue()) << pf.error() << "\n" << texts[0];
    const auto a = interp.evaluate(p, ds);
    const auto b = interp.evaluate(pf->program, ds);
    for (int j = 0; j < k; ++j)
      for (size_t r = 0; r < t.rows(); ++r)
        ASSERT_EQ(test::ulpDistance(a[j][r], b[j][r]), 0)
            << "program " << i << " output " << j << " row " << r << ": " << texts[j];
  }
}

// The error of a formula on `t` (rmse, mean over the outputs), or NaN if it does not score.
double formulaError(const std::vector<std::string>& expr, const Table& t) {
  auto j = scoreFormula("f", expr, {}, t, ScoreOptions{});
  EXPECT_TRUE(j.hasValue()) << j.error();
  return j && (*j)["error"].is_number() ? (*j)["error"].get<double>() : NAN;
}

// The best constant formula on `t` under that error: every output its mean (what minimises
// each output's rmse), computed from the table.
std::string bestConstant(const Table& t) {
  std::string s;
  for (size_t o = 0; o < t.numOutputs(); ++o) {
    double m = 0;
    for (double v : t.outputs[o]) m += v;
    char b[96];
    std::snprintf(b, sizeof b, "%s%s = %.9g", o ? "; " : "", t.output_names[o].c_str(),
                  m / static_cast<double>(t.rows()));
    s += b;
  }
  return s;
}

// The formula with outputs A and B exchanged (the last assignment wins).
std::vector<std::string> swapAB(std::vector<std::string> expr) {
  expr.back() += "\nswap_t = A; A = B; B = swap_t";
  return expr;
}

// A published formula's error bound on tests/emit/data/dfg_16x16.json: its error there when
// this test was written, plus 5%. The fits target the authors' own tables (a different
// masking term or roughness mapping, docs/published.md), so the errors are not small; what
// the bound checks is that the text parses into the formula as written. It is tight enough
// that the best constant formula (the table's means, error 0.1623), the constant A = 0.5,
// B = 0.05 (0.1987) and the formula with A and B exchanged all fail it, which the tests
// below check too.
constexpr double kBoundFactor = 1.05;

TEST(EmitParser, PublishedDfgFormulasParseAndScore) {
  const Table dfg = test::loadDfg();
  struct Pub {
    std::string name;
    std::vector<std::string> expr;
    double measured;  // error on dfg_16x16 when this test was written
  };
  const std::vector<Pub> pubs = {
      {"Karis EnvBRDFApprox",
       {"qx = 1 - r; qy = -0.0275*r + 0.0425; qz = -0.572*r + 1.04; qw = 0.022*r - 0.04;\n"
        "a004 = min(qx*qx, exp2(-9.28*NoV))*qx + qy\n"
        "A = -1.04*a004 + qz;  B = 1.04*a004 + qw"},
       0.0487641},
      {"Iwanicki & Pesce",
       {"m = r*r\nB = exp2(-(7*NoV + 4*m))\nA = 1 - B - m*max(B, min(r, 0.739 + 0.323*NoV) - "
        "0.434)"},
       0.111674},
      {"Narkowicz 2014",
       {"x = (1 - r)*(1 - r); y = NoV\n"
        "B = saturate(min(-0.1688*x + 1.895*x*x, 0.9903 - 4.853*y + 8.404*y*y - 5.069*y*y*y))\n"
        "delta = saturate(0.6045 + 1.699*x - 0.5228*y - 3.603*x*x + 1.404*x*y + 0.1939*y*y + "
        "2.661*x*x*x)\n"
        "A = delta - B"},
       0.0553285},
      {"Ray Tracing Gems 32",
       {"m = r*r\n"
        "B  = ((0.99044 - 1.28514*NoV) + m*(1.29678 - 0.755907*NoV)) /\n"
        "     ((1 + 2.92338*NoV + 59.4188*NoV^3) + m*(20.3225 - 27.0302*NoV + 222.592*NoV^3) + "
        "m^3*(121.563 + 626.13*NoV + 316.627*NoV^3))\n"
        "A = ((0.0365463 + 3.32707*NoV) + m*(9.0632 - 9.04756*NoV)) /\n"
        "     ((1 + 3.59685*NoV^2 - 1.36772*NoV^3) + m*(9.04401 - 16.3174*NoV^2 + 9.22949*NoV^3) + "
        "m^3*(5.56589 + 19.7886*NoV^2 - 20.2123*NoV^3))"},
       0.0467424},
  };
  const double constant_error = formulaError({bestConstant(dfg)}, dfg);
  EXPECT_NEAR(constant_error, 0.162262, 1e-5);
  EXPECT_NEAR(formulaError({"A = 0.5; B = 0.05"}, dfg), 0.198673, 1e-5);
  ScoreOptions so;
  for (const auto& p : pubs) {
    auto j = scoreFormula(p.name, p.expr, {}, dfg, so);
    ASSERT_TRUE(j.hasValue()) << p.name << ": " << j.error();
    const auto& r = *j;
    EXPECT_EQ(r["name"], p.name);
    ASSERT_TRUE(r["error"].is_number()) << p.name;
    const double bound = kBoundFactor * p.measured;
    EXPECT_LT(r["error"].get<double>(), bound) << p.name;
    EXPECT_GT(r["error"].get<double>(), p.measured / kBoundFactor) << p.name;
    // What a misparse could give fails the bound: a constant, or A and B exchanged.
    EXPECT_GT(constant_error, bound) << p.name;
    EXPECT_GT(formulaError(swapAB(p.expr), dfg), bound) << p.name;
    EXPECT_GT(r["cost"].get<double>(), 0) << p.name;
    for (const char* t : {"gpu-generic", "nvidia", "gcn", "rdna", "cpu"})
      EXPECT_TRUE(r["cost_by_target"][t].is_number()) << p.name << " " << t;
    ASSERT_EQ(r["outputs"].size(), 2u);
    EXPECT_EQ(r["outputs"][0]["name"], "A");
    EXPECT_EQ(r["outputs"][1]["transform"], "none");
    EXPECT_TRUE(r["outputs"][0]["double"]["rmse"].is_number());
  }
  // Karis: 12 opcodes, 4 of them fused mads, one exp2 and one min (piecewise).
  auto k = scoreFormula("karis", pubs[0].expr, {}, dfg, so);
  ASSERT_TRUE(k.hasValue());
  EXPECT_EQ((*k)["opcodes"], 12);
  EXPECT_EQ((*k)["piecewise"], 1);
  // docs/published.md: cost 13.5 in gpu-generic (docs/cost-models.md: 10 mads and muls, one
  // product fused into the add that reads it, the exp2 with its clamp proven away on the
  // table, the min, non-inline constants).
  EXPECT_DOUBLE_EQ((*k)["cost"].get<double>(), 13.5);
  // The printed formula writes the fused mads as a*b + c, with signs in the constants.
  const std::string f = (*k)["formula"].get<std::string>();
  EXPECT_NE(f.find("exp2(-9.28*NoV)"), std::string::npos) << f;
  EXPECT_EQ(f.find("mad("), std::string::npos) << f;
  EXPECT_FALSE(std::regex_search(f, std::regex(R"(\(-[0-9.]+\)|-\(-)"))) << f;
  EXPECT_NE(f.find("; A = "), std::string::npos) << f;
  EXPECT_NE(f.find("; B = "), std::string::npos) << f;
}

TEST(EmitParser, MaterialXRationalFitParses) {
  const Table dfg = test::loadDfg();
  // c[i][k] of the MaterialX fit (docs/published.md),
  // t = (1, x, y, x*y, x^2, y^2, x^2*y, x*y^2, x^2*y^2).
  const double c[9][4] = {{0.1003, 0.9345, 1.0, 1.0},     {-0.6303, -2.323, -1.765, 0.2281},
                          {9.748, 2.229, 8.263, 15.94},   {-2.038, -3.748, 11.53, -55.83},
                          {29.34, 1.424, 28.96, 13.08},   {-8.245, -0.7684, -7.507, 41.26},
                          {-26.44, 1.436, -36.11, 54.9},  {19.99, 0.2913, 15.86, 300.2},
                          {-5.448, 0.6286, 33.37, -285.1}};
  const char* terms[9] = {"1", "x", "y", "x*y", "x*x", "y*y", "x*x*y", "x*y*y", "x*x*y*y"};
  std::string text = "x = NoV; y = r*r\n";
  for (int k = 0; k < 4; ++k) {
    text += "R" + std::to_string(k) + " = ";
    for (int i = 0; i < 9; ++i) {
      char buf[64];
      std::snprintf(buf, sizeof buf, "%s%g*%s", i ? " + " : "", c[i][k], terms[i]);
      text += buf;
    }
    text += "\n";
  }
  text += "A = saturate(R0/R2); B = saturate(R1/R3)";
  auto j = scoreFormula("MaterialX", {text}, {}, dfg, ScoreOptions{});
  ASSERT_TRUE(j.hasValue()) << j.error();
  ASSERT_TRUE((*j)["error"].is_number());
  const double measured = 0.0591901, bound = kBoundFactor * measured;  // see above
  EXPECT_LT((*j)["error"].get<double>(), bound);
  EXPECT_GT((*j)["error"].get<double>(), measured / kBoundFactor);
  EXPECT_GT(formulaError({bestConstant(dfg)}, dfg), bound);
  EXPECT_GT(formulaError(swapAB({text}), dfg), bound);
  // x and y exchanged (NoV for alpha): 0.114, also refused.
  std::string swapped = text;
  swapped.replace(0, swapped.find('\n'), "x = r*r; y = NoV");
  EXPECT_GT(formulaError({swapped}, dfg), bound);
}

}  // namespace
}  // namespace lgp::emit
