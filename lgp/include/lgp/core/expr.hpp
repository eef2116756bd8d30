// A program's effective opcodes as a hash-consed expression DAG, its simplifier and its scalar
// evaluator. One form for everything that reads a formula: the formula printer (formula.hpp),
// the front JSON and `lgp front`, `lgp score`, the emitters and the parser (emit/).
//
// A Program is already a DAG (operands name earlier opcodes), but it may hold duplicate
// opcodes, introns and constant-only sub-expressions. buildDag() keeps only what the outputs
// depend on and merges structurally identical nodes (same op, same operands), so a
// sub-expression is computed once however often the program spelt it. simplify() then folds
// constants with the interpreter's own semantics and applies the rewrites below.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include "lgp/core/interval.hpp"
#include "lgp/core/ops.hpp"
#include "lgp/core/program.hpp"
#include "lgp/core/status.hpp"

namespace lgp {

// Arithmetic the DAG is folded and evaluated in: the float32 interpreter, the double
// reference, or IEEE binary16 (every operation rounded to half, half-sized guards; half.hpp).
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

  // Adds a node, or returns the id of an identical existing one (hash-consing: a linear
  // probe while the DAG is small, a hash index beyond kLinearProbeNodes nodes, so building
  // a DAG of n nodes is O(n) however long the parsed text was).
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

  static constexpr size_t kLinearProbeNodes = 64;

 private:
  // Hash of node -> id, covering nodes[0, indexed_); nodes appended directly (toProgram's
  // distinct output copies) are indexed on the next add. Entries are verified on a hit.
  std::unordered_multimap<uint64_t, int> index_;
  size_t indexed_ = 0;
};

// Effective opcodes of `p` as a DAG; duplicates merged. Constant slots become Const nodes.
Dag buildDag(const Program& p, int num_inputs);

// Linearises a DAG into a Program (constants deduplicated into slots). Outputs that are
// plain inputs or constants get an `add(x, -0)` opcode (exactly x, and removed by simplify),
// since outputs must be opcodes. Uses
// OutputMode::Last when the outputs can be the last k opcodes in order, else Designated.
struct LinearProgram {
  Program program;
  OutputMode output_mode = OutputMode::Last;
};
Expected<LinearProgram> toProgram(const Dag& d);

// Conservative interval of every node (interval.hpp), given one interval per input.
std::vector<Interval> nodeIntervals(const Dag& d, const std::vector<Interval>& domain);
// provenUnguarded (interval.hpp) of node `node`.
bool provenUnguarded(const Dag& d, int node, const std::vector<Interval>& iv);
// Whether an operator has a protected branch at all (the table's `guarded` column).
constexpr bool isProtected(Op op) {
  return opInfo(op).guarded;
}

// The simplifier. Bound: on every row whose inputs lie in `domain` (every row of the table the
// domain was taken from), the simplified DAG evaluated in float32 gives the original's values
// (the interpreter's) bit for bit, except where pow_rewrites apply (there a value moves by at
// most the pow error; see below). The one liberty: a zero may come out as -0 instead of +0 (or
// back) where its sign reaches no div/rcp divisor (the guard keeps a zero's sign there; every
// other operator, comparison and metric treats +0 and -0 alike). Without a domain the identity
// holds for every input. Rewrites (each applied bottom-up while the DAG is rebuilt):
//   always   constant folding in `precision` (the interpreter's float semantics by default);
//            --x -> x; x*1, x/1, x-0 -> x; x*-1, x/-1 -> -x; 1/x -> rcp(x); x + -c -> x - c,
//            x - -c -> x + c, x + (-y) -> x - y, (-y) + x -> x - y, x - (-y) -> x + y;
//            (-x)*c -> x*(-c); (-x)*(-y) -> x*y; abs(-x) -> abs(x); (-x)^2 -> x^2;
//            abs(abs x), saturate(saturate x) -> inner; min(x, x), max(x, x) -> x;
//            select(a, b, c, c) -> c; select(a, a, c, d) -> d; mad(1, x, y) -> x + y;
//            mad(-1, x, y) -> y - x; mad(c1, c2, y) -> (c1*c2) + y;
//            pow(c, x) -> exp2(x * log2(c)) (pow's own definition, the log2 folded).
//   proven   by the intervals (`domain`; without it only what holds on the whole line):
//            x + 0 -> x and mad(a, b, 0) -> a*b where the sum cannot be -0 or its sign is
//            free (above); 0 - x -> -x likewise; mad(0, x, c) -> c where x is finite;
//            abs(x) -> x or -x where x keeps its sign; saturate(x) -> x, 0 or 1 where x stays
//            in [0, 1], <= 0 or >= 1; min/max(a, b) -> the dominating operand; select ->
//            the branch always taken (domain_rewrites).
//   pow      pow(x, 0) -> 1, pow(x, 1) -> x, pow(x, 2|3|4) -> products, pow(x, 0.5) ->
//            sqrt(x) where x >= 0 is proven. The interpreter computes pow as exp2(b*log2(a))
//            (a few ulp); the products are correctly rounded, so results move by at most the
//            pow error (emit/README.md).
struct SimplifyOptions {
  Precision precision = Precision::Float;  // arithmetic of constant folding
  bool exact = true;                       // the "always" and "proven" rewrites
  bool domain_rewrites = true;             // the piecewise removals among the proven ones
  bool pow_rewrites = true;
  std::vector<Interval> domain;  // per input; empty = the whole line
};

// Returns the simplified, compacted DAG.
Dag simplify(const Dag& d, const SimplifyOptions& opts);

// Evaluates every output on one row of inputs in the given precision, with the protected
// semantics (Float: sem::applyDynamic<float>, i.e. bit-identical to the interpreter;
// Double: the reference; Half: half.hpp).
std::vector<double> evaluateRow(const Dag& d, const double* inputs, Precision p);
// One operator in a precision (what evaluateRow and constant folding apply).
double applyOp(Precision p, Op op, double a, double b, double c, double d);

// Number of effective piecewise operators.
int countPiecewise(const Dag& d);

}  // namespace lgp
