// Exports a program (a front member) as an HLSL, GLSL or C++ function that computes what the
// search scored. See emit/README.md for the languages, the protected helpers, `fast` and the
// measured agreement with the interpreter.
//
// Pipeline: Program -> buildDag (effective opcodes, duplicates merged) -> simplify (constant
// folding with the interpreter's semantics, exact and domain-proven rewrites, proven pow
// rewrites; the same DAG the front prints, lgp/core/formula.hpp) -> render:
// a node used more than once becomes a named local `tN`, single-use sub-expressions are
// inlined, constants print as shortest round-trip literals, protected operators call small
// `lgp_*` helpers emitted in front of the function (each behind an #ifndef guard, so several
// emitted functions can share a file).
#pragma once

#include <array>
#include <cstddef>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "lgp/core/program.hpp"
#include "lgp/core/status.hpp"
#include "lgp/core/table.hpp"
#include "lgp/emit/dag.hpp"
#include "lgp/eval/objectives.hpp"

namespace lgp::emit {

enum class Language { Hlsl, Glsl, Cpp };

// Every language the emitters write, described once: what `lgp emit --lang`, lgpd (?lang= and
// the page's tabs, GET /api/v1/languages) and Python (Member.emit, lgp.languages) accept and
// show. How each is written is decided in emit/src (a switch over Language with no `default:`
// at every decision, so a new language fails to compile until each is made) and in the
// operator table's spelling column (ops.hpp).
struct LanguageInfo {
  Language lang;
  std::string_view name;   // "hlsl"
  std::string_view title;  // "HLSL"
  bool shader;             // GPU code: measured cost (ACO), --verify vulkan, a compute kernel
  bool half;               // --precision half
  bool double_precision;   // --precision double
  bool exact_math;         // --exact-math (the interpreter's own exp2/log2/sin/cos)
};
inline constexpr std::array<LanguageInfo, 3> kLanguages = {{
    {Language::Hlsl, "hlsl", "HLSL", true, true, false, false},
    {Language::Glsl, "glsl", "GLSL", true, true, false, false},
    {Language::Cpp, "cpp", "C++", false, false, true, true},
}};
constexpr const std::array<LanguageInfo, 3>& allLanguages() {
  return kLanguages;
}
const LanguageInfo& languageInfo(Language l);
std::string_view toString(Language l);
// A name of allLanguages() (and "c++" for cpp).
std::optional<Language> languageFromString(std::string_view s);
// "hlsl, glsl or cpp", for messages and help texts.
std::string languageChoices();

struct EmitOptions {
  std::string function_name = "lgp_fit";  // a C identifier
  // float everywhere; half: HLSL (`half`) and GLSL (`float16_t`, which needs
  // GL_EXT_shader_explicit_arithmetic_types_float16), with protection constants sized for
  // binary16 and the error re-measured in half when `table` is set; double: C++ only.
  Precision precision = Precision::Float;
  // Emit the raw operator instead of the protected helper wherever interval analysis on the
  // table's domain proves the protected branch is never taken (a comment lists them).
  bool fast = false;
  // pow(x, 2) -> x*x and friends where x >= 0 is proven (expr.hpp); off = only exact rewrites.
  bool pow_rewrites = true;
  // Remove piecewise operators whose branch never switches on the domain (abs of a value that
  // keeps its sign, saturate of [0, 1], a dominated min/max operand, a constant select): the
  // code then equals the interpreter on the domain only (expr.hpp).
  bool domain_rewrites = true;
  // C++ float only: emit the interpreter's own exp2/log2/sin/cos polynomials (vecmath.hpp)
  // instead of <cmath>, making the function bit-identical to the float32 interpreter.
  bool exact_math = false;
  bool header = true;    // the header comment (table, domain, metrics, costs, piecewise ops)
  bool helpers = true;   // the lgp_* helper definitions (false: defined elsewhere)
  bool includes = true;  // C++: the #include lines
  std::vector<std::string> header_lines;  // extra header lines, e.g. the measured cost
  const Table* table = nullptr;           // if set, the header's error is re-measured on it
  // What `table` is, named in that header line (it is often not the table the search fitted,
  // whose errors the lines above it give); empty: "the given table".
  std::string table_label;
  std::string source;  // free text for the header, e.g. "front.json member 3"

