// Golden-text tests: formatting, CSE (a shared sub-expression is emitted once), helpers,
// multi-output returns, --fast and half.
#include <gtest/gtest.h>

#include "lgp/emit/emit.hpp"

namespace lgp::emit {
namespace {

constexpr auto X = inputOperand;
constexpr auto C = constOperand;
constexpr auto R = regOperand;
Instr I(Op op, Operand a, Operand b = {}, Operand c = {}, Operand d = {}) {
  Instr in;
  in.op = op;
  in.args = {a, b, c, d};
  return in;
}

EmitInput input(Program p, int k = 1) {
  EmitInput in;
  in.program = std::move(p);
  in.input_names = {"x", "y"};
  for (int j = 0; j < k; ++j) in.output_names.push_back(k == 1 ? "y0" : (j == 0 ? "A" : "B"));
  return in;
}

EmitOptions bare() {
  EmitOptions o;
  o.function_name = "f";
  o.header = false;
  o.helpers = false;
  o.includes = false;
  return o;
}

std::string emitText(const EmitInput& in, Language l, const EmitOptions& o) {
  auto e = emitProgram(in, l, o);
  EXPECT_TRUE(e.hasValue()) << e.error();
  return e ? e->code : "";
}

// t = x * 2.5; out = t + exp2(t)
Program sharedProgram() {
  Program p;
  p.constants = {2.5f};
  p.code = {I(Op::Mul, X(0), C(0)), I(Op::Exp2, R(0)), I(Op::Add, R(0), R(1))};
  p.outputs = {2};
  return p;
}

TEST(EmitGolden, SharedSubexpressionIsOneLocalInEveryLanguage) {
  const auto in = input(sharedProgram());
  EXPECT_EQ(emitText(in, Language::Hlsl, bare()), R"(float f(float x, float y) {
  float t0 = x * 2.5;
  return t0 + lgp_exp2(t0);
}
)");
  EXPECT_EQ(emitText(in, Language::Glsl, bare()), R"(float f(float x, float y) {
  float t0 = x * 2.5;
  return t0 + lgp_exp2(t0);
}
)");
  EXPECT_EQ(emitText(in, Language::Cpp, bare()),
            R"(inline float f(float x, [[maybe_unused]] float y) {
  const float t0 = x * 2.5f;
  return t0 + lgp_exp2(t0);
}
)");
  EmitOptions d = bare();
  d.precision = Precision::Double;
  EXPECT_EQ(emitText(in, Language::Cpp, d),
            R"(inline double f(double x, [[maybe_unused]] double y) {
  const double t0 = x * 2.5;
  return t0 + lgp_exp2(t0);
}
)");
}

TEST(EmitGolden, DuplicateOpcodesAreMerged) {
  Program p;
  p.code = {I(Op::Mul, X(0), X(1)), I(Op::Mul, X(0), X(1)), I(Op::Add, R(0), R(1))};
  p.outputs = {2};
  EXPECT_EQ(emitText(input(p), Language::Hlsl, bare()), R"(float f(float x, float y) {
  float t0 = x * y;
  return t0 + t0;
}
)");
}

TEST(EmitGolden, HelpersAreGuardedAndExact) {
  auto o = bare();
  o.helpers = true;
  EXPECT_EQ(emitText(input(sharedProgram()), Language::Hlsl, o),
            R"(// lgp protected-operator helpers (see lgp emit/README.md)
#ifndef LGP_HELPER_EXP2_FLOAT
#define LGP_HELPER_EXP2_FLOAT
float lgp_exp2(float a) { return exp2(a > 126.0 ? 126.0 : (a < -126.0 ? -126.0 : a)); }
#endif

float f(float x, float y) {
  float t0 = x * 2.5;
  return t0 + lgp_exp2(t0);
}
)");
  Program p;
  p.code = {I(Op::Div, X(0), X(1))};
  p.outputs = {0};
  o.includes = true;
  EXPECT_EQ(emitText(input(p), Language::Cpp, o), R"(#include <algorithm>
#include <cmath>

// lgp protected-operator helpers (see lgp emit/README.md)
#ifndef LGP_HELPER_GUARD_FLOAT
#define LGP_HELPER_GUARD_FLOAT
inline float lgp_guard(float b) { return std::fabs(b) < 1e-20f ? std::copysign(1e-20f, b) : b; }
#endif
#ifndef LGP_HELPER_DIV_FLOAT
#define LGP_HELPER_DIV_FLOAT
inline float lgp_div(float a, float b) { return a / lgp_guard(b); }
#endif

inline float f(float x, float y) {
  return lgp_div(x, y);
}
)");
}

