// Infix formula parser: the emitter's inverse. Turns the printed infix of a front (or a
// hand-written / published formula) into a Program over the same operator table.
//
// Grammar (whitespace and // or /* */ comments are ignored):
//   formula    := statement { (';' | newline) statement } [';']
//   statement  := [type] NAME '=' expr        (let: NAME names the value from here on)
//              |  'return' expr | expr        (type: float half double const auto)
//   expr       := compare [ '?' expr ':' expr ]    a > b ? c : d  -> select(a, b, c, d)
//   compare    := additive [ ('>' | '<' | '>=' | '<=') additive ]   (only before '?')
//   additive   := term { ('+' | '-') term }
//   term       := unary { ('*' | '/') unary }
//   unary      := ('-' | '+') unary | power
//   power      := primary [ '^' unary ]
//   primary    := NUMBER | NAME | NAME '(' expr { ',' expr } ')' | '(' expr ')'
// Newlines separate statements only outside parentheses and after a complete operand, so a
// line ending in an operator continues on the next line.
//
// Meaning:
//   - `/` is the protected div; a literal 1 divided by x is rcp(x) (identical semantics).
//   - `a*b + c` and `c + a*b`, with the product not in parentheses, become mad(a, b, c): the
//     same value (mad rounds twice), and what a shader compiler emits. `(a*b) + c` stays
//     mul then add, which is what the printed infix of such a program looks like.
//   - x^n: n = 1 -> x, 2 -> square(x), 3 -> square(x)*x, 4 -> square(square(x)); other
//     exponents -> pow(x, n).
//   - Functions: every op name of ops.hpp with its arity (add ... select), plus aliases:
//     fabs -> abs, fmin/fmax -> min/max, fma -> mad, mix -> lerp, inversesqrt -> rsqrt,
//     sqr -> square, the C `f` variants (exp2f, sqrtf, ...), `std::` and `lgp_` prefixes
//     (the emitted helpers), clamp(x, lo, hi) -> saturate(x) for lo = 0, hi = 1, else
//     min(max(x, lo), hi), and the casts float()/half()/double() as the identity.
//     float2/float3/float4/vec2/vec3/vec4(...) (only as the value of the last statement)
//     give one output per component.
//   - Names: a let-bound name, then a table input (after `aliases`), then xI (input I).
//   - Literals are rounded to float32; operations on constants only are folded with the
//     interpreter's float semantics.
// Outputs (k = number of table outputs): with k texts, text j gives output j (its last
// statement's value) unless every text ends by assigning a distinct table output name, in
// which case they are matched by name. With one text and k > 1: every table output name
// must be assigned (matched by name; the last assignment wins), or the last statement is a
// k-component vector, or the text has exactly k bare expressions (matched by position).
// All texts share one scope, in order, so a later output may use an earlier output's names.
//
// Limits (emit/README.md, "Limits"). Input beyond one is refused with a message that names
// it, before any work that grows with it; nothing the parser is given can crash it:
//   kMaxFormulaBytes   = 65536 bytes: the texts of one formula together. A program has at
//                        most 255 opcodes, which print in a few kilobytes.
//   kMaxFormulaNesting = 256 levels: parentheses, function-call arguments, unary signs and
//                        '? :' branches open at one point of the text (the parser is
//                        recursive descent; this bounds its stack).
//   xI                 = 0 <= I < number of table inputs, read without overflow
//                        ("x2147483648" is out of range, never a negative index).
//   program size       = at most 255 opcodes and 255 distinct constants after folding and
//                        merging (lgp/core/program.hpp), checked when the DAG is linearised.
//   texts              = 1 or k (one per output); any other count is refused before parsing.
// Parsing is linear in the length of the text (the DAG's hash-consing is by a hash index).
#pragma once

#include <cstddef>

#include <map>
#include <string>
#include <vector>

#include "lgp/core/program.hpp"
#include "lgp/core/status.hpp"
#include "lgp/emit/dag.hpp"

namespace lgp::emit {

inline constexpr size_t kMaxFormulaBytes = 65536;
inline constexpr int kMaxFormulaNesting = 256;

struct ParseOptions {
  std::vector<std::string> input_names;        // table inputs
  std::vector<std::string> output_names;       // table outputs (k = their number, >= 1)
  std::map<std::string, std::string> aliases;  // formula name -> table input, e.g. NoV -> mu
  bool fuse_mad = true;                        // a*b + c -> mad (see above)
};

struct ParsedFormula {
  Dag dag;                         // constants folded, nothing else simplified
  Program program;                 // linearised; validated against `shape`
  ProgramShape shape;              // inputs, outputs, length, constants, output mode
  std::vector<std::string> infix;  // dagInfix of the DAG, per output
};

Expected<ParsedFormula> parseFormula(const std::vector<std::string>& texts,
                                     const ParseOptions& opts);

}  // namespace lgp::emit
