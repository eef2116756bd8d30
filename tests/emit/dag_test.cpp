// The emitter's DAG: construction and CSE, linearisation, simplification rules, interval
// proofs behind --fast, costs, and binary16 rounding.
#include <gtest/gtest.h>

#include "emit_test_util.hpp"
#include "lgp/emit/dag.hpp"
#include "lgp/emit/emit.hpp"
#include "lgp/emit/half.hpp"
#include "lgp/emit/parser.hpp"
#include "lgp/eval/interpreter.hpp"
#include "lgp/eval/objectives.hpp"

namespace lgp::emit {
namespace {

Dag parse(const std::string& text) {
  ParseOptions o;
  o.input_names = {"x", "y"};
  o.output_names = {"y0"};
  o.fuse_mad = false;
  auto pf = parseFormula({text}, o);
  EXPECT_TRUE(pf.hasValue()) << pf.error();
  return pf ? pf->dag : Dag{};
}

std::string simplified(const std::string& text, std::vector<Interval> dom = {}) {
  SimplifyOptions so;
  so.domain = dom;
  return dagInfix(simplify(parse(text), so), {"x", "y"})[0];
}

TEST(EmitDag, ExactRewrites) {
  const std::vector<Interval> pos = {Interval{0.5, 2, false}, Interval{0.5, 2, false}};
  EXPECT_EQ(simplified("x * 1 + 0"), "x");  // -0 + 0 = +0, but no divisor sees the sign
  // Here the sign reaches rcp's guard (1/guard(-0) = -1e20): x + 0 stays unless x is never -0.
  EXPECT_EQ(simplified("1 / (x * 1 + 0)"), "1/(x + 0)");
  EXPECT_EQ(simplified("1 / (x * 1 + 0)", pos), "1/x");
  EXPECT_EQ(simplified("1 / (x * 1 + -0)"), "1/x");  // x + (-0) = x for every x
  EXPECT_EQ(simplified("1 * x - 0"), "x");
  EXPECT_EQ(simplified("x / 1"), "x");
  EXPECT_EQ(simplified("x / -1"), "-x");
  EXPECT_EQ(simplified("x * -1"), "-x");
  EXPECT_EQ(simplified("0 - x"), "-x");
  EXPECT_EQ(simplified("y / (0 - x)"), "y/(0 - x)");  // 0 - (+0) = +0 but -(+0) = -0
  EXPECT_EQ(simplified("y / (0 - x)", pos), "-y/x");
  EXPECT_EQ(simplified("-(-x)"), "x");
  EXPECT_EQ(simplified("x + -2"), "x - 2");
  EXPECT_EQ(simplified("x - -2"), "x + 2");
  EXPECT_EQ(simplified("x + -y"), "x - y");
  EXPECT_EQ(simplified("-y + x"), "x - y");
  EXPECT_EQ(simplified("x - -y"), "x + y");
  EXPECT_EQ(simplified("div(1, x + y)"), "1/(x + y)");
  EXPECT_EQ(simplified("mad(1, x, y)"), "x + y");
  EXPECT_EQ(simplified("mad(x, -1, y)"), "y - x");
  EXPECT_EQ(simplified("mad(x, y, 0)"), "x*y");
  EXPECT_EQ(simplified("1 / mad(x, y, 0)"), "1/(x*y + 0)");  // x*y may be -0
  EXPECT_EQ(simplified("1 / mad(x, y, 0)", pos), "1/(x*y)");
  EXPECT_EQ(simplified("mad(2, 3, y)"), "6 + y");
  EXPECT_EQ(simplified("exp2(3) * x"), "8*x");  // folded with the interpreter's exp2
  EXPECT_EQ(simplified("(-x) * 3"), "-3*x");
  EXPECT_EQ(simplified("min(x + y, x + y)"), "x + y");
  // A zero coefficient folds where its operand is proven finite, keeping the zero's sign
  // where a divisor sees it.
  EXPECT_EQ(simplified("0 * x + y"), "0*x + y");  // x may be Inf: 0*Inf is NaN
  EXPECT_EQ(simplified("0 * x + y", pos), "y");
  EXPECT_EQ(simplified("y + x * 0 * y", pos), "y");
  EXPECT_EQ(simplified("1 / (-0 * x)", pos), "-1e+20");  // -0, then the guarded 1/-0
  const std::vector<Interval> signed_dom = {Interval{-1, 1, false}, Interval{0.5, 2, false}};
  EXPECT_EQ(simplified("y + 0 * x", signed_dom), "y");          // no divisor sees the zero
  EXPECT_EQ(simplified("1 / (0 * x)", signed_dom), "1/(0*x)");  // +-0 reaches rcp's guard
}

TEST(EmitDag, PowRewritesNeedAProvenNonNegativeBase) {
  const std::vector<Interval> d = {Interval{0, 2, false}, Interval{-1, 1, false}};
  EXPECT_EQ(simplified("pow(x, 2)", d), "x^2");
  EXPECT_EQ(simplified("pow(x, 3)", d), "x^3");
  EXPECT_EQ(simplified("pow(x, 4)", d), "x^4");
  EXPECT_EQ(simplified("pow(x, 0.5)", d), "sqrt(x)");
  EXPECT_EQ(simplified("pow(x, 1)", d), "x");
  EXPECT_EQ(simplified("pow(x, 0)", d), "1");
  EXPECT_EQ(simplified("pow(y, 2)", d), "pow(y, 2)");  // y may be negative
  EXPECT_EQ(simplified("pow(x, 2)"), "pow(x, 2)");     // no domain
  EXPECT_EQ(simplified("pow(x, 2.5)", d), "pow(x, 2.5)");
}

TEST(EmitDag, DuplicatesMergeAndIntronsDrop) {
  // r0 = x*y, r1 = x*y (duplicate), r2 = sin(x) (intron), r3 = r0 + r1
  Program p;
  auto X = [](int i) { return Operand{OperandKind::Var, static_cast<uint8_t>(i)}; };
  auto R = [](int i) { return Operand{OperandKind::Reg, static_cast<uint8_t>(i)}; };
  p.code = {Instr{Op::Mul, {X(0), X(1)}}, Instr{Op::Mul, {X(0), X(1)}}, Instr{Op::Sin, {X(0)}},
            Instr{Op::Add, {R(0), R(1)}}};
  p.outputs = {3};
  const Dag d = buildDag(p, 2);
  EXPECT_EQ(d.numOps(), 2);
  EXPECT_EQ(dagInfix(d, {"x", "y"})[0], "t0 = x*y; t0 + t0");
  // Three effective opcodes, two distinct ones: the shared product is costed once.
  EXPECT_EQ(effectiveIndices(p).size(), 3u);
  const CostModel m = CostModel::preset(CostTarget::GpuGeneric);
  const double once = m.cost[static_cast<int>(Op::Mul)] + m.cost[static_cast<int>(Op::Add)];
  EXPECT_EQ(m.dagCost(d), once);
  EXPECT_EQ(m.programCost(p), once);
}

TEST(EmitDag, SimplifiedDagIsNeverMoreExpensiveAndLinearisesFaithfully) {
  std::mt19937 rng(17);
  const Table t = test::edgeTable(2);
  const Dataset ds(t, 256);
  Interpreter interp(256);
  for (int i = 0; i < 300; ++i) {
    const Program p = test::randomProgram(rng, 2, 2 + i % 14, 1 + i % 2, false);
    SimplifyOptions so;
    so.pow_rewrites = false;
    const Dag d = simplify(buildDag(p, 2), so);
    for (int c = 0; c < kNumCostTargets; ++c) {
      const CostModel cm = CostModel::preset(static_cast<CostTarget>(c));
      ASSERT_LE(cm.dagCost(d), cm.dagCost(buildDag(p, 2)) + 1e-9) << "program " << i;
    }
    // DAG -> Program -> interpreter equals the DAG's own float evaluation, row by row.
    auto lp = toProgram(d);
    ASSERT_TRUE(lp.hasValue()) << lp.error();
    const auto v = interp.evaluate(lp->program, ds);
    std::vector<double> x(2);
    for (size_t r = 0; r < t.rows(); r += 7) {
      x[0] = t.inputs[0][r];
      x[1] = t.inputs[1][r];
      const auto e = evaluateRow(d, x.data(), Precision::Float);
      for (size_t j = 0; j < e.size(); ++j)
        ASSERT_EQ(test::ulpDistance(static_cast<float>(e[j]), v[j][r]), 0)
            << "program " << i << " row " << r;
    }
  }
}

TEST(EmitDag, IntervalProofsBehindFast) {
  auto proven = [](const std::string& text, std::vector<Interval> dom) {
    const Dag d = parse(text);
    const auto iv = nodeIntervals(d, dom);
    return provenUnguarded(d, d.outputs[0], iv);
  };
  const Interval pos{0.5, 2, false}, unit{0, 1, false}, sym{-1, 1, false};
  EXPECT_TRUE(proven("log2(x)", {pos, pos}));
  EXPECT_FALSE(proven("log2(x)", {unit, pos}));  // log2(0) hits the floor
  EXPECT_TRUE(proven("x / y", {sym, pos}));
  EXPECT_FALSE(proven("x / y", {pos, sym}));
  EXPECT_TRUE(proven("sqrt(x)", {unit, pos}));
  EXPECT_FALSE(proven("sqrt(x - 0.5)", {unit, pos}));
  EXPECT_TRUE(proven("rsqrt(x)", {pos, pos}));
  EXPECT_TRUE(proven("exp2(x * 100)", {sym, pos}));
  EXPECT_FALSE(proven("exp2(x * 200)", {sym, pos}));
  EXPECT_TRUE(proven("pow(x, y)", {pos, sym}));
  EXPECT_FALSE(proven("pow(x, y)", {unit, sym}));
  EXPECT_TRUE(proven("exp(x)", {sym, pos}));
  EXPECT_FALSE(proven("x / y", {pos, Interval{}}));  // unknown domain
  EXPECT_TRUE(proven("saturate(x * y)", {sym, sym}));
}

TEST(EmitDag, IntervalsContainEveryInterpretedValue) {
  std::mt19937 rng(29);
  Table t;
  t.input_names = {"x", "y"};
  t.inputs.resize(2);
  std::uniform_real_distribution<double> ux(-2, 3), uy(0.1, 4);
  for (int r = 0; r < 400; ++r) {
    t.inputs[0].push_back(ux(rng));
    t.inputs[1].push_back(uy(rng));
  }
  t.inputs[0].push_back(-2);
  t.inputs[1].push_back(0.1);
  t.inputs[0].push_back(3);
  t.inputs[1].push_back(4);
  const std::vector<Interval> dom = {Interval{-2, 3, false}, Interval{0.1, 4, false}};
  for (int i = 0; i < 300; ++i) {
    const Program p = test::randomProgram(rng, 2, 2 + i % 10, 1, false);
    const Dag d = buildDag(p, 2);
    const auto iv = nodeIntervals(d, dom);
    std::vector<double> x(2);
    for (size_t r = 0; r < t.inputs[0].size(); ++r) {
      x[0] = t.inputs[0][r];
      x[1] = t.inputs[1][r];
      Dag one = d;  // evaluate every node: make each one an output
      one.outputs.clear();
      for (size_t n = 0; n < d.nodes.size(); ++n) one.outputs.push_back(static_cast<int>(n));
      const auto v = evaluateRow(one, x.data(), Precision::Float);
      for (size_t n = 0; n < v.size(); ++n) {
        if (std::isnan(v[n])) {
          ASSERT_TRUE(iv[n].nan) << "program " << i << " node " << n;
          continue;
        }
        ASSERT_GE(v[n], iv[n].lo) << "program " << i << " node " << n << " row " << r;
        ASSERT_LE(v[n], iv[n].hi) << "program " << i << " node " << n << " row " << r;
      }
    }
  }
}

TEST(EmitDag, HalfRounding) {
  EXPECT_EQ(roundToHalf(1.0f), 1.0f);
  EXPECT_EQ(roundToHalf(0.1f), 0.0999755859375f);
  EXPECT_EQ(roundToHalf(65504.0f), 65504.0f);
  EXPECT_TRUE(std::isinf(roundToHalf(65520.0f)));
  EXPECT_EQ(roundToHalf(65519.0f), 65504.0f);
  EXPECT_EQ(roundToHalf(1e-8f), 0.0f);
  EXPECT_EQ(roundToHalf(5.0e-8f), 5.9604644775390625e-08f);  // smallest subnormal half
  EXPECT_EQ(roundToHalf(-3.0f), -3.0f);
  EXPECT_EQ(roundToHalf(1.0f + 0x1p-11f), 1.0f);  // tie to even
  EXPECT_EQ(roundToHalf(1.0f + 3 * 0x1p-11f), 1.0f + 0x1p-9f);
  EXPECT_EQ(applyHalf(Op::Div, 1.0f, 0.0f, 0, 0), 16384.0f);  // 1 / 2^-14
  EXPECT_EQ(applyHalf(Op::Exp2, 40.0f, 0, 0, 0), 32768.0f);   // clamp at 15
}

// A slope of 0 on a value beyond binary16's range (a front member's constant output: the
// scored float32 program computes 0*1e20 + b = b) must export as b in half, not 0*inf + b.
TEST(EmitDag, HalfKeepsOnlyWhatTheScoredProgramComputes) {
  Program p;
  p.code.push_back(Instr{Op::Add, {constOperand(0), constOperand(1)}});  // 1e20 + -0
  p.code.push_back(Instr{Op::Add, {inputOperand(0), constOperand(0)}});  // x + 1e20
  p.code.push_back(Instr{Op::Mad, {regOperand(0), constOperand(2), constOperand(3)}});
  p.code.push_back(Instr{Op::Mad, {regOperand(1), constOperand(2), constOperand(3)}});
  p.constants = {1.0e20f, -0.0f, 0.0f, 0.06557155f};
  p.outputs = {2, 3};
  EmitInput in;
  in.program = p;
  in.input_names = {"mu", "r"};
  in.output_names = {"A", "B"};
  in.domain = {Interval{0.015625, 1, false}, Interval{0, 1, false}};
  for (Language lang : {Language::Hlsl, Language::Glsl}) {
    EmitOptions o;
    o.precision = Precision::Half;
    auto e = emitProgram(in, lang, o);
    ASSERT_TRUE(e.hasValue()) << e.error();
    EXPECT_EQ(e->formula, "A = 0.06555176; B = 0.06555176") << e->code;
    EXPECT_EQ(e->code.find("0x7F800000"), std::string::npos) << e->code;
    const double row[2] = {0.5, 0.5};
    for (double v : evaluateRow(e->dag, row, Precision::Half))
      EXPECT_EQ(v, double(roundToHalf(0.06557155f)));
    EXPECT_TRUE(e->half_overflow.empty());
    EXPECT_EQ(e->code.find("Warning: constant"), std::string::npos) << e->code;
  }
  // A constant the scored program needs beyond binary16's range is named in the header.
  p.code[2] = Instr{Op::Mad, {inputOperand(1), constOperand(0), constOperand(3)}};  // r*1e20 + b
  for (Precision prec : {Precision::Half, Precision::Float}) {
    EmitOptions o;
    o.precision = prec;
    in.program = p;
    auto e = emitProgram(in, Language::Hlsl, o);
    ASSERT_TRUE(e.hasValue()) << e.error();
    const bool half = prec == Precision::Half;
    EXPECT_EQ(e->half_overflow, half ? std::vector<double>{1e20f} : std::vector<double>{});
    EXPECT_EQ(e->code.find("// Warning: constant 1e+20 beyond binary16's range (65504): "
                           "infinite in half") != std::string::npos,
              half)
        << e->code;
  }
  // Hardening round 4, F13: a constant below binary16's smallest subnormal became 0.0h without
  // the warning a large one gets.
  p.code[2] = Instr{Op::Mul, {inputOperand(1), constOperand(0)}};  // r*1e-9
  p.constants[0] = 1e-9f;
  in.program = p;
  EmitOptions o;
  o.precision = Precision::Half;
  auto e = emitProgram(in, Language::Hlsl, o);
  ASSERT_TRUE(e.hasValue()) << e.error();
  EXPECT_EQ(e->half_underflow, std::vector<double>{1e-9f});
  EXPECT_NE(e->code.find("constant 1e-09 below binary16's smallest subnormal (5.9604645e-08): 0 "
                         "in half"),
            std::string::npos)
      << e->code;
  EXPECT_NE(halfRangeWarning(*e).find("does not suit a half export"), std::string::npos);
}

}  // namespace
}  // namespace lgp::emit
