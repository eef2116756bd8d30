// Registry coverage of the emitters (structure, round 2): every language of allLanguages()
// writes every operator of allOps() in code that the parser reads back to the same values,
// that the language's compiler accepts where one is here (C++ built and run; HLSL and GLSL
// through glslang and ACO on RADV's null device), and every operator has a measured cost row:
// its single-op program measures a finite RDNA2 instruction count, near the table's price.
// tests/core/registry_coverage_test.cpp covers the rest of each operator's description.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <set>

#include "../skip.hpp"
#include "emit_test_util.hpp"
#include "lgp/emit/emit.hpp"
#include "lgp/emit/gpu_cost.hpp"
#include "lgp/emit/parser.hpp"
#include "lgp/eval/interpreter.hpp"

namespace lgp::emit {
namespace {

const std::vector<std::string> kInputs = {"x", "y", "z", "w"};
// Operands away from every guard and branch: the parsed program must agree exactly there.
const std::vector<Interval> kDomain = {
    {0.5, 1.5, false}, {0.25, 0.75, false}, {-1, 1, false}, {-1, 1, false}};

// The program op(x, y, z, w) (its arity's first operands).
Program singleOp(Op op) {
  Program p;
  Instr in;
  in.op = op;
  // (bounded by kMaxArity too: GCC 12 cannot tell that arity() is, and warns)
  for (int k = 0; k < std::min(arity(op), kMaxArity); ++k) in.args[k] = inputOperand(k);
  p.code = {in};
  p.outputs = {0};
  return p;
}

EmitInput inputOf(Op op) {
  EmitInput in;
  in.program = singleOp(op);
  in.input_names = kInputs;
  in.output_names = {"v"};
  in.domain = kDomain;
  return in;
}

Table sampleTable() {
  Table t;
  t.input_names = kInputs;
  t.output_names = {"v"};
  t.inputs.assign(4, {});
  for (int r = 0; r < 16; ++r) {
    const double u = (r + 0.5) / 16;
    t.inputs[0].push_back(0.5 + u);
    t.inputs[1].push_back(0.75 - 0.5 * u);
    t.inputs[2].push_back(2 * u - 1);
    t.inputs[3].push_back(1 - 2 * u);
  }
  t.outputs.assign(1, std::vector<double>(16, 0.0));
  return t;
}

TEST(EmitRegistry, EveryLanguageIsNamedOnceAndReadsBack) {
  std::set<std::string_view> names;
  for (const auto& l : allLanguages()) {
    EXPECT_TRUE(names.insert(l.name).second) << l.name;
    EXPECT_EQ(languageFromString(l.name), l.lang) << l.name;
    EXPECT_EQ(toString(l.lang), l.name);
    EXPECT_EQ(&languageInfo(l.lang), &l);
    EXPECT_NE(languageChoices().find(l.name), std::string::npos) << languageChoices();
    EmitOptions eo;
    for (Precision p : {Precision::Float, Precision::Half, Precision::Double}) {
      eo.precision = p;
      const bool offered = p == Precision::Float || (p == Precision::Half && l.half) ||
                           (p == Precision::Double && l.double_precision);
      EXPECT_EQ(bool(eo.validate(l.lang)), offered) << l.name << " " << toString(p);
    }
  }
}

TEST(EmitRegistry, EveryOperatorInEveryLanguageParsesBackToItsValues) {
  const Table t = sampleTable();
  for (const auto& l : allLanguages())
    for (const auto& info : allOps()) {
      const EmitInput in = inputOf(info.op);
      EmitOptions eo;
      eo.function_name = "f";
      eo.header = eo.helpers = false;
      auto e = emitProgram(in, l.lang, eo);
      ASSERT_TRUE(e.hasValue()) << l.name << " " << info.name << ": " << e.error();
      const std::string& code = e->code;
      const std::string body =
          code.substr(code.find("{\n") + 2, code.rfind('}') - code.find("{\n") - 2);
      ParseOptions po;
      po.input_names = kInputs;
      po.output_names = {"v"};
      auto pf = parseFormula({body}, po);
      ASSERT_TRUE(pf.hasValue()) << l.name << " " << info.name << ": " << pf.error() << "\n"
                                 << code;
      const auto want = evaluateReference(in.program, t)[0];
      const auto got = evaluateReference(pf->program, t)[0];
      for (size_t r = 0; r < t.rows(); ++r)
        EXPECT_NEAR(got[r], want[r], 1e-6 * std::max(1.0, std::fabs(want[r])))
            << l.name << " " << info.name << " row " << r << "\n"
            << code;
    }
}

TEST(EmitRegistry, EveryOperatorCompilesAndRunsInCpp) {
  // One translation unit: every operator's C++ function (with its helpers), and a main that
  // prints each over the sample rows.
  const Table t = sampleTable();
  std::string src = "#include <cstdio>\n";
  std::string calls;
  for (const auto& info : allOps()) {
    EmitOptions eo;
    eo.function_name = "f_" + std::string(info.name);
    eo.header = false;
    auto e = emitProgram(inputOf(info.op), Language::Cpp, eo);
    ASSERT_TRUE(e.hasValue()) << info.name << ": " << e.error();
    src += e->code + "\n";
    calls += "  for (int r = 0; r < 16; ++r) std::printf(\"%.9g\\n\", " + eo.function_name +
             "(X[r][0], X[r][1], X[r][2], X[r][3]));\n";
  }
  src += "static const float X[16][4] = {";
  for (size_t r = 0; r < t.rows(); ++r) {
    char b[160];
    std::snprintf(b, sizeof b, "{%.9gf, %.9gf, %.9gf, %.9gf},", t.inputs[0][r], t.inputs[1][r],
                  t.inputs[2][r], t.inputs[3][r]);
    src += b;
  }
  src += "};\nint main() {\n" + calls + "}\n";
  const auto dir = test::scratchDir("registry");
  test::writeFile(dir / "all_ops.cpp", src);
  const std::string exe = (dir / "all_ops").string();
  auto cc = test::runCommand(std::string(LGP_TEST_CXX) + " -std=c++20 -O1 -o " + exe + " " +
                             (dir / "all_ops.cpp").string());
  ASSERT_EQ(cc.rc, 0) << cc.output.substr(0, 4000);
  auto run = test::runCommand(exe);
  ASSERT_EQ(run.rc, 0) << run.output;
  std::istringstream out(run.output);
  for (const auto& info : allOps()) {
    const auto want = evaluateReference(singleOp(info.op), t)[0];
    for (size_t r = 0; r < t.rows(); ++r) {
      double v = 0;
      ASSERT_TRUE(out >> v) << info.name;
      EXPECT_NEAR(v, want[r], 1e-5 * std::max(1.0, std::fabs(want[r]))) << info.name << " row "
                                                                          << r;
    }
  }
}

TEST(EmitRegistry, EveryOperatorCompilesForTheGpuAndHasAMeasuredCostRow) {
  const auto st = isaBackendStatus();
  if (!st.available) LGP_SKIP_UNLESS_REQUIRED() << "no ISA measurement here: " << st.detail;
  for (const auto& l : allLanguages()) {
    if (!l.shader) continue;
    for (const auto& info : allOps()) {
      MeasureOptions o;
      o.families = {GpuFamily::Rdna2};
      o.lang = l.lang;
      auto m = measureProgram(inputOf(info.op), o);
      ASSERT_TRUE(m.hasValue()) << l.name << " " << info.name << ": " << m.error();
      const double isa = (*m)["rdna2"]["instructions"].get<double>();
      EXPECT_TRUE(std::isfinite(isa) && isa >= 0) << l.name << " " << info.name;
      // The table's RDNA2 price (a least-squares fit over random programs, guards proven away
      // here as in the measurement) against this op's own count: within 2.5 instructions.
      if (l.lang == Language::Hlsl) {
        EXPECT_NEAR(info.cost[static_cast<int>(CostTarget::Rdna)], isa, 2.5) << info.name;
      }
    }
  }
}

}  // namespace
}  // namespace lgp::emit
