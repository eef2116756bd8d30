// Interval analysis on the table's domain: piecewise operators that switch and that do not,
// the discontinuity objective that counts only the former, and the simplifier that removes the
// latter (abs of a non-negative, saturate of [0, 1], a dominated min/max operand, a select
// whose comparison never changes).
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>

#include "lgp/core/expr.hpp"
#include "lgp/core/formula.hpp"
#include "lgp/core/interval.hpp"
#include "lgp/eval/discontinuity.hpp"
#include "lgp/eval/interpreter.hpp"
#include "lgp/eval/objectives.hpp"

namespace lgp {
namespace {

constexpr auto X = inputOperand;
constexpr auto C = constOperand;
constexpr auto R = regOperand;

Interval iv(double lo, double hi) {
  return Interval{lo, hi, false};
}

bool switches(Op op, std::vector<Interval> a) {
  a.resize(kMaxArity);
  return branchMaySwitch(op, a.data());
}

TEST(Interval, PiecewiseBranchesThatSwitchAndThatDoNot) {
  EXPECT_FALSE(switches(Op::Abs, {iv(1, 2)}));
  EXPECT_FALSE(switches(Op::Abs, {iv(-2, -1)}));
  EXPECT_TRUE(switches(Op::Abs, {iv(-1, 1)}));
  EXPECT_TRUE(switches(Op::Abs, {Interval{1, 2, true}}));  // may be NaN
  EXPECT_FALSE(switches(Op::Saturate, {iv(0.2, 0.8)}));
  EXPECT_FALSE(switches(Op::Saturate, {iv(-2, -1)}));     // always 0
  EXPECT_FALSE(switches(Op::Saturate, {iv(1.5, 2)}));     // always 1
  EXPECT_TRUE(switches(Op::Saturate, {iv(-0.5, 0.5)}));   // crosses 0
  EXPECT_TRUE(switches(Op::Saturate, {iv(0.5, 1.5)}));    // crosses 1
  EXPECT_FALSE(switches(Op::Min, {iv(0, 1), iv(2, 3)}));  // the first always
  EXPECT_FALSE(switches(Op::Max, {iv(2, 3), iv(0, 1)}));
  EXPECT_TRUE(switches(Op::Min, {iv(0, 1), iv(0.5, 2)}));
  EXPECT_TRUE(switches(Op::Max, {iv(0, 1), Interval{}}));                        // unknown operand
  EXPECT_FALSE(switches(Op::Select, {iv(2, 3), iv(0, 1), iv(0, 1), iv(0, 1)}));  // a > b
  EXPECT_FALSE(switches(Op::Select, {iv(0, 1), iv(1, 2), iv(0, 1), iv(0, 1)}));  // a <= b
  EXPECT_TRUE(switches(Op::Select, {iv(0, 1), iv(0.5, 2), iv(0, 1), iv(0, 1)}));
  EXPECT_FALSE(switches(Op::Add, {iv(-1, 1), iv(-1, 1)}));  // not piecewise
}

// abs(mad(mu, 0.608, 0.608)): its argument never changes sign for mu in [0, 1].
Program absOfPositive() {
  Program p;
  p.code = {Instr{Op::Mad, {X(0), C(0), C(0)}}, Instr{Op::Abs, {R(0)}}};
  p.constants = {0.608f};
  p.outputs = {1};
  return p;
}

TEST(Interval, DiscontinuityCountsOnlyBranchesThatSwitchOnTheDomain) {
  DiscontinuityModel m = DiscontinuityModel::defaults();
  EXPECT_EQ(m.programDiscontinuity(absOfPositive()), 1);  // no domain: every piecewise op
  m.domain = {iv(0, 1), iv(0, 1)};
  EXPECT_EQ(m.programDiscontinuity(absOfPositive()), 0);
  m.domain = {iv(-2, 1), iv(0, 1)};  // now 0.608*mu + 0.608 crosses 0 at mu = -1
  EXPECT_EQ(m.programDiscontinuity(absOfPositive()), 1);

  // min(mu, r + 2) never switches; max(mu, r) does; saturate(mu*0.5) stays inside [0, 1].
  Program q;
  q.code = {Instr{Op::Add, {X(1), C(0)}}, Instr{Op::Min, {X(0), R(0)}},
            Instr{Op::Max, {X(0), X(1)}}, Instr{Op::Mul, {X(0), C(1)}},
            Instr{Op::Saturate, {R(3)}},  Instr{Op::Add, {R(1), R(2)}},
            Instr{Op::Add, {R(5), R(4)}}};
  q.constants = {2.0f, 0.5f};
  q.outputs = {6};
  m.domain = {iv(0, 1), iv(0, 1)};
  EXPECT_EQ(m.programDiscontinuity(q), 1);  // only max
  m.weight[static_cast<int>(Op::Max)] = 2.5;
  EXPECT_EQ(m.programDiscontinuity(q), 2.5);
}

// Node count of the simplified DAG and whether a given op survives.
struct Simplified {
  int ops = 0;
  bool has(Op op) const { return std::find(kinds.begin(), kinds.end(), op) != kinds.end(); }
  std::vector<Op> kinds;
};
Simplified simplifiedOn(const Program& p, std::vector<Interval> dom) {
  const Dag d = formulaDag(p, 2, dom);
  Simplified s;
  s.ops = d.numOps();
  for (const Node& n : d.nodes)
    if (n.isOp()) s.kinds.push_back(n.op);
  return s;
}

Program unary(Op op, Op inner, float c) {
  Program p;
  p.code = {Instr{inner, {X(0), C(0)}}, Instr{op, {R(0)}}};
  p.constants = {c};
  p.outputs = {1};
  return p;
}

Program binary(Op op, Operand a, Operand b, std::vector<float> c = {}) {
  Program p;
  p.code = {Instr{op, {a, b}}};
  p.constants = std::move(c);
  p.outputs = {0};
  return p;
}

TEST(Interval, SimplifierRemovesBranchesThatNeverSwitch) {
  const std::vector<Interval> unit = {iv(0, 1), iv(0, 1)};
  EXPECT_FALSE(simplifiedOn(absOfPositive(), unit).has(Op::Abs));
  EXPECT_TRUE(simplifiedOn(absOfPositive(), {iv(-2, 1), iv(0, 1)}).has(Op::Abs));
  // abs of a negative value becomes a negation (free on GPUs), never wrong.
  const auto neg = simplifiedOn(unary(Op::Abs, Op::Sub, 2.0f), unit);  // abs(mu - 2)
  EXPECT_FALSE(neg.has(Op::Abs));
  EXPECT_TRUE(neg.has(Op::Neg));
  EXPECT_FALSE(simplifiedOn(unary(Op::Saturate, Op::Mul, 0.5f), unit).has(Op::Saturate));
  EXPECT_TRUE(simplifiedOn(unary(Op::Saturate, Op::Mul, 1.5f), unit).has(Op::Saturate));
  EXPECT_EQ(simplifiedOn(unary(Op::Saturate, Op::Add, 3.0f), unit).ops, 0);    // always 1
  EXPECT_EQ(simplifiedOn(binary(Op::Min, X(0), C(0), {5.0f}), unit).ops, 0);   // mu
  EXPECT_EQ(simplifiedOn(binary(Op::Max, X(0), C(0), {-5.0f}), unit).ops, 0);  // mu
  EXPECT_EQ(simplifiedOn(binary(Op::Max, X(0), C(0), {5.0f}), unit).ops, 0);   // 5
  EXPECT_TRUE(simplifiedOn(binary(Op::Min, X(0), X(1)), unit).has(Op::Min));
  EXPECT_TRUE(simplifiedOn(binary(Op::Min, X(0), C(0), {0.5f}), unit).has(Op::Min));
  Program sel;
  sel.code = {Instr{Op::Select, {X(0), C(0), X(1), C(1)}}};  // mu > -1 ? r : 3
  sel.constants = {-1.0f, 3.0f};
  sel.outputs = {0};
  EXPECT_EQ(simplifiedOn(sel, unit).ops, 0);
  sel.constants = {0.5f, 3.0f};  // mu > 0.5 switches
  EXPECT_TRUE(simplifiedOn(sel, unit).has(Op::Select));
  // Without a domain nothing is known about the inputs: every branch stays.
  EXPECT_TRUE(simplifiedOn(absOfPositive(), {}).has(Op::Abs));
}

// Every removal is exact on the domain: the simplified DAG, relinearised, computes the same
// float32 bits as the program on a grid over the domain, corners included.
TEST(Interval, RemovalsAreExactOnTheDomain) {
  const std::vector<Interval> unit = {iv(0, 1), iv(0, 1)};
  Table t;
  t.input_names = {"mu", "r"};
  t.output_names = {"y"};
  t.inputs.resize(2);
  for (int i = 0; i <= 20; ++i)
    for (int j = 0; j <= 20; ++j) {
      t.inputs[0].push_back(i / 20.0);
      t.inputs[1].push_back(j / 20.0);
    }
  t.outputs.push_back(std::vector<double>(t.rows(), 0.0));
  const Dataset ds(t, 256);
  Interpreter interp(256);
  Program sel;
  sel.code = {Instr{Op::Select, {X(0), C(0), X(1), C(1)}}};
  sel.constants = {-1.0f, 3.0f};
  sel.outputs = {0};
  for (const Program& p :
       {absOfPositive(), unary(Op::Abs, Op::Sub, 2.0f), unary(Op::Saturate, Op::Mul, 0.5f),
        unary(Op::Saturate, Op::Add, 3.0f), binary(Op::Min, X(0), C(0), {5.0f}),
        binary(Op::Max, X(0), C(0), {-5.0f}), sel}) {
    auto lp = toProgram(formulaDag(p, 2, unit));
    ASSERT_TRUE(lp.hasValue()) << lp.error();
    const auto a = interp.evaluate(p, ds);
    const auto b = interp.evaluate(lp->program, ds);
    for (size_t r = 0; r < t.rows(); ++r)
      ASSERT_EQ(std::bit_cast<uint32_t>(a[0][r]), std::bit_cast<uint32_t>(b[0][r]))
          << toInfix(p, {"mu", "r"})[0] << " row " << r;
  }
}

// The intervals of a program (what the discontinuity objective reads) hold every value the
// interpreter computes on the domain.
TEST(Interval, ProgramIntervalsContainTheInterpretedValues) {
  Program p;
  p.code = {Instr{Op::Mad, {X(0), C(0), C(1)}}, Instr{Op::Exp2, {R(0)}},
            Instr{Op::Sub, {R(1), X(1)}}, Instr{Op::Abs, {R(2)}}, Instr{Op::Rcp, {R(3)}}};
  p.constants = {-3.0f, 0.25f};
  p.outputs = {4};
  const std::vector<Interval> dom = {iv(0.1, 2), iv(-1, 1)};
  std::vector<Interval> out;
  programIntervals(p, dom, effectiveIndices(p), out);
  const Dag d = buildDag(p, 2);
  for (double x0 : {0.1, 0.5, 1.3, 2.0})
    for (double x1 : {-1.0, 0.0, 0.7, 1.0}) {
      Dag all = d;  // every node as an output
      all.outputs.clear();
      for (size_t n = 0; n < d.nodes.size(); ++n)
        if (d.nodes[n].isOp()) all.outputs.push_back(static_cast<int>(n));
      const double in[2] = {x0, x1};
      const auto v = evaluateRow(all, in, Precision::Float);
      ASSERT_EQ(v.size(), out.size());
      for (size_t k = 0; k < v.size(); ++k) {
        EXPECT_GE(v[k], out[k].lo) << k;
        EXPECT_LE(v[k], out[k].hi) << k;
      }
    }
}

}  // namespace
}  // namespace lgp