  Status validate(Language lang) const;
};

// Everything the emitter needs about one program.
struct EmitInput {
  Program program;
  std::vector<std::string> input_names;     // table inputs: parameter names
  std::vector<std::string> output_names;    // table outputs: struct fields / comments
  std::vector<TargetTransform> transforms;  // per output; empty = none (the emitted function
                                            // returns invertTransform(T, program output))
  std::vector<Interval> domain;             // per input [lo, hi]; empty = unknown
  std::string table_desc;                   // e.g. "dfg (256 rows)"
  nlohmann::json output_metrics;  // optional, per output {"float32": {...}, "double": {...}}
  nlohmann::json cost_by_target;  // optional, as recorded by the search
};

// The emitted text plus what the header states, for tests and tools.
struct Emitted {
  std::string code;                            // complete text: header, helpers, function
  std::string function;                        // the function alone (header comment included)
  std::vector<std::string> helpers;            // names of the helpers used, e.g. "lgp_div"
  std::vector<std::string> raw_ops;            // ops emitted raw under `fast`
  Dag dag;                                     // the simplified DAG that was rendered
  std::string formula;                         // printFormula of `dag` (the header's Formula:)
  std::array<double, kNumCostTargets> cost{};  // per target, inverse transforms included
  int piecewise = 0;
  // How a caller reads the result: the function's name and return type, and per output the
  // accessor to append to the returned value ("" for a scalar, ".x".. for a vector, ".A" for a
  // struct field).
  std::string function_name;
  std::string return_type;
  int num_inputs = 0;  // parameters, one per table input, in table order
  std::vector<std::string> output_access;
  // The function's I/O-only twin: the same name, signature and return type, returning the
  // inputs the formula reads (cycled over the outputs; 0 when it reads none), without helpers
  // or header. A shader built around it costs what the surrounding I/O costs, so subtracting
  // its cost leaves the formula's own (gpu_cost.hpp).
  std::string io_baseline;
  // Half precision: the constants of the code (as scored, in float32) beyond binary16's range,
  // which are infinite in it, and the non-zero ones below its smallest subnormal, which are 0
  // in it; the header says so, and the member does not suit a half export.
  std::vector<double> half_overflow;
  std::vector<double> half_underflow;
};

Expected<Emitted> emitProgram(const EmitInput& in, Language lang, const EmitOptions& opts);

// The warning about `half_overflow` and `half_underflow` that the header carries and
// `lgp emit` prints ("" when there is none).
std::string halfRangeWarning(const Emitted& e);

// A program fitted on `t`: its input and output names and domain (no transforms, no metrics).
EmitInput emitInputForTable(const Program& p, const Table& t);

// Member `member` of a front.json ("lgp-front/1"): program, names, transforms, domain and
// metrics are taken from the front. Errors name the bad field.
Expected<EmitInput> emitInputFromFront(const nlohmann::json& front, size_t member);
// The same for any entry of the front with a "program" (a member, or a scored reference);
// `path` names it in errors (e.g. "/references/2").
Expected<EmitInput> emitInputFromFrontEntry(const nlohmann::json& front,
                                            const nlohmann::json& entry, const std::string& path);
Expected<std::string> emitFromFront(const nlohmann::json& front, size_t member, Language lang,
                                    const EmitOptions& opts);

// Member selection for `lgp emit` and lgpd. At most one criterion may be set; with none,
// the member with the lowest error. max_error: the cheapest member with error <= E (ties:
// lower error). max_cost: the most accurate member with cost <= C (ties: lower cost). Cost
// is the member's "cost" (the run's cost model), or cost_by_target[cost_target] if set.
struct MemberSelector {
  std::optional<size_t> index;
  std::optional<double> max_error;
  std::optional<double> max_cost;
  std::string cost_target;  // empty = the run's cost model
};
Expected<size_t> selectMember(const nlohmann::json& front, const MemberSelector& sel);

// Text made safe for a // comment of HLSL, GLSL or C++: bytes outside printable ASCII, '%'
// and '\\' become %XX, and a '?' that follows a '?' becomes %3F, so no newline, line
// continuation or trigraph can end the comment or continue it onto code.
std::string commentText(std::string_view text);

// A C identifier made from a column name ("n.v" -> "n_v", "2x" -> "_2x"), never a keyword of
// HLSL, GLSL or C++.
std::string sanitizeIdentifier(std::string_view name);

}  // namespace lgp::emit