TEST(EmitGolden, MultiOutputReturnsVectorOrStruct) {
  // A = mad(x, y, 1), B = A * A  (A is used twice: a local)
  Program p;
  p.constants = {1.0f};
  p.code = {I(Op::Mad, X(0), X(1), C(0)), I(Op::Square, R(0))};
  p.outputs = {0, 1};
  const auto in = input(p, 2);
  EXPECT_EQ(emitText(in, Language::Hlsl, bare()), R"(float2 f(float x, float y) {
  float t0 = mad(x, y, 1.0);
  return float2(t0, t0 * t0);
}
)");
  EXPECT_EQ(emitText(in, Language::Glsl, bare()), R"(vec2 f(float x, float y) {
  float t0 = x * y + 1.0;
  return vec2(t0, t0 * t0);
}
)");
  EXPECT_EQ(emitText(in, Language::Cpp, bare()), R"(struct f_result { float A; float B; };
inline f_result f(float x, float y) {
  const float t0 = x * y + 1.0f;
  return f_result{t0, t0 * t0};
}
)");
}

TEST(EmitGolden, SimplificationsAndLiterals) {
  // ((x * 1) + 0) - (-0.5)  ->  x + 0.5 ;  pow(y, 2) on y in [0, 1] -> y * y
  Program p;
  p.constants = {1.0f, 0.0f, -0.5f, 2.0f, 0.1f};
  p.code = {I(Op::Mul, X(0), C(0)), I(Op::Add, R(0), C(1)), I(Op::Sub, R(1), C(2)),
            I(Op::Pow, X(1), C(3)), I(Op::Mul, R(2), R(3)), I(Op::Add, R(4), C(4))};
  p.outputs = {5};
  auto in = input(p);
  in.domain = {Interval{-1, 1, false}, Interval{0, 1, false}};
  EXPECT_EQ(emitText(in, Language::Hlsl, bare()), R"(float f(float x, float y) {
  return ((x + 0.5) * (y * y)) + 0.1;
}
)");
  // Without a domain the pow rewrite is not proven: protected pow stays.
  in.domain.clear();
  EXPECT_EQ(emitText(in, Language::Hlsl, bare()), R"(float f(float x, float y) {
  return ((x + 0.5) * lgp_pow(y, 2.0)) + 0.1;
}
)");
}

TEST(EmitGolden, FastEmitsRawOpsOnlyWhereProven) {
  // log2(x) / y with x in [0.5, 2] (unguarded) and y in [-1, 1] (guard reachable).
  Program p;
  p.code = {I(Op::Log2, X(0)), I(Op::Div, R(0), X(1))};
  p.outputs = {1};
  auto in = input(p);
  in.domain = {Interval{0.5, 2, false}, Interval{-1, 1, false}};
  auto o = bare();
  o.fast = true;
  o.header = true;
  auto e = emitProgram(in, Language::Glsl, o);
  ASSERT_TRUE(e.hasValue()) << e.error();
  EXPECT_NE(e->code.find("return lgp_div(log2(x), y);"), std::string::npos) << e->code;
  EXPECT_NE(e->code.find("// --fast: raw log2 (proven never to reach the protection on the "
                         "domain)"),
            std::string::npos)
      << e->code;
  EXPECT_EQ(e->raw_ops, std::vector<std::string>{"log2"});
}

