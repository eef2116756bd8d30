// The SIMD block interpreter agrees with the double reference: operator by operator on edge
// inputs, bit for bit with the per-row scalar path, and end to end on random programs.
#include <gtest/gtest.h>

#include <cfloat>
#include <cmath>
#include <limits>

#include "lgp/core/rng.hpp"
#include "lgp/core/variation.hpp"
#include "lgp/eval/interpreter.hpp"
#include "lgp/eval/semantics.hpp"

namespace lgp {
namespace {

const float kEdge[] = {0.0f,    -0.0f,    1e-45f,   -1e-45f,   FLT_MIN, -FLT_MIN, 1e-20f,
                       -1e-20f, 1e-7f,    0.5f,     -0.5f,     1.0f,    -1.0f,    2.0f,
                       -3.0f,   10.0f,    126.5f,   -200.0f,   1e6f,    1e20f,    -1e20f,
                       3.4e38f, -3.4e38f, INFINITY, -INFINITY, NAN};

bool sameNonFinite(float f, float d) {
  if (std::isnan(f) || std::isnan(d)) return std::isnan(f) && std::isnan(d);
  return f == d;
}

// Tolerance of operator `op` at these (float) operands, from the documented bounds.
double tolerance(Op op, float a, float b, float c, double ref) {
  const double u = std::ldexp(1.0, -23);
  const double r = std::fabs(ref);
  switch (op) {
    // exp(x) = exp2(x log2 e): the rounding of the product adds |x| ulp-ish relative error.
    case Op::Exp2:
      return 2 * u * r + 1e-45;
    case Op::Exp:
      return (2 + std::fabs(static_cast<double>(a))) * u * r + 1e-45;
    case Op::Pow: {
      const double l = std::fabs(static_cast<double>(b) * sem::plog2<double>(a));
      return (4 + 2 * l) * u * r + 1e-45;
    }
    case Op::Log2:
    case Op::Log:
      return 2e-7 + 2 * u * r;
    case Op::Sin:
    case Op::Cos:
      return std::fabs(a) <= 8192 ? 2.5e-7 : 2.0;
    case Op::Mad:
      return u * (std::fabs(static_cast<double>(a) * b) + r) + 1e-45;
    case Op::Lerp:
      return u * (std::fabs(static_cast<double>(a)) +
                  2 * std::fabs((static_cast<double>(b) - a) * c) + r) +
             1e-45;
    case Op::Rsqrt:
    case Op::Rcp:
    case Op::Div:
    case Op::Sqrt:
      return u * r + 1e-45;
    default:  // one IEEE rounding, or a few ulps for an operator the table marks approximate
      return (opInfo(op).rounding == OpRounding::Approx ? 2 : 0.5) * u * r + 1e-45;
  }
}

template <Op OP>
void checkOp() {
  SCOPED_TRACE(std::string(opName(OP)));
  const Kernel k = kernelFor(OP);
  std::vector<float> xs;
  for (float a : kEdge) xs.push_back(a);
  Rng rng(static_cast<uint64_t>(OP) + 11);
  for (int i = 0; i < 200; ++i) xs.push_back(static_cast<float>(rng.uniform(-8, 8)));
  const int n = static_cast<int>(xs.size());
  // All operand combinations (a, b) over edges, c and d drawn from the list too.
  std::vector<float, AlignedAllocator<float>> A, B, C, D;  // kernels require aligned columns
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; j += (arity(OP) >= 2 ? 1 : n)) {
      A.push_back(xs[i]);
      B.push_back(xs[j]);
      C.push_back(xs[(i * 7 + j) % n]);
      D.push_back(xs[(i + 3 * j) % n]);
    }
  while (A.size() % 16) {
    A.push_back(1);
    B.push_back(1);
    C.push_back(1);
    D.push_back(1);
  }
  std::vector<float, AlignedAllocator<float>> out(A.size());
  k(out.data(), A.data(), B.data(), C.data(), D.data(), static_cast<int>(A.size()));
  int failures = 0;
  for (size_t i = 0; i < A.size() && failures < 5; ++i) {
    const float scalar = sem::apply<OP, float>(A[i], B[i], C[i], D[i]);
    const double ref = sem::apply<OP, double>(A[i], B[i], C[i], D[i]);
    const float reff = static_cast<float>(ref);
    // SIMD and scalar float paths are the same code: bit-identical (NaN matches NaN).
    if (!(sameNonFinite(out[i], scalar) || out[i] == scalar)) {
      ADD_FAILURE() << "simd/scalar differ at a=" << A[i] << " b=" << B[i] << ": " << out[i]
                    << " vs " << scalar;
      ++failures;
    }
    // mad and lerp round an intermediate: if that overflows float but not double, the results
    // legitimately differ (inf or NaN against a finite or infinite double).
    const double ia = static_cast<double>(A[i]), ib = B[i], ic = C[i];
    if ((OP == Op::Mad && std::fabs(ia * ib) > 3.4028234e38) ||
        (OP == Op::Lerp && (std::fabs(ib - ia) > 3.4028234e38 ||
                            std::fabs(static_cast<float>(ib - ia) * ic) > 3.4028234e38)))
      continue;
    if (!std::isfinite(out[i]) || !std::isfinite(reff)) {
      if (!sameNonFinite(out[i], reff)) {
        // Float overflow of a value the double path keeps finite is a legal difference only
        // when the double result itself exceeds the float range.
        if (!(std::isinf(out[i]) && std::fabs(ref) > 3.0e38)) {
          ADD_FAILURE() << "finiteness differs at a=" << A[i] << " b=" << B[i] << " c=" << C[i]
                        << ": " << out[i] << " vs ref " << ref;
          ++failures;
        }
      }
      continue;
    }
    const double tol = tolerance(OP, A[i], B[i], C[i], ref);
    if (std::fabs(out[i] - ref) > tol) {
      ADD_FAILURE() << "a=" << A[i] << " b=" << B[i] << " c=" << C[i] << " d=" << D[i] << ": "
                    << out[i] << " vs ref " << ref << " (tol " << tol << ")";
      ++failures;
    }
  }
}

TEST(Interpreter, EveryOperatorMatchesReferenceOnEdgeInputs) {
#define LGP_X_CHECK(E, ...) checkOp<Op::E>();
  LGP_OPS(LGP_X_CHECK)
#undef LGP_X_CHECK
}

TEST(Interpreter, ProtectedOperatorsNeverProduceNaNFromFiniteInputs) {
  for (float a : kEdge) {
    if (!std::isfinite(a)) continue;
    for (float b : kEdge) {
      if (!std::isfinite(b)) continue;
      for (Op op : {Op::Div, Op::Rcp, Op::Sqrt, Op::Rsqrt, Op::Log2, Op::Log, Op::Exp2, Op::Exp,
                    Op::Pow, Op::Sin, Op::Cos, Op::Saturate}) {
        const float v = sem::applyDynamic<float>(op, a, b, a, b);
        EXPECT_FALSE(std::isnan(v)) << opName(op) << "(" << a << ", " << b << ")";
      }
      // log/exp/pow/rsqrt are additionally bounded.
      EXPECT_TRUE(std::isfinite(sem::applyDynamic<float>(Op::Log2, a, b, a, b)));
      EXPECT_TRUE(std::isfinite(sem::applyDynamic<float>(Op::Exp2, a, b, a, b)));
      EXPECT_TRUE(std::isfinite(sem::applyDynamic<float>(Op::Pow, a, b, a, b)));
      EXPECT_TRUE(std::isfinite(sem::applyDynamic<float>(Op::Rsqrt, a, b, a, b)));
    }
  }
}

Table randomTable(int inputs, int rows, double lo, double hi, uint64_t seed) {
  Table t;
  Rng rng(seed);
  for (int i = 0; i < inputs; ++i) {
    t.input_names.push_back("x" + std::to_string(i));
    t.inputs.emplace_back();
    for (int r = 0; r < rows; ++r) t.inputs.back().push_back(rng.uniform(lo, hi));
  }
  t.output_names = {"y"};
  t.outputs = {std::vector<double>(rows, 0.0)};
  return t;
}

TEST(Interpreter, BlockPathEqualsScalarPathBitForBit) {
  ProgramShape shape;
  shape.num_inputs = 3;
  shape.num_outputs = 2;
  shape.max_length = 32;
  shape.output_mode = OutputMode::Designated;
  InitConfig init{8, 32, -3, 3};
  Table t = randomTable(3, 1000, -4, 4, 5);
  t.output_names = {"y0", "y1"};
  t.outputs.assign(2, std::vector<double>(1000, 0.0));
  for (int bs : {16, 64, 256}) {
    Dataset ds(t, bs);
    Interpreter interp(bs);
    for (int trial = 0; trial < 200; ++trial) {
      Rng rng(1000 + trial);
      const Program p = randomProgram(shape, init, rng);
      const auto block = interp.evaluate(p, ds);
      std::vector<std::vector<float>> scalar;
      evaluateScalarRows(p, ds, scalar);
      for (size_t o = 0; o < block.size(); ++o)
        for (size_t r = 0; r < ds.rows(); ++r)
          ASSERT_TRUE(block[o][r] == scalar[o][r] || sameNonFinite(block[o][r], scalar[o][r]))
              << "trial " << trial << " row " << r;
    }
  }
}

TEST(Interpreter, PairFusionIsBitIdenticalAndFusesArithmeticChains) {
  ProgramShape shape;
  shape.num_inputs = 2;
  shape.max_length = 24;
  shape.ops = OpSet();
  for (Op op : {Op::Add, Op::Sub, Op::Mul, Op::Mad, Op::Min, Op::Max, Op::Exp2, Op::Select})
    shape.ops.insert(op);
  InitConfig init{12, 24, -2, 2};
  Table t = randomTable(2, 300, -2, 2, 4);
  Dataset ds(t, 64);
  Interpreter interp(64);
  size_t fused_steps = 0, plain_steps = 0;
  for (int trial = 0; trial < 300; ++trial) {
    Rng rng(500 + trial);
    const Program p = randomProgram(shape, init, rng);
    BoundProgram fused, plain;
    plain.fuse = false;
    fused.bind(p, 2);
    plain.bind(p, 2);
    fused_steps += fused.steps.size();
    plain_steps += plain.steps.size();
    for (size_t b = 0; b < ds.numBlocks(); ++b) {
      const std::vector<float> want(interp.evalBlock(plain, ds, b)[0],
                                    interp.evalBlock(plain, ds, b)[0] + 64);
      const float* got = interp.evalBlock(fused, ds, b)[0];
      for (int i = 0; i < 64; ++i)
        ASSERT_TRUE(got[i] == want[i] || sameNonFinite(got[i], want[i])) << "trial " << trial;
    }
  }
  EXPECT_LT(fused_steps, plain_steps * 9 / 10);  // chains of arithmetic opcodes were fused
}

TEST(Interpreter, RandomProgramsAgreeWithDoubleReference) {
  // Well-conditioned domain: inputs in [0.5, 2]. Rounding differences can still be amplified by
  // cancellation in a random DAG, so the check is on the median row and on the share of rows
  // within 1e-4 relative, per program.
  ProgramShape shape;
  shape.num_inputs = 2;
  shape.max_length = 12;
  InitConfig init{3, 12, 0.5, 2};
  Table t = randomTable(2, 512, 0.5, 2.0, 9);
  Dataset ds(t, 128);
  Interpreter interp(128);
  int checked = 0;
  for (int trial = 0; trial < 300; ++trial) {
    Rng rng(77 + trial);
    const Program p = randomProgram(shape, init, rng);
    const auto f = interp.evaluate(p, ds)[0];
    const auto d = evaluateReference(p, t)[0];
    int good = 0, finite_rows = 0;
    for (size_t r = 0; r < d.size(); ++r) {
      if (!std::isfinite(d[r]) || std::fabs(d[r]) > 1e30) continue;
      ++finite_rows;
      const double rel = std::fabs(f[r] - d[r]) / std::max(1e-6, std::fabs(d[r]));
      if (rel <= 1e-4) ++good;
    }
    if (finite_rows < 100) continue;
    ++checked;
    EXPECT_GE(good, finite_rows * 95 / 100) << "trial " << trial;
  }
  EXPECT_GT(checked, 200);
}

TEST(Interpreter, PaddingDoesNotLeakIntoOutputs) {
  Table t = randomTable(1, 37, 0, 1, 3);
  Dataset ds(t, 16);
  EXPECT_EQ(ds.paddedRows(), 48u);
  EXPECT_EQ(ds.numBlocks(), 3u);
  EXPECT_DOUBLE_EQ(ds.weightSum(), 37.0);
  Program p;
  p.code.push_back(Instr{Op::Square, {Operand{OperandKind::Var, 0}}});
  p.outputs = {0};
  Interpreter interp(16);
  const auto out = interp.evaluate(p, ds);
  ASSERT_EQ(out[0].size(), 37u);
  for (size_t r = 0; r < 37; ++r)
    EXPECT_FLOAT_EQ(out[0][r], static_cast<float>(t.inputs[0][r] * t.inputs[0][r]));
}

}  // namespace
}  // namespace lgp
