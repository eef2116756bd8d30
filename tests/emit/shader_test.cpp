// HLSL and GLSL validation with glslangValidator (Debian glslang-tools; scripts/lgp.sh
// installs it). Random programs over every operator, the published DFG formulas and
// multi-output members are emitted in every variant (float, half, --fast, 1..5 outputs),
// gathered into one shader per variant with an entry point that calls them all, and
// compiled to SPIR-V. Skipped, with a message, only if the tool is missing.
#include <gtest/gtest.h>

#include "../skip.hpp"
#include "emit_test_util.hpp"
#include "lgp/emit/emit.hpp"
#include "lgp/emit/parser.hpp"

namespace lgp::emit {
namespace {

struct Variant {
  std::string name;
  Language lang;
  Precision prec;
  bool fast;
};

std::string validatorPath() {
  return LGP_GLSLANG_VALIDATOR;
}

std::vector<std::pair<Program, std::vector<Interval>>> programs() {
  std::mt19937 rng(99);
  std::vector<std::pair<Program, std::vector<Interval>>> out;
  const std::vector<Interval> any;  // unknown domain: everything protected
  const std::vector<Interval> pos = {Interval{0.25, 4, false}, Interval{0.5, 2, false}};
  for (const auto& info : allOps()) {
    out.emplace_back(test::randomProgram(rng, 2, 3, 1, false, info.op), any);
    out.emplace_back(test::randomProgram(rng, 2, 3, 1, false, info.op), pos);
  }
  // Constants beyond binary16's range: infinite in half, and still valid code.
  Program big;
  big.code.push_back(Instr{Op::Mad, {inputOperand(0), constOperand(0), constOperand(1)}});
  big.constants = {1.0e5f, -7.0e4f};
  big.outputs = {0};
  out.emplace_back(big, any);
  for (int i = 0; i < 60; ++i) {
    const int k = 1 + i % 5;  // 1..5 outputs: scalar, vectors, and a struct
    const int len = std::max(k, std::uniform_int_distribution<int>(3, 14)(rng));
    out.emplace_back(test::randomProgram(rng, 2, len, k, false), i % 2 ? pos : any);
  }
  return out;
}

std::string callExpr(const Variant& v, const std::string& fn, size_t k, size_t idx) {
  const bool hlsl = v.lang == Language::Hlsl;
  const std::string a = hlsl ? "p.x" : "uv.x", b = hlsl ? "p.y" : "uv.y";
  const std::string cast = v.prec == Precision::Half ? "(half)" : "";
  const std::string call = fn + "(" + cast + a + ", " + cast + b + ")";
  const std::string var = "v" + std::to_string(idx);
  if (k == 1) return "  acc += float(" + call + ");\n";
  std::string type =
      k > 4 ? fn + "_result"
            : (hlsl ? (v.prec == Precision::Half ? "half" : "float") + std::to_string(k)
                    : "vec" + std::to_string(k));
  std::string s = "  { " + type + " " + var + " = " + call + "; acc += float(" + var;
  s += k > 4 ? ".o0)" : ".x)";
  s += "; }\n";
  return s;
}

TEST(EmitShaders, HlslAndGlslValidateWithGlslang) {
  const std::string tool = validatorPath();
  if (tool.empty())
    LGP_SKIP_UNLESS_REQUIRED() << "glslangValidator not found: install Debian glslang-tools "
                                  "(scripts/lgp.sh deps) to validate the emitted HLSL/GLSL";
  const auto progs = programs();
  const Table dfg = test::loadDfg();
  std::vector<Program> published;
  for (const std::vector<std::string>& texts :
       {std::vector<std::string>{"qx = 1 - r; a004 = min(qx*qx, exp2(-9.28*NoV))*qx + "
                                 "(-0.0275*r + 0.0425); A = -1.04*a004 + (-0.572*r + 1.04); "
                                 "B = 1.04*a004 + (0.022*r - 0.04)"},
        std::vector<std::string>{"m = r*r; B = exp2(-(7*NoV + 4*m)); A = 1 - B - m*max(B, "
                                 "min(r, 0.739 + 0.323*NoV) - 0.434)"}}) {
    ParseOptions po;
    po.input_names = {"x", "y"};  // emitted with the test's parameter names
    po.output_names = dfg.output_names;
    po.aliases = {{"NoV", "x"}, {"r", "y"}};
    auto pf = parseFormula(texts, po);
    ASSERT_TRUE(pf.hasValue()) << pf.error();
    published.push_back(pf->program);
  }
  const std::vector<Variant> variants = {
      {"hlsl_float", Language::Hlsl, Precision::Float, false},
      {"hlsl_float_fast", Language::Hlsl, Precision::Float, true},
      {"hlsl_half", Language::Hlsl, Precision::Half, false},
      {"hlsl_half_fast", Language::Hlsl, Precision::Half, true},
      {"glsl", Language::Glsl, Precision::Float, false},
      {"glsl_fast", Language::Glsl, Precision::Float, true},
  };
  const auto dir = test::scratchDir("shaders");
  for (const auto& v : variants) {
    std::string body, calls;
    size_t idx = 0;
    auto add = [&](const Program& p, const std::vector<Interval>& dom) {
      EmitInput in;
      in.program = p;
      in.input_names = {"x", "y"};
      for (size_t j = 0; j < p.outputs.size(); ++j)
        in.output_names.push_back("o" + std::to_string(j));
      in.domain = dom;
      EmitOptions o;
      o.function_name = "f" + std::to_string(idx);
      o.precision = v.prec;
      o.fast = v.fast;
      auto e = emitProgram(in, v.lang, o);
      ASSERT_TRUE(e.hasValue()) << e.error();
      body += e->code + "\n";
      calls += callExpr(v, o.function_name, p.outputs.size(), idx);
      ++idx;
    };
    for (const auto& [p, dom] : progs) add(p, dom);
    for (const auto& p : published)
      add(p, {Interval{1.0 / 32, 31.0 / 32, false}, Interval{0, 1, false}});
    std::string src;
    std::filesystem::path file;
    std::string cmd;
    if (v.lang == Language::Hlsl) {
      src = body + "float4 main(float4 p : SV_Position) : SV_Target {\n  float acc = 0.0;\n" +
            calls + "  return float4(acc, 0.0, 0.0, 1.0);\n}\n";
      file = dir / (v.name + ".hlsl");
      // -D: HLSL input. `half` is validated as glslang's default (relaxed-precision float,
      // as DXC without -enable-16bit-types); glslang's --hlsl-enable-16bit-types mode has no
      // float16 overloads of the intrinsics.
      cmd = tool + " -D -V -S frag -e main -o " + (dir / (v.name + ".spv")).string() + " " +
            file.string();
    } else {
      src = "#version 450\n" + body +
            "layout(location = 0) in vec2 uv;\nlayout(location = 0) out vec4 color;\n"
            "void main() {\n  float acc = 0.0;\n" +
            calls + "  color = vec4(acc);\n}\n";
      file = dir / (v.name + ".frag");
      cmd = tool + " -V -S frag -o " + (dir / (v.name + ".spv")).string() + " " + file.string();
    }
    test::writeFile(file, src);
    const auto r = test::runCommand(cmd);
    EXPECT_EQ(r.rc, 0) << v.name << ": " << cmd << "\n" << r.output.substr(0, 4000);
  }
}

}  // namespace
}  // namespace lgp::emit
