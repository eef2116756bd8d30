// The largest programs and tables a shape allows (255 opcodes, 255 constant slots, 255 inputs)
// evaluate without writing past any buffer: the block interpreter, the Scorer, the Jacobian
// pass and LM agree with the double reference. Before the interpreter sized its operand table
// by inputs + slots, these ran past the table (heap corruption, a crash at free).
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include <nlohmann/json.hpp>

#include "lgp/core/program.hpp"
#include "lgp/core/rng.hpp"
#include "lgp/eval/interpreter.hpp"
#include "lgp/eval/objectives.hpp"
#include "lgp/search/levenberg_marquardt.hpp"

namespace lgp {
namespace {

constexpr int kMax = 255;

// `inputs` columns of `rows` values in [0, 1), and y = sum_i w_i x_i.
Table wideTable(int inputs, int rows) {
  Table t;
  Rng rng(7);
  t.inputs.resize(inputs);
  for (int i = 0; i < inputs; ++i) t.input_names.push_back("x" + std::to_string(i));
  t.output_names = {"y"};
  t.outputs.resize(1);
  for (int r = 0; r < rows; ++r) {
    double y = 0;
    for (int i = 0; i < inputs; ++i) {
      const double x = rng.uniform(0, 1);
      t.inputs[i].push_back(x);
      y += (i % 7 - 3) * 0.01 * x;
    }
    t.outputs[0].push_back(y);
  }
  return t;
}

// A chain of `len` opcodes: r0 = x0 * c0, r_k = mad(x_(k mod inputs), c_(k mod consts), r_(k-1)),
// so every opcode, input and constant slot is effective.
Program chain(int len, int inputs, int consts) {
  Program p;
  p.constants.resize(consts);
  for (int c = 0; c < consts; ++c) p.constants[c] = 0.001f * static_cast<float>(c % 13 - 6);
  p.code.push_back({Op::Mul, {inputOperand(0), constOperand(0)}});
  for (int k = 1; k < len; ++k)
    p.code.push_back(
        {Op::Mad, {inputOperand(k % inputs), constOperand(k % consts), regOperand(k - 1)}});
  p.outputs = {static_cast<uint8_t>(len - 1)};
  return p;
}

ProgramShape shapeFor(int inputs, int len, int consts) {
  ProgramShape s;
  s.num_inputs = inputs;
  s.max_length = len;
  s.num_constants = consts;
  return s;
}

void expectAgrees(const Program& p, const Table& t) {
  ASSERT_TRUE(validate(
      p, shapeFor(static_cast<int>(t.numInputs()), kMax, static_cast<int>(p.constants.size()))));
  const Dataset ds(t, 64);
  Interpreter in(64);
  const auto f = in.evaluate(p, ds);
  const auto d = evaluateReference(p, t);
  for (size_t r = 0; r < t.rows(); ++r) EXPECT_NEAR(f[0][r], d[0][r], 1e-4) << "row " << r;

  Scorer s(ds, ErrorConfig{}, 64);
  const double e = s.error(p);
  EXPECT_TRUE(std::isfinite(e));
  EXPECT_NEAR(e, referenceMetrics(p, t, ErrorConfig{})[0].rmse, 1e-4);

  // LM's Jacobian pass binds every constant of the chain as a parameter (it needs more rows
  // than parameters).
  ConstantFitter fitter(ds, ErrorConfig{});
  Program q = p;
  LevenbergMarquardtConfig lm;
  lm.max_iterations = 2;
  const auto fit = fitter.fit(q, lm);
  EXPECT_GT(fit.evaluations, 0);
  EXPECT_LE(s.error(q), e);
}

TEST(Bounds, MaxInputsConstantsAndOpcodes) {
  const Table t = wideTable(kMax, 320);
  expectAgrees(chain(kMax, kMax, kMax), t);
}

// The shapes the overflow first showed with: 64 and 100 inputs, and 2 inputs with a program
// of more than 63 scratch slots.
TEST(Bounds, ManyInputsSmallProgram) {
  for (int inputs : {64, 100}) {
    const Table t = wideTable(inputs, 48);
    expectAgrees(chain(3, inputs, 2), t);
  }
}

TEST(Bounds, TwoInputsLongProgram) {
  const Table t = wideTable(2, 320);
  for (int len : {62, 64, 66, 130, kMax}) expectAgrees(chain(len, 2, 8), t);
  expectAgrees(chain(kMax, 2, kMax), t);
}

// One interpreter serves programs of every size in turn, growing and reusing its scratch.
TEST(Bounds, InterpreterReusedAcrossSizes) {
  const Table t = wideTable(kMax, 32);
  const Dataset ds(t, 32);
  Interpreter in(32);
  for (int len : {2, kMax, 5, 130, kMax}) {
    const Program p = chain(len, kMax, 1 + len / 2);
    const auto f = in.evaluate(p, ds);
    const auto d = evaluateReference(p, t);
    for (size_t r = 0; r < t.rows(); ++r) ASSERT_NEAR(f[0][r], d[0][r], 1e-4);
  }
}

// A program past the 255-opcode bound is refused naming the bound (hardening round 3): the
// decoder took max_length from the program itself and said "program has 300 opcodes,
// max_length is 300".
TEST(Bounds, AProgramOver255OpcodesIsRefusedNamingTheBound) {
  nlohmann::json code = nlohmann::json::array({{"add", "x0", "x0"}});
  for (int i = 1; i < 300; ++i) code.push_back({"mul", "r" + std::to_string((i - 1) % 255), "x0"});
  ProgramShape shape;
  shape.num_inputs = 1;
  shape.max_length = kMax;
  shape.num_constants = 0;
  auto p = programFromJson({{"code", code}, {"constants", nlohmann::json::array()}}, shape);
  ASSERT_FALSE(p);
  EXPECT_EQ(p.error(), "program: program has 300 opcodes, at most 255 are allowed");
}

}  // namespace
}  // namespace lgp
