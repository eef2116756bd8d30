// Effective-program extraction, pruning, infix, JSON, and validity under variation.
#include <gtest/gtest.h>
#include <algorithm>
#include <nlohmann/json.hpp>

#include "lgp/core/variation.hpp"
#include "lgp/eval/interpreter.hpp"

namespace lgp {
namespace {

constexpr auto X = inputOperand;
constexpr auto C = constOperand;
constexpr auto R = regOperand;

// r0 = x0 * c0      (effective)
// r1 = x1 + x1      (intron)
// r2 = exp2(r0)     (effective)
// r3 = r2 - r0      (effective, output)
Program sample() {
  Program p;
  p.code = {Instr{Op::Mul, {X(0), C(0)}}, Instr{Op::Add, {X(1), X(1)}}, Instr{Op::Exp2, {R(0)}},
            Instr{Op::Sub, {R(2), R(0)}}};
  p.constants = {2.5f, 9.0f};
  p.outputs = {3};
  return p;
}

TEST(Program, EffectiveIndicesSkipIntrons) {
  const Program p = sample();
  EXPECT_EQ(effectiveIndices(p), (std::vector<int>{0, 2, 3}));
  EXPECT_EQ(effectiveConstants(p), (std::vector<int>{0}));
}

TEST(Program, PruneKeepsSemantics) {
  const Program p = sample();
  const Program q = pruneIntrons(p);
  EXPECT_EQ(q.code.size(), 3u);
  ProgramShape s;
  s.num_inputs = 2;
  s.num_constants = 2;
  s.max_length = 8;
  EXPECT_TRUE(validate(q, s)) << validate(q, s).message();
  const double in[2] = {0.3, 0.7};
  EXPECT_DOUBLE_EQ(evaluateReferenceRow(p, in)[0], evaluateReferenceRow(q, in)[0]);
}

TEST(Program, InfixBindsSharedSubexpressionsOnce) {
  const auto s = toInfix(sample(), {"mu", "r"});
  ASSERT_EQ(s.size(), 1u);
  EXPECT_EQ(s[0], "t0 = 2.5*mu; exp2(t0) - t0");  // constant factor first, no parentheses
}

TEST(Program, InfixFoldsNegationsIntoConstants) {
  Program p;
  p.code = {Instr{Op::Neg, {C(0)}}};
  p.constants = {-0.25f};
  p.outputs = {0};
  EXPECT_EQ(toInfix(p, {"x"})[0], "0.25");  // -(-0.25), folded
  // (-7)*x + (-4)*x^2: signs become subtraction, negative literals lose their parentheses.
  Program q;
  q.code = {Instr{Op::Square, {X(0)}}, Instr{Op::Mul, {C(1), R(0)}},
            Instr{Op::Mad, {C(0), X(0), R(1)}}};
  q.constants = {-7.0f, -4.0f};
  q.outputs = {2};
  EXPECT_EQ(toInfix(q, {"x"})[0], "-7*x - 4*x^2");
}

TEST(Program, JsonRoundTrip) {
  const Program p = sample();
  ProgramShape s;
  s.num_inputs = 2;
  s.num_constants = 2;
  s.max_length = 8;
  const auto j = toJson(p);
  EXPECT_EQ(j["code"][0], (nlohmann::json{"mul", "x0", "c0"}));
  auto q = programFromJson(j, s);
  ASSERT_TRUE(q) << q.error();
  EXPECT_EQ(*q, p);
  auto bad = j;
  bad["code"][2][1] = "r5";
  EXPECT_FALSE(programFromJson(bad, s));
  bad = j;
  bad["code"][0][0] = "frobnicate";
  auto e = programFromJson(bad, s);
  ASSERT_FALSE(e);
  EXPECT_NE(e.error().find("frobnicate"), std::string::npos);
}

TEST(Program, ValidateRejectsForwardReferences) {
  Program p = sample();
  p.code[0].args[0] = R(0);
  ProgramShape s;
  s.num_inputs = 2;
  s.num_constants = 2;
  EXPECT_FALSE(validate(p, s));
}

class Variation : public ::testing::TestWithParam<OutputMode> {};

TEST_P(Variation, OperatorsAlwaysYieldValidPrograms) {
  ProgramShape shape;
  shape.num_inputs = 3;
  shape.num_outputs = 2;
  shape.max_length = 24;
  shape.num_constants = 5;
  shape.output_mode = GetParam();
  InitConfig init{2, 24, -2, 2};
  Rng rng(42);
  std::vector<Program> pop;
  for (int i = 0; i < 50; ++i) {
    pop.push_back(randomProgram(shape, init, rng));
    ASSERT_TRUE(validate(pop.back(), shape)) << validate(pop.back(), shape).message();
  }
  for (int it = 0; it < 20000; ++it) {
    const int a = rng.below(50), b = rng.below(50);
    Program c;
    switch (it % 3) {
      case 0:
        c = crossover(pop[a], pop[b], shape, rng);
        break;
      case 1:
        c = pop[a];
        microMutate(c, shape, rng, 0.3, 0.9);
        break;
      case 2:
        c = pop[a];
        macroMutate(c, shape, rng);
        break;
    }
    const Status st = validate(c, shape);
    ASSERT_TRUE(st) << "iteration " << it << ": " << st.message();
    // Canonical genome: unused operand slots are always Operand{} (checkpoints are exact).
    for (const auto& ins : c.code)
      for (int slot = arity(ins.op); slot < kMaxArity; ++slot)
        ASSERT_EQ(ins.args[slot], Operand{}) << "iteration " << it;
    pop[rng.below(50)] = std::move(c);
  }
}

INSTANTIATE_TEST_SUITE_P(Modes, Variation,
                         ::testing::Values(OutputMode::Last, OutputMode::Designated));

// Whether c is a[0, i) + b[k, l) + a[j, n) for some segments of at most 8 opcodes (the
// crossover's shape): every opcode's operator matches, the prefix is a's verbatim, and the
// input and constant operands of the two copied parts are the parents' (register operands are
// renumbered to the new positions). Sets *from_b to the length of b's segment.
bool isSplice(const Program& c, const Program& a, const Program& b, int* from_b) {
  const int na = static_cast<int>(a.code.size()), nb = static_cast<int>(b.code.size());
  const int nc = static_cast<int>(c.code.size());
  // x in the child, y in a parent. A register operand of b's segment that points before the
  // segment may have been out of range at its new place and redrawn (at position 0 as an
  // input or constant), so only the parents' input and constant operands must be kept. A
  // constant operand stays a constant operand with one of the parents' values: crossover
  // carries constants with the structure (variation.hpp), so where both parents' opcodes
  // read one slot the segment's value moves to a free slot, and an opcode of a that no output
  // reads may then see the segment's value.
  auto parentValue = [&](float v) {
    return std::find(a.constants.begin(), a.constants.end(), v) != a.constants.end() ||
           std::find(b.constants.begin(), b.constants.end(), v) != b.constants.end();
  };
  auto sameNonReg = [&](const Instr& x, const Instr& y) {
    if (x.op != y.op) return false;
    for (int q = 0; q < arity(x.op); ++q) {
      const Operand &ox = x.args[q], &oy = y.args[q];
      if (oy.kind == OperandKind::Var && !(ox == oy)) return false;
      if (oy.kind == OperandKind::Const &&
          (ox.kind != OperandKind::Const || !parentValue(c.constants[ox.index])))
        return false;
    }
    return true;
  };
  for (int i = 0; i < na; ++i) {
    bool prefix = i <= nc;
    for (int p = 0; prefix && p < i; ++p) prefix = c.code[p] == a.code[p];
    if (!prefix) break;  // longer prefixes fail too
    for (int j = i + 1; j <= std::min(na, i + 8); ++j)
      for (int k = 0; k < nb; ++k)
        for (int l = k + 1; l <= std::min(nb, k + 8); ++l) {
          if (i + (l - k) + (na - j) != nc) continue;
          bool ok = true;
          for (int p = k; ok && p < l; ++p) ok = sameNonReg(c.code[i + p - k], b.code[p]);
          for (int p = j; ok && p < na; ++p)
            ok = sameNonReg(c.code[i + (l - k) + p - j], a.code[p]);
          if (ok) {
            *from_b = l - k;
            return true;
          }
        }
  }
  return false;
}

TEST(Variation, CrossoverSplicesASegmentOfBIntoA) {
  ProgramShape shape;
  shape.num_inputs = 2;
  shape.num_constants = 4;
  shape.max_length = 32;
  InitConfig init{10, 10, -1, 1};
  Rng rng(3);
  int changed = 0;
  for (int t = 0; t < 200; ++t) {
    const Program a = randomProgram(shape, init, rng);
    const Program b = randomProgram(shape, init, rng);
    const Program c = crossover(a, b, shape, rng);
    int from_b = 0;
    ASSERT_TRUE(isSplice(c, a, b, &from_b)) << "trial " << t;
    EXPECT_GE(from_b, 1);
    EXPECT_LE(from_b, 8);
    // Every constant is one of the parents' values (a slot may have moved, see isSplice).
    ASSERT_EQ(c.constants.size(), a.constants.size());
    for (float v : c.constants)
      EXPECT_TRUE(std::find(a.constants.begin(), a.constants.end(), v) != a.constants.end() ||
                  std::find(b.constants.begin(), b.constants.end(), v) != b.constants.end());
    changed += !(c.code == a.code);
  }
  // Random parents share few opcodes: almost every child differs from a.
  EXPECT_GT(changed, 150);
}

TEST(Variation, RespectsTheAllowedOperatorSet) {
  ProgramShape shape;
  shape.num_inputs = 2;
  shape.ops = OpSet();
  shape.ops.insert(Op::Add);
  shape.ops.insert(Op::Exp2);
  InitConfig init{2, 20, -1, 1};
  Rng rng(8);
  Program p = randomProgram(shape, init, rng);
  for (int i = 0; i < 2000; ++i) {
    microMutate(p, shape, rng, 0.2, 0.5);
    macroMutate(p, shape, rng);
  }
  for (const auto& ins : p.code) EXPECT_TRUE(ins.op == Op::Add || ins.op == Op::Exp2);
}

}  // namespace
}  // namespace lgp