TEST(EmitGolden, HalfUsesHalfTypesLiteralsAndGuards) {
  Program p;
  p.constants = {0.1f};
  p.code = {I(Op::Rcp, X(0)), I(Op::Mul, R(0), C(0))};
  p.outputs = {1};
  auto o = bare();
  o.helpers = true;
  o.precision = Precision::Half;
  EXPECT_EQ(emitText(input(p), Language::Hlsl, o),
            R"(// lgp protected-operator helpers (see lgp emit/README.md)
#ifndef LGP_HELPER_GUARD_HALF
#define LGP_HELPER_GUARD_HALF
half lgp_guard(half b) { return abs(b) < 6.1035156e-05h ? (b < 0.0h ? -6.1035156e-05h : 6.1035156e-05h) : b; }
#endif
#ifndef LGP_HELPER_RCP_HALF
#define LGP_HELPER_RCP_HALF
half lgp_rcp(half a) { return 1.0h / lgp_guard(a); }
#endif

half f(half x, half y) {
  return lgp_rcp(x) * 0.099975586h;
}
)");
}

TEST(EmitGolden, HeaderStatesTableDomainMetricsCostAndPiecewise) {
  Program p;
  p.code = {I(Op::Min, X(0), X(1)), I(Op::Saturate, R(0))};
  p.outputs = {1};
  auto in = input(p);
  in.domain = {Interval{0, 1.5, false}, Interval{0.25, 2, false}};  // both branches switch
  in.table_desc = "dfg, 256 rows";
  in.output_metrics = nlohmann::json::array(
      {{{"float32", {{"rmse", 0.001}, {"max_abs", 0.004}}}, {"double", nullptr}}});
  EmitOptions o;
  o.function_name = "g";
  o.helpers = false;
  auto e = emitProgram(in, Language::Hlsl, o);
  ASSERT_TRUE(e.hasValue()) << e.error();
  EXPECT_EQ(e->function, R"(// g: generated by lgp emit (hlsl, float). Re-emit rather than edit.
// Formula: y0 = saturate(min(x, y))
// Fitted on: dfg, 256 rows; domain x in [0, 1.5], y in [0.25, 2]
// Returns y0
// Error (search, float32): y0 rmse 0.001 max_abs 0.004
// Cost: gpu-generic 1.5, nvidia 1, gcn 1.5, rdna 1.25, cpu 3
// Piecewise ops: 2 (min, saturate)
float g(float x, float y) {
  return saturate(min(x, y));
}
)");
}

TEST(EmitGolden, IdentifiersAreSanitised) {
  EXPECT_EQ(sanitizeIdentifier("n.v"), "n_v");
  EXPECT_EQ(sanitizeIdentifier("2x"), "_2x");
  EXPECT_EQ(sanitizeIdentifier("in"), "in_");
  EXPECT_EQ(sanitizeIdentifier("half"), "half_");
  EXPECT_EQ(sanitizeIdentifier("lgp_div"), "v_lgp_div");
  EXPECT_EQ(sanitizeIdentifier("NoV"), "NoV");
}

TEST(EmitGolden, BadOptionsAreErrorsNamingTheField) {
  auto in = input(sharedProgram());
  EmitOptions o;
  o.function_name = "2bad";
  auto e = emitProgram(in, Language::Hlsl, o);
  ASSERT_FALSE(e.hasValue());
  EXPECT_NE(e.error().find("function name"), std::string::npos);
  o = EmitOptions{};
  o.precision = Precision::Half;
  e = emitProgram(in, Language::Cpp, o);
  ASSERT_FALSE(e.hasValue());
  EXPECT_NE(e.error().find("precision"), std::string::npos);
  o.precision = Precision::Double;
  e = emitProgram(in, Language::Glsl, o);
  ASSERT_FALSE(e.hasValue());
  EXPECT_NE(e.error().find("precision"), std::string::npos);
  in.program.code[0].args[0] = X(5);
  e = emitProgram(in, Language::Hlsl, EmitOptions{});
  ASSERT_FALSE(e.hasValue());
  EXPECT_NE(e.error().find("input x5"), std::string::npos);
  EXPECT_FALSE(languageFromString("metal").has_value());
  EXPECT_EQ(languageFromString("cpp"), Language::Cpp);
}

}  // namespace
}  // namespace lgp::emit
