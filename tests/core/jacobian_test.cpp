// The forward-mode Jacobian pass: values bit-identical to the interpreter, derivatives equal to
// central differences of a double evaluation for every operator, and zero where a guard,
// clamp or floor of the protected semantics is active.
#include "lgp/eval/jacobian.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "lgp/core/rng.hpp"
#include "lgp/core/variation.hpp"
#include "lgp/eval/interpreter.hpp"
#include "lgp/eval/semantics.hpp"

namespace lgp {
namespace {

// The program in double precision with double constants (the float constants of a Program
// cannot be perturbed by a small step).
std::vector<double> evalDouble(const Program& p, const std::vector<double>& consts,
                               const double* inputs) {
  return evaluateReferenceRow(p, inputs, consts.data());
}

Table randomInputs(int inputs, int outputs, int rows, double lo, double hi, uint64_t seed) {
  Table t;
  Rng rng(seed);
  for (int i = 0; i < inputs; ++i) {
    t.input_names.push_back("x" + std::to_string(i));
    t.inputs.emplace_back();
    for (int r = 0; r < rows; ++r) t.inputs.back().push_back(rng.uniform(lo, hi));
  }
  for (int o = 0; o < outputs; ++o) {
    t.output_names.push_back("y" + std::to_string(o));
    t.outputs.emplace_back(rows, 0.0);
  }
  return t;
}

// Jacobian of every output w.r.t. every parameter at every row: [output][param][row].
std::vector<std::vector<std::vector<float>>> jacobian(JacobianEvaluator& je, const Program& p,
                                                      const Dataset& ds) {
  je.bind(p, ds);
  const int np = je.numParameters(), bs = je.blockSize();
  std::vector<std::vector<std::vector<float>>> out(
      p.outputs.size(), std::vector<std::vector<float>>(np, std::vector<float>(ds.rows())));
  for (size_t b = 0; b < ds.numBlocks(); ++b) {
    je.evalBlock(b);
    for (size_t r = b * bs; r < std::min(ds.rows(), (b + 1) * bs); ++r)
      for (size_t o = 0; o < p.outputs.size(); ++o)
        for (int k = 0; k < np; ++k)
          out[o][k][r] = je.derivative(static_cast<int>(o), k)[r - b * bs];
  }
  return out;
}

// Central difference of output o w.r.t. constant slot `slot` at input row x, in double.
// h = 1e-6 (relative): the truncation error is O(h^2 f''') ~ 1e-12 and the rounding error
// ~ 1e-16 / h = 1e-10, far below the float32 Jacobian's own error.
struct CentralDifference {
  double d = 0;
  bool smooth = false;  // the one-sided differences agree: no kink or guard within h
};
CentralDifference centralDifference(const Program& p, int o, int slot, const double* x) {
  std::vector<double> c(p.constants.begin(), p.constants.end());
  const double c0 = c[slot], h = 1e-6 * std::max(1.0, std::fabs(c0));
  const double f0 = evalDouble(p, c, x)[o];
  c[slot] = c0 + h;
  const double fp = evalDouble(p, c, x)[o];
  c[slot] = c0 - h;
  const double fm = evalDouble(p, c, x)[o];
  CentralDifference cd;
  cd.d = (fp - fm) / (2 * h);
  const double fwd = (fp - f0) / h, bwd = (f0 - fm) / h;
  cd.smooth = std::isfinite(cd.d) && std::fabs(fwd - bwd) <= 1e-4 * (std::fabs(fwd) + 1.0);
  return cd;
}

// float32 partials carry a few ulp (~1e-6 relative, the vecmath bounds) per operator, and the
// float operand values differ from the double ones by as much; 1e-4 relative (plus 1e-4 of
// the scale) leaves a wide margin for that, while any wrong derivative formula is off by O(1).
bool close(double jac, double fd) {
  return std::fabs(jac - fd) <= 1e-4 * (std::fabs(fd) + 1.0);
}

// Distance of the operands of `op` from its kinks and guards (central differences across one
// are meaningless); large when there are none.
double kinkDistance(Op op, const double* v) {
  switch (op) {
    case Op::Min:
    case Op::Max:
    case Op::Select:
      return std::fabs(v[0] - v[1]);
    case Op::Abs:
    case Op::Sqrt:
    case Op::Rsqrt:
    case Op::Log:
    case Op::Log2:
    case Op::Rcp:
      return std::fabs(v[0]);
    case Op::Saturate:
      return std::min(std::fabs(v[0]), std::fabs(v[0] - 1));
    case Op::Div:
      return std::fabs(v[1]);
    case Op::Pow:
      return v[0];  // below 0 pow of the floored base: its exponent reaches the clamp
    default:
      return 1e300;
  }
}

// Bit-identical values, on the first pass over each block and on later passes (which reuse the
// cached constant-free columns), also after the parameters change.
TEST(Jacobian, ValuesAreBitIdenticalToTheInterpreter) {
  ProgramShape shape;
  shape.num_inputs = 3;
  shape.num_outputs = 2;
  shape.max_length = 32;
  shape.output_mode = OutputMode::Designated;
  InitConfig init{8, 32, -3, 3};
  const Table t = randomInputs(3, 2, 300, -4, 4, 5);
  for (int bs : {16, 256}) {
    Dataset ds(t, bs);
    Interpreter interp(bs);
    JacobianEvaluator je;
    for (int trial = 0; trial < 300; ++trial) {
      Rng rng(7000 + trial);
      Program p = randomProgram(shape, init, rng);
      je.bind(p, ds);
      for (int round = 0; round < 2; ++round) {
        if (round == 1) {  // new constants: both evaluators see them
          std::vector<double> x;
          for (int slot : je.parameters()) {
            p.constants[slot] = p.constants[slot] * 1.5f - 0.25f;
            x.push_back(p.constants[slot]);
          }
          je.setParameters(x.data());
        }
        BoundProgram bp;
        bp.bind(p, ds.numInputs());
        for (size_t b = 0; b < ds.numBlocks(); ++b) {
          const auto& outs = interp.evalBlock(bp, ds, b);
          for (bool with_derivatives : {true, false}) {
            je.evalBlock(b, with_derivatives);
            for (size_t o = 0; o < outs.size(); ++o)
              for (int i = 0; i < bs; ++i) {
                const float a = je.value(static_cast<int>(o))[i], e = outs[o][i];
                ASSERT_TRUE(a == e || (std::isnan(a) && std::isnan(e)))
                    << "trial " << trial << " round " << round << " block " << b << " row " << i
                    << ": " << a << " vs " << e;
              }
          }
        }
      }
    }
  }
}

TEST(Jacobian, SetParametersChangesOnlyTheConstants) {
  // mad(x0, c0, c1): after setParameters the values are those of the program with the new
  // constants, bit for bit.
  Program p;
  p.constants = {0.5f, -1.0f, 7.0f};
  p.code = {{Op::Mad, {inputOperand(0), constOperand(2), constOperand(1)}}};
  p.outputs = {0};
  const Table t = randomInputs(1, 1, 40, -2, 2, 3);
  Dataset ds(t, 16);
  JacobianEvaluator je;
  je.bind(p, ds);
  ASSERT_EQ(je.parameters(), (std::vector<int>{1, 2}));  // slot 0 is unused
  const double x[] = {0.25, 3.0};
  je.setParameters(x);
  Program q = p;
  q.constants = {0.5f, 0.25f, 3.0f};
  Interpreter interp(16);
  const auto ref = interp.evaluate(q, ds);
  for (size_t b = 0; b < ds.numBlocks(); ++b) {
    je.evalBlock(b);
    for (size_t r = b * 16; r < std::min<size_t>(ds.rows(), (b + 1) * 16); ++r) {
      EXPECT_EQ(je.value(0)[r - b * 16], ref[0][r]);
      EXPECT_EQ(je.derivative(0, 0)[r - b * 16], 1.0f);                                // d/dc1
      EXPECT_EQ(je.derivative(0, 1)[r - b * 16], static_cast<float>(t.inputs[0][r]));  // d/dc2
    }
  }
}

// For every operator and every operand position: the operand is a constant-dependent value
// u = mad(x0, c0, c1) (pattern A, other operands are inputs), or every differentiable operand
// depends on constants at once (pattern B: u, the constant c4 itself, w = mad(x1, c2, c3)).
// The Jacobian matches central differences at every row away from the operator's kinks.
TEST(Jacobian, EveryOperatorMatchesCentralDifferences) {
  const Table t = randomInputs(4, 1, 400, -1.5, 1.5, 11);
  Dataset ds(t, 64);
  JacobianEvaluator je;
  const std::vector<float> consts = {0.7f, 0.3f, -0.6f, 0.4f, 0.8f};
  for (const OpInfo& info : allOps()) {
    const Op op = info.op;
    const int ar = arity(op);
    for (int pattern = 0; pattern <= ar; ++pattern) {  // 0..ar-1: pattern A at that operand
      SCOPED_TRACE(std::string(info.name) + " pattern " + std::to_string(pattern));
      Program p;
      p.constants = consts;
      p.code.push_back({Op::Mad, {inputOperand(0), constOperand(0), constOperand(1)}});
      p.code.push_back({Op::Mad, {inputOperand(1), constOperand(2), constOperand(3)}});
      Instr ins{op, {}};
      for (int a = 0; a < std::min(ar, kMaxArity); ++a) {  // (the bound quiets GCC)
        if (pattern < ar)
          ins.args[a] = a == pattern ? regOperand(0) : inputOperand(1 + (a + pattern) % 3);
        else
          ins.args[a] = a == 0   ? regOperand(0)
                        : a == 1 ? constOperand(4)
                        : a == 2 ? regOperand(1)
                                 : inputOperand(2);
      }
      p.code.push_back(ins);
      p.outputs = {2};
      const auto jac = jacobian(je, p, ds);
      const std::vector<int>& params = je.parameters();
      int compared = 0;
      for (size_t r = 0; r < ds.rows(); ++r) {
        const double x[4] = {t.inputs[0][r], t.inputs[1][r], t.inputs[2][r], t.inputs[3][r]};
        // Operand values of the tested opcode, in double.
        const std::vector<double> c(consts.begin(), consts.end());
        const double u = x[0] * c[0] + c[1], w = x[1] * c[2] + c[3];
        double v[kMaxArity] = {0, 0, 0, 0};
        for (int a = 0; a < ar; ++a) {
          const Operand& o = ins.args[a];
          v[a] = o.kind == OperandKind::Var     ? x[o.index]
                 : o.kind == OperandKind::Const ? c[o.index]
                 : o.index == 0                 ? u
                                                : w;
        }
        if (kinkDistance(op, v) < 0.05) continue;
        for (size_t k = 0; k < params.size(); ++k) {
          const CentralDifference cd = centralDifference(p, 0, params[k], x);
          ASSERT_TRUE(cd.smooth) << "row " << r;  // away from kinks everything is smooth
          ASSERT_TRUE(close(jac[0][k][r], cd.d))
              << "row " << r << " d/dc" << params[k] << ": " << jac[0][k][r] << " vs " << cd.d;
          ++compared;
        }
      }
      EXPECT_GT(compared, 300);
    }
  }
}

// Random programs over every operator, two outputs: wherever the double program is locally
// smooth in the constant and the float and double values agree (no kink between them), the
// Jacobian matches central differences.
TEST(Jacobian, RandomProgramsMatchCentralDifferences) {
  ProgramShape shape;
  shape.num_inputs = 2;
  shape.num_outputs = 2;
  shape.max_length = 12;
  shape.num_constants = 4;
  shape.output_mode = OutputMode::Designated;
  InitConfig init{3, 12, -2, 2};
  const Table t = randomInputs(2, 2, 64, -2, 2, 17);
  Dataset ds(t, 64);
  JacobianEvaluator je;
  long compared = 0, skipped = 0;
  for (int trial = 0; trial < 300; ++trial) {
    Rng rng(9000 + trial);
    const Program p = randomProgram(shape, init, rng);
    const auto jac = jacobian(je, p, ds);
    const std::vector<int> params = je.parameters();
    ASSERT_EQ(params, effectiveConstants(p));
    for (size_t r = 0; r < ds.rows(); ++r) {
      const double x[2] = {t.inputs[0][r], t.inputs[1][r]};
      const auto ref = evaluateReferenceRow(p, x);
      for (size_t o = 0; o < p.outputs.size(); ++o) {
        const double fv = je.value(static_cast<int>(o))[r];  // the last (only) block
        if (!std::isfinite(ref[o]) || std::fabs(ref[o]) > 1e4 ||
            std::fabs(fv - ref[o]) > 1e-4 * (1 + std::fabs(ref[o]))) {
          ++skipped;
          continue;
        }
        for (size_t k = 0; k < params.size(); ++k) {
          const CentralDifference cd = centralDifference(p, static_cast<int>(o), params[k], x);
          if (!cd.smooth || std::fabs(cd.d) > 1e4) {
            ++skipped;
            continue;
          }
          ASSERT_TRUE(close(jac[o][k][r], cd.d))
              << "trial " << trial << " row " << r << " output " << o << " d/dc" << params[k]
              << ": " << jac[o][k][r] << " vs " << cd.d;
          ++compared;
        }
      }
    }
  }
  EXPECT_GT(compared, 10 * skipped);  // the comparison covers most rows
}

// One-row evaluation of d out / d c0 for the program op(...) at the given input.
float derivativeAt(const Program& p, double x0, int param = 0) {
  Table t = randomInputs(1, 1, 1, 0, 1, 1);
  t.inputs[0][0] = x0;
  Dataset ds(t, 16);
  JacobianEvaluator je;
  je.bind(p, ds);
  je.evalBlock(0);
  return je.derivative(0, param)[0];
}

Program unary(Op op, float c) {  // op(x0 * c0)
  Program p;
  p.constants = {c};
  p.code = {{Op::Mul, {inputOperand(0), constOperand(0)}}, {op, {regOperand(0)}}};
  p.outputs = {1};
  return p;
}

Program binary(Op op, Operand a, Operand b, float c) {
  Program p;
  p.constants = {c};
  p.code = {{op, {a, b}}};
  p.outputs = {0};
  return p;
}

TEST(Jacobian, GuardsClampsAndFloorsHaveZeroDerivative) {
  // Active: the guard holds, the derivative is 0. Inactive (just inside the domain): not 0.
  EXPECT_EQ(derivativeAt(unary(Op::Exp2, 1.0f), 200.0), 0.0f);
  EXPECT_EQ(derivativeAt(unary(Op::Exp2, 1.0f), -200.0), 0.0f);
  EXPECT_NE(derivativeAt(unary(Op::Exp2, 1.0f), 100.0), 0.0f);
  EXPECT_EQ(derivativeAt(unary(Op::Exp, 1.0f), 100.0), 0.0f);  // 100 log2 e > 126
  EXPECT_EQ(derivativeAt(unary(Op::Exp, 1.0f), -100.0), 0.0f);
  EXPECT_NE(derivativeAt(unary(Op::Exp, 1.0f), 80.0), 0.0f);
  EXPECT_EQ(derivativeAt(unary(Op::Sqrt, 1.0f), -2.0), 0.0f);
  EXPECT_EQ(derivativeAt(unary(Op::Sqrt, 1.0f), 0.0), 0.0f);
  EXPECT_EQ(derivativeAt(unary(Op::Rsqrt, 1.0f), -2.0), 0.0f);
  EXPECT_EQ(derivativeAt(unary(Op::Log, 1.0f), -2.0), 0.0f);
  EXPECT_EQ(derivativeAt(unary(Op::Log2, 1.0f), 0.0), 0.0f);
  EXPECT_EQ(derivativeAt(unary(Op::Rcp, 1e-25f), 1.0), 0.0f);  // |a| < kDivGuard
  EXPECT_EQ(derivativeAt(unary(Op::Rcp, -1e-25f), 1.0), 0.0f);
  EXPECT_EQ(derivativeAt(unary(Op::Saturate, 1.0f), 1.5), 0.0f);
  EXPECT_EQ(derivativeAt(unary(Op::Saturate, 1.0f), -0.5), 0.0f);
  EXPECT_FLOAT_EQ(derivativeAt(unary(Op::Saturate, 1.0f), 0.5), 0.5f);
  EXPECT_FLOAT_EQ(derivativeAt(unary(Op::Abs, 1.0f), -0.5), 0.5f);  // d|c x|/dc = x sign(cx)
  EXPECT_FLOAT_EQ(derivativeAt(unary(Op::Abs, -1.0f), -0.5), -0.5f);
  // div(x0, c0): the guard on the divisor zeroes d/dc0 only there.
  EXPECT_EQ(derivativeAt(binary(Op::Div, inputOperand(0), constOperand(0), 1e-25f), 1.0), 0.0f);
  EXPECT_FLOAT_EQ(derivativeAt(binary(Op::Div, inputOperand(0), constOperand(0), 2.0f), 1.0),
                  -0.25f);
  // div(c0, x0) where x0 is tiny: guard(x0) is still a constant divisor, d/dc0 = 1/guard.
  EXPECT_FLOAT_EQ(derivativeAt(binary(Op::Div, constOperand(0), inputOperand(0), 1.0f), 0.0),
                  1e20f);
  // pow(c0, x0) with c0 <= 0: floored base, d/dc0 = 0. pow(x0, c0) with x0 <= 0: the exponent
  // still acts on the floored base (2^(-126 c0)), so d/dc0 = v ln2 (-126).
  EXPECT_EQ(derivativeAt(binary(Op::Pow, constOperand(0), inputOperand(0), -1.0f), 2.0), 0.0f);
  EXPECT_EQ(derivativeAt(binary(Op::Pow, constOperand(0), inputOperand(0), 0.0f), 2.0), 0.0f);
  const float v = sem::apply<Op::Pow, float>(-1.0f, 0.5f, 0, 0);
  EXPECT_FLOAT_EQ(derivativeAt(binary(Op::Pow, inputOperand(0), constOperand(0), 0.5f), -1.0),
                  v * static_cast<float>(sem::kLn2) * -126.0f);
  // pow clamp: b log2 a beyond kExpClamp, both derivatives 0.
  EXPECT_EQ(derivativeAt(binary(Op::Pow, constOperand(0), inputOperand(0), 1e10f), 10.0), 0.0f);
  EXPECT_EQ(derivativeAt(binary(Op::Pow, inputOperand(0), constOperand(0), 10.0f), 1e10), 0.0f);
  // min/max/select: the derivative of the active branch only.
  EXPECT_EQ(derivativeAt(binary(Op::Min, inputOperand(0), constOperand(0), 1.0f), 0.5), 0.0f);
  EXPECT_EQ(derivativeAt(binary(Op::Min, inputOperand(0), constOperand(0), 1.0f), 1.5), 1.0f);
  EXPECT_EQ(derivativeAt(binary(Op::Max, inputOperand(0), constOperand(0), 1.0f), 0.5), 1.0f);
  EXPECT_EQ(derivativeAt(binary(Op::Max, inputOperand(0), constOperand(0), 1.0f), 1.5), 0.0f);
  Program sel;  // select(x0, c0, c0 * 3, x0): the comparison operand has no derivative
  sel.constants = {1.0f, 3.0f};
  sel.code = {{Op::Mul, {constOperand(0), constOperand(1)}},
              {Op::Select, {inputOperand(0), constOperand(0), regOperand(0), inputOperand(0)}}};
  sel.outputs = {1};
  EXPECT_EQ(derivativeAt(sel, 2.0), 3.0f);
  EXPECT_EQ(derivativeAt(sel, 0.0), 0.0f);
}

TEST(Jacobian, ReusedConstantsAndIndependentOutputs) {
  // out0 = x0 c0 + c0 (d/dc0 = x0 + 1), out1 = x0 * x0 (no constant).
  Program p;
  p.constants = {2.0f};
  p.code = {{Op::Mad, {inputOperand(0), constOperand(0), constOperand(0)}},
            {Op::Square, {inputOperand(0)}}};
  p.outputs = {0, 1};
  const Table t = randomInputs(1, 2, 20, -2, 2, 5);
  Dataset ds(t, 16);
  JacobianEvaluator je;
  je.bind(p, ds);
  ASSERT_EQ(je.numParameters(), 1);
  EXPECT_TRUE(je.hasDerivative(0, 0));
  EXPECT_FALSE(je.hasDerivative(1, 0));
  je.evalBlock(0);
  for (int r = 0; r < 16; ++r) {
    EXPECT_EQ(je.derivative(0, 0)[r], static_cast<float>(t.inputs[0][r]) + 1.0f);
    EXPECT_EQ(je.derivative(1, 0)[r], 0.0f);
  }
}

}  // namespace
}  // namespace lgp
