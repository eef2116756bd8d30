// The formula printer: one readable text for a program, used by the front JSON and CSV,
// `lgp front`, `lgp score`, the emitters' header comments, the quality report and the page.
//
// What it prints is the simplified DAG (expr.hpp; on the table's domain when one is given)
// in the parser's syntax (emit/parser.hpp), with minimal parentheses:
//   a + b, a - b, a*b, a/b, -a, x^2 (square, or x*x), x^3 (x^2*x), x^4 (square of a square),
//   1/x (rcp), a*b + c (mad), a > b ? c : d (select), and function calls for everything
//   else (min, max, abs, saturate, sqrt, rsqrt, exp2, log2, exp, log, pow, sin, cos, lerp).
// Negative constants and negations are pulled to the front of a product and turned into
// subtraction (`-7*mu - 4*r^2`, never `(-7)*mu + (-4)*r^2`); a constant factor is written
// first (`2*x`); a sum whose right operand is itself a sum is written the other way round
// instead of parenthesised (`b + c + a` for a + (b + c)); p/q is written for a constant that
// is exactly the float nearest a simple fraction with a non-decimal denominator (`1/3`).
// All of these are exact in IEEE float32 (negation, commutativity, x + (-y) = x - y), so
// the text, parsed back, evaluates bit-identically to the DAG it was printed from.
//
// Sub-expressions used twice or more (other than inputs, constants and negated leaves) are
// bound to temporaries tN, in dependency order, in front of the outputs.
#pragma once

#include <string>
#include <vector>

#include "lgp/core/expr.hpp"
#include "lgp/core/interval.hpp"
#include "lgp/core/program.hpp"

namespace lgp {

// One statement of a formula: `name = expr`.
struct FormulaStatement {
  std::string name;
  std::string expr;
  int output = -1;  // output index, or -1 for a temporary
};

struct Formula {
  std::vector<FormulaStatement> statements;  // temporaries and outputs, in dependency order
  // "t0 = r^2; A = 1 - t0; B = exp2(-t0)": every statement, joined by "; ".
  std::string text() const;
};

// The whole DAG: shared temporaries first (an output that another output also reads is one
// of them), then `NAME = expr` per output, in order: "t0 = r^2; t1 = exp2(-t0); A = 1 - t1;
// B = t1". Missing output names are y0, y1, ...
Formula printFormula(const Dag& d, const std::vector<std::string>& input_names,
                     const std::vector<std::string>& output_names);

// Per output, a text that stands alone: the temporaries that output needs, then its
// expression ("t0 = x*y; t0 + sin(t0)"). Parsed back with the emit parser (one text per
// output) it gives the same values.
std::vector<std::string> printOutputs(const Dag& d, const std::vector<std::string>& input_names);

// How a program is turned into the DAG that is printed and emitted: buildDag, then simplify
// with every rewrite on, float32 folding and the domain given here (the table's, via
// tableDomain(); empty = the whole line, where only identities that hold for every input
// apply).
SimplifyOptions formulaSimplifyOptions(const std::vector<Interval>& domain);
Dag formulaDag(const Program& p, int num_inputs, const std::vector<Interval>& domain);

// The program as one readable formula: printFormula(formulaDag(...)).text(). This is the
// function to call for a program or a front member (io/result.hpp memberFormula reads a
// front's names and domain for it).
std::string programFormula(const Program& p, const std::vector<std::string>& input_names,
                           const std::vector<std::string>& output_names,
                           const std::vector<Interval>& domain = {});

}  // namespace lgp
