// Text from tables and configs never becomes code (issue 21). Column names, the data path,
// the source and extra header lines with newlines, a trailing backslash (which continues a
// // comment onto the next line), a trigraph ??/ and bytes outside ASCII are emitted in every
// language; the C++ is compiled and run and the shaders are compiled with glslangValidator,
// next to a definition of pwn() that an injected one would collide with. Loaders refuse such
// names with a message that names the field (tests/core/input_hardening_test.cpp).
#include <gtest/gtest.h>

#include <sstream>

#include "../skip.hpp"
#include "emit_test_util.hpp"
#include "lgp/emit/emit.hpp"

namespace lgp::emit {
namespace {

const std::string kInject = "mu\n#include </etc/shadow>\nint pwn(){return 1;}\n//";

EmitInput hostileInput() {
  std::mt19937 rng(21);
  EmitInput in;
  in.program = test::randomProgram(rng, 2, 8, 2, false);
  in.input_names = {kInject, "r\\"};
  in.output_names = {"A\r\nint pwn(){return 1;}\n", "B?\?/"};
  in.table_desc = "/data/" + kInject + "\\";
  return in;
}

EmitOptions hostileOptions(Precision prec) {
  EmitOptions o;
  o.function_name = "f";
  o.precision = prec;
  o.source = "front.json\nint pwn(){return 1;}\n";
  // The last header line, right above the code: a trailing backslash or ??/ would swallow
  // the function's first line.
  o.header_lines = {"\xC2\xB5 \x7f\x1b[2J", "ends in a backslash \\", "ends in a trigraph ?\?/"};
  return o;
}

// Every line that is not a comment, and no comment line ends in a continuation.
void expectNothingInjected(const std::string& code, const std::string& what) {
  std::istringstream lines(code);
  std::string line;
  int n = 0;
  while (std::getline(lines, line)) {
    ++n;
    const bool comment = line.rfind("//", 0) == 0;
    if (!comment) {
      // (A sanitised identifier such as v_mu__include___etc_shadow__int_pwn___ is fine.)
      EXPECT_EQ(line.find("pwn("), std::string::npos) << what << " line " << n << ": " << line;
      EXPECT_EQ(line.find("/etc/shadow"), std::string::npos)
          << what << " line " << n << ": " << line;
    }
    EXPECT_TRUE(line.empty() || line.back() != '\\') << what << " line " << n << ": " << line;
    EXPECT_EQ(line.find("?\?/"), std::string::npos) << what << " line " << n << ": " << line;
    EXPECT_EQ(line.find('\r'), std::string::npos) << what << " line " << n;
    for (unsigned char c : line) EXPECT_TRUE(c >= 0x20 && c < 0x7f) << what << " line " << n;
  }
  // The names are still there to read, escaped.
  EXPECT_NE(code.find("mu%0A#include </etc/shadow>%0Aint pwn(){return 1;}%0A//"), std::string::npos)
      << what << "\n"
      << code.substr(0, 3000);
}

TEST(EmitInjection, CommentTextEscapesWhatCouldEndOrContinueAComment) {
  EXPECT_EQ(commentText("a\nb"), "a%0Ab");
  EXPECT_EQ(commentText("end\\"), "end%5C");
  EXPECT_EQ(commentText("?\?/ ?\? ?"), "?%3F/ ?%3F ?");
  EXPECT_EQ(commentText("50% \xC2\xB5"), "50%25 %C2%B5");
  EXPECT_EQ(commentText("x*y + 0.5 (plain)"), "x*y + 0.5 (plain)");
}

TEST(EmitInjection, HostileNamesCompileAsCommentsInCpp) {
  for (Precision prec : {Precision::Float, Precision::Double}) {
    auto e = emitProgram(hostileInput(), Language::Cpp, hostileOptions(prec));
    ASSERT_TRUE(e.hasValue()) << e.error();
    const std::string what = std::string("cpp ") + std::string(toString(prec));
    expectNothingInjected(e->code, what);
    // pwn() is defined here once; an injected definition would be a redefinition, an
    // injected #include </etc/shadow> an error, and a swallowed line an undefined f().
    const std::string T = prec == Precision::Double ? "double" : "float";
    const std::string src = e->code + "\nint pwn() { return 2; }\nint main() {\n  auto r = f(" + T +
                            "(0.5), " + T +
                            "(0.25));\n  (void)r;\n  return pwn() == 2 ? 0 : 1;\n}\n";
    const auto dir = test::scratchDir("injection");
    const auto file = dir / ("hostile_" + std::string(toString(prec)) + ".cpp");
    test::writeFile(file, src);
    const std::string exe = (dir / ("hostile_" + std::string(toString(prec)))).string();
    // -trigraphs: as a compiler that still reads them (??/ is a backslash).
    for (const char* std_flag : {"-std=c++20", "-std=c++20 -trigraphs"}) {
      const std::string cmd = std::string(LGP_TEST_CXX) + " " + std_flag +
                              " -Wall -Werror=comment -o " + exe + " " + file.string();
      const auto cc = test::runCommand(cmd);
      ASSERT_EQ(cc.rc, 0) << what << ": " << cmd << "\n" << cc.output.substr(0, 4000);
      EXPECT_EQ(test::runCommand(exe).rc, 0) << what;
    }
  }
}

TEST(EmitInjection, HostileNamesCompileAsCommentsInShaders) {
  const std::string tool = LGP_GLSLANG_VALIDATOR;
  struct Variant {
    Language lang;
    Precision prec;
  };
  for (Variant v : {Variant{Language::Glsl, Precision::Float},
                    {Language::Hlsl, Precision::Float},
                    {Language::Hlsl, Precision::Half}}) {
    auto e = emitProgram(hostileInput(), v.lang, hostileOptions(v.prec));
    ASSERT_TRUE(e.hasValue()) << e.error();
    const std::string what = std::string(toString(v.lang)) + " " + std::string(toString(v.prec));
    expectNothingInjected(e->code, what);
    if (tool.empty()) continue;
    const bool hlsl = v.lang == Language::Hlsl;
    const std::string cast = v.prec == Precision::Half ? "(half)" : "";
    const std::string call = "f(" + cast + (hlsl ? "p.x, " : "uv.x, ") + cast +
                             (hlsl ? "p.y)" : "uv.y)") + e->output_access[0];
    const auto dir = test::scratchDir("injection");
    std::filesystem::path file;
    std::string src, cmd;
    const std::string spv = (dir / "hostile.spv").string();
    if (hlsl) {
      src = e->code +
            "\nint pwn() { return 2; }\nfloat4 main(float4 p : SV_Position) : SV_Target {\n"
            "  return float4(float(" +
            call + ") + float(pwn()), 0.0, 0.0, 1.0);\n}\n";
      file = dir / ("hostile_" + std::string(toString(v.prec)) + ".hlsl");
      cmd = tool + " -D -V -S frag -e main -o " + spv + " " + file.string();
    } else {
      src = "#version 450\n" + e->code +
            "\nint pwn() { return 2; }\nlayout(location = 0) in vec2 uv;\n"
            "layout(location = 0) out vec4 color;\n"
            "void main() { color = vec4(float(" +
            call + ") + float(pwn())); }\n";
      file = dir / "hostile.frag";
      cmd = tool + " -V -S frag -o " + spv + " " + file.string();
    }
    test::writeFile(file, src);
    const auto r = test::runCommand(cmd);
    EXPECT_EQ(r.rc, 0) << what << ": " << cmd << "\n" << r.output.substr(0, 4000);
  }
  if (tool.empty())
    LGP_SKIP_UNLESS_REQUIRED()
        << "glslangValidator not found (Debian glslang-tools): the shaders were checked "
           "line by line but not compiled";
}

TEST(EmitInjection, FrontsWithControlCharactersAreRefusedNamingTheField) {
  std::mt19937 rng(3);
  const Program p = test::randomProgram(rng, 2, 6, 1, false);
  nlohmann::json base = {{"format", "lgp-front/1"},
                         {"table", {{"inputs", {"x", "y"}}, {"outputs", {"f"}}, {"rows", 4}}},
                         {"config", {{"data", {{"path", "t.csv"}}}}},
                         {"members",
                          {{{"index", 0},
                            {"program", toJson(p)},
                            {"cost", 1.0},
                            {"error", 0.1},
                            {"outputs", {{{"name", "f"}, {"expression", "x"}}}}}}}};
  ASSERT_TRUE(emitInputFromFront(base, 0).hasValue()) << emitInputFromFront(base, 0).error();
  struct Case {
    nlohmann::json::json_pointer at;
    std::string value;
    std::string field;
  };
  for (const Case& c :
       {Case{"/table/inputs/0"_json_pointer, kInject, "/table/inputs/0"},
        Case{"/table/outputs/0"_json_pointer, "f\r", "/table/outputs/0"},
        Case{"/config/data/path"_json_pointer, "t.csv\nint pwn();", "/config/data/path"}}) {
    nlohmann::json front = base;
    front[c.at] = c.value;
    auto in = emitInputFromFront(front, 0);
    ASSERT_FALSE(in.hasValue()) << c.field;
    EXPECT_NE(in.error().find(c.field), std::string::npos) << in.error();
    EXPECT_NE(in.error().find("control character (0x"), std::string::npos) << in.error();
    EXPECT_EQ(in.error().find("pwn"), std::string::npos) << "the name is quoted: " << in.error();
  }
}

}  // namespace
}  // namespace lgp::emit
