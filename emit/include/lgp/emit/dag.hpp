// The emitter's intermediate form: a program's effective opcodes as a hash-consed DAG.
//
// A Program is already a DAG (operands name earlier opcodes), but it may hold duplicate
// opcodes, introns and constant-only sub-expressions. buildDag() keeps only what the outputs
// depend on and merges structurally identical nodes (same op, same operands), so a
// sub-expression is computed once however often the program spelt it. simplify() then folds
// constants with the interpreter's own semantics and applies rewrites (see Simplify below).
// The parser (parser.hpp) builds the same DAG from text and linearises it with toProgram().
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "lgp/core/ops.hpp"
#include "lgp/core/program.hpp"
#include "lgp/core/status.hpp"

namespace lgp::emit {

// Arithmetic the DAG is folded and evaluated in: the float32 interpreter, the double
// reference, or IEEE binary16 (every operation rounded to half, half-sized guards; see
// half.hpp).
enum class Precision : uint8_t { Float, Double, Half };
std::string_view toString(Precision p);
std::optional<Precision> precisionFromString(std::string_view s);

struct Node {
  enum class Kind : uint8_t { Var, Const, Op };
  Kind kind = Kind::Const;
  Op op = Op::Add;   // Kind::Op
  int index = 0;     // Kind::Var: input column
  double value = 0;  // Kind::Const: value (float-representable in Float precision)
  std::array<int, kMaxArity> args{-1, -1, -1, -1};  // Kind::Op: node ids, all < own id
  bool isConst() const { return kind == Kind::Const; }
  bool isOp() const { return kind == Kind::Op; }
  bool isLeaf() const { return kind != Kind::Op; }
};

struct Dag {
  std::vector<Node> nodes;   // topologically ordered: every argument precedes its user
  std::vector<int> outputs;  // node id per output
  int num_inputs = 0;

  // Adds a node, or returns the id of an identical existing one (hash-consing by a linear
  // probe over nodes; DAGs here have at most a few hundred nodes).
  int add(const Node& n);
  int var(int index);
  int constant(double v);
  int op(Op o, std::array<int, kMaxArity> args);
  // Number of references to each node from other reachable nodes and from outputs.
  std::vector<int> useCounts() const;
  // Ids of nodes reachable from the outputs.
  std::vector<uint8_t> reachable() const;
  // A copy with only reachable nodes, renumbered (order kept).
  Dag compact() const;
  int numOps() const;
};

// Effective opcodes of `p` as a DAG; duplicates merged. Constant slots become Const nodes.
Dag buildDag(const Program& p, int num_inputs);

// Linearises a DAG into a Program (constants deduplicated into slots). Outputs that are
// plain inputs or constants get an `add(x, 0)` opcode, since outputs must be opcodes. Uses
// OutputMode::Last when the outputs can be the last k opcodes in order, else Designated.
struct LinearProgram {
  Program program;
  OutputMode output_mode = OutputMode::Last;
};
Expected<LinearProgram> toProgram(const Dag& d);

// Interval [lo, hi] of a node's value over the input domain, plus whether it may be NaN.
struct Interval {
  double lo = -std::numeric_limits<double>::infinity();
  double hi = std::numeric_limits<double>::infinity();
  bool nan = true;  // the value may be NaN (only the whole-line interval of an unknown input
                    // or an operation on non-finite operands)
  bool finite() const { return std::isfinite(lo) && std::isfinite(hi); }
};

// Conservative interval of every node, given one interval per input (the table's domain).
// Real-number interval arithmetic, widened after every operation by a relative 2^-20 (and
// an absolute 2^-126) so that float32 rounding and the interpreter's transcendental error
// stay inside. Inputs without a domain are the whole line.
std::vector<Interval> nodeIntervals(const Dag& d, const std::vector<Interval>& domain);

// True when, for every value in the intervals of its operands, operator `n` never takes a
// protected branch (div/rcp guard, sqrt/rsqrt/log/pow floor, exp clamp, saturate's NaN):
// the raw operator then computes exactly the protected one.
bool provenUnguarded(const Dag& d, int node, const std::vector<Interval>& iv);
// Whether an operator has a protected branch at all.
bool isProtected(Op op);

struct SimplifyOptions {
  Precision precision = Precision::Float;  // arithmetic of constant folding
  // Exact rewrites (results bit-identical, up to the sign of a zero result): x*1, x+0, x-0,
  // x/1, 0-x -> -x, x*-1 -> -x, 1/x -> rcp(x), --x, x + -c -> x - c, x + (-y) -> x - y,
  // mad with a unit factor or a zero addend, constant folding.
  bool exact = true;
  // Value-changing rewrites, applied only where the interval analysis proves the base is
  // >= 0 on the domain: pow(x, 0) -> 1, pow(x, 1) -> x, pow(x, 2|3|4) -> products,
  // pow(x, 0.5) -> sqrt(x). The interpreter computes pow as exp2(b*log2(a)) (a few ulp);
  // the products are correctly rounded, so results move by at most the pow error (README).
  bool pow_rewrites = true;
  std::vector<Interval> domain;  // per input; needed by pow_rewrites
};

// Returns the simplified, compacted DAG.
Dag simplify(const Dag& d, const SimplifyOptions& opts);

// Evaluates every output on one row of inputs in the given precision, with the protected
// semantics (Float: sem::applyDynamic<float>, i.e. bit-identical to the interpreter;
// Double: the reference; Half: half.hpp).
std::vector<double> evaluateRow(const Dag& d, const double* inputs, Precision p);

// Readable infix of every output in the parser's syntax (the `infix` column of ops.hpp):
// nodes used more than once are bound first as `tN = expr; ` in front of the output that
// first needs them. Pure function of the DAG, so emit -> parse -> emit is a fixed point.
std::vector<std::string> dagInfix(const Dag& d, const std::vector<std::string>& input_names);

// Per-op counts of effective operators, and the number of piecewise ones.
int countPiecewise(const Dag& d);
// Cost of the DAG under a per-op cost table (each node once).
double dagCost(const Dag& d, const std::array<double, kNumOps>& cost);

}  // namespace lgp::emit
