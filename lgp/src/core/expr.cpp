// DAG construction, simplification, interval analysis and scalar evaluation (see expr.hpp).
#include "lgp/core/expr.hpp"

#include <algorithm>
#include <bit>
#include <cfloat>
#include <cmath>
#include <cstring>
#include <functional>
#include <map>
#include <string>

#include "lgp/core/half.hpp"
#include "lgp/eval/semantics.hpp"

namespace lgp {

std::string_view toString(Precision p) {
  switch (p) {
    case Precision::Float:
      return "float";
    case Precision::Double:
      return "double";
    case Precision::Half:
      return "half";
  }
  return "float";
}

std::optional<Precision> precisionFromString(std::string_view s) {
  if (s == "float") return Precision::Float;
  if (s == "double") return Precision::Double;
  if (s == "half") return Precision::Half;
  return std::nullopt;
}

// ---------------------------------------------------------------------------------------
// Dag

namespace {
bool sameNode(const Node& a, const Node& b) {
  if (a.kind != b.kind) return false;
  switch (a.kind) {
    case Node::Kind::Var:
      return a.index == b.index;
    case Node::Kind::Const:
      return std::memcmp(&a.value, &b.value, sizeof(double)) == 0;
    case Node::Kind::Op:
      return a.op == b.op && a.args == b.args;
  }
  return false;
}
}  // namespace

namespace {
uint64_t mix(uint64_t h, uint64_t v) {  // splitmix64's finaliser over h ^ v
  uint64_t z = (h ^ v) + 0x9e3779b97f4a7c15ull;
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  return z ^ (z >> 31);
}
// Consistent with sameNode: equal nodes hash alike.
uint64_t nodeHash(const Node& n) {
  uint64_t h = static_cast<uint64_t>(n.kind);
  switch (n.kind) {
    case Node::Kind::Var:
      return mix(h, static_cast<uint64_t>(static_cast<uint32_t>(n.index)));
    case Node::Kind::Const:
      return mix(h, std::bit_cast<uint64_t>(n.value));
    case Node::Kind::Op:
      h = mix(h, static_cast<uint64_t>(n.op));
      for (int a : n.args) h = mix(h, static_cast<uint64_t>(static_cast<uint32_t>(a)));
      return h;
  }
  return h;
}
}  // namespace

int Dag::add(const Node& n) {
  Node c = n;
  if (c.kind == Node::Kind::Op) {
    for (int i = arity(c.op); i < kMaxArity; ++i) c.args[i] = -1;
  } else {
    c.args = {-1, -1, -1, -1};
  }
  if (nodes.size() < kLinearProbeNodes) {
    for (size_t i = 0; i < nodes.size(); ++i)
      if (sameNode(nodes[i], c)) return static_cast<int>(i);
  } else {
    if (indexed_ > nodes.size()) {  // nodes were replaced: start again
      index_.clear();
      indexed_ = 0;
    }
    for (; indexed_ < nodes.size(); ++indexed_)
      index_.emplace(nodeHash(nodes[indexed_]), static_cast<int>(indexed_));
    auto [lo, hi] = index_.equal_range(nodeHash(c));
    int found = -1;
    for (auto it = lo; it != hi; ++it) {
      const int id = it->second;
      if (static_cast<size_t>(id) < nodes.size() && sameNode(nodes[id], c) &&
          (found < 0 || id < found))
        found = id;  // the first identical node, as the linear probe finds it
    }
    if (found >= 0) return found;
  }
  nodes.push_back(c);
  return static_cast<int>(nodes.size() - 1);
}

int Dag::var(int index) {
  Node n;
  n.kind = Node::Kind::Var;
  n.index = index;
  return add(n);
}

int Dag::constant(double v) {
  Node n;
  n.kind = Node::Kind::Const;
  n.value = v;
  return add(n);
}

int Dag::op(Op o, std::array<int, kMaxArity> args) {
  Node n;
  n.kind = Node::Kind::Op;
  n.op = o;
  n.args = args;
  return add(n);
}

std::vector<uint8_t> Dag::reachable() const {
  std::vector<uint8_t> r(nodes.size(), 0);
  for (int o : outputs) r[o] = 1;
  for (int i = static_cast<int>(nodes.size()) - 1; i >= 0; --i) {
    if (!r[i] || !nodes[i].isOp()) continue;
    for (int k = 0; k < arity(nodes[i].op); ++k) r[nodes[i].args[k]] = 1;
  }
  return r;
}

std::vector<int> Dag::useCounts() const {
  std::vector<int> uses(nodes.size(), 0);
  const auto r = reachable();
  for (size_t i = 0; i < nodes.size(); ++i) {
    if (!r[i] || !nodes[i].isOp()) continue;
    for (int k = 0; k < arity(nodes[i].op); ++k) ++uses[nodes[i].args[k]];
  }
  for (int o : outputs) ++uses[o];
  return uses;
}

Dag Dag::compact() const {
  const auto r = reachable();
  Dag out;
  out.num_inputs = num_inputs;
  std::vector<int> map(nodes.size(), -1);
  for (size_t i = 0; i < nodes.size(); ++i) {
    if (!r[i]) continue;
    Node n = nodes[i];
    if (n.isOp())
      for (int k = 0; k < arity(n.op); ++k) n.args[k] = map[n.args[k]];
    map[i] = out.add(n);
  }
  for (int o : outputs) out.outputs.push_back(map[o]);
  return out;
}

int Dag::numOps() const {
  const auto r = reachable();
  int n = 0;
  for (size_t i = 0; i < nodes.size(); ++i) n += (r[i] && nodes[i].isOp()) ? 1 : 0;
  return n;
}

Dag buildDag(const Program& p, int num_inputs) {
  Dag d;
  d.num_inputs = num_inputs;
  const int n = static_cast<int>(p.code.size());
  std::vector<uint8_t> live(n, 0);
  for (uint8_t o : p.outputs)
    if (o < n) live[o] = 1;
  for (int i = n - 1; i >= 0; --i) {
    if (!live[i]) continue;
    const Instr& in = p.code[i];
    for (int k = 0; k < arity(in.op); ++k)
      if (in.args[k].kind == OperandKind::Reg && in.args[k].index < i) live[in.args[k].index] = 1;
  }
  std::vector<int> map(n, -1);
  for (int i = 0; i < n; ++i) {
    if (!live[i]) continue;
    const Instr& in = p.code[i];
    std::array<int, kMaxArity> args{-1, -1, -1, -1};
    for (int k = 0; k < arity(in.op); ++k) {
      const Operand& a = in.args[k];
      switch (a.kind) {
        case OperandKind::Var:
          args[k] = d.var(a.index);
          break;
        case OperandKind::Const:
          args[k] = d.constant(a.index < p.constants.size() ? p.constants[a.index] : 0.0f);
          break;
        case OperandKind::Reg:
          args[k] = a.index < i ? map[a.index] : d.constant(0.0);
          break;
      }
    }
    map[i] = d.op(in.op, args);
  }
  for (uint8_t o : p.outputs) d.outputs.push_back(o < n ? map[o] : d.constant(0.0));
  return d;
}

Expected<LinearProgram> toProgram(const Dag& src) {
  // Operands must name earlier nodes and inputs must be operand indices: a DAG that breaks
  // this (built by hand) is refused rather than read out of bounds.
  for (size_t i = 0; i < src.nodes.size(); ++i) {
    const Node& n = src.nodes[i];
    if (n.kind == Node::Kind::Var && (n.index < 0 || n.index > 255))
      return Status::error("input x" + std::to_string(n.index) + " out of range (0 to 255)");
    if (n.isOp())
      for (int k = 0; k < arity(n.op); ++k)
        if (n.args[k] < 0 || static_cast<size_t>(n.args[k]) >= i)
          return Status::error("DAG node " + std::to_string(i) + ": operand " +
                               std::to_string(n.args[k]) + " is not an earlier node");
  }
  for (int o : src.outputs)
    if (o < 0 || static_cast<size_t>(o) >= src.nodes.size())
      return Status::error("DAG output " + std::to_string(o) + " is not a node");
  Dag d = src;
  // Outputs must be distinct opcodes: a leaf output, or one that repeats an earlier output,
  // gets its own `add(x, -0)` (appended without hash-consing, so copies stay distinct).
  const int zero = d.constant(-0.0);  // x + (-0) = x for every x, -0 included
  std::vector<uint8_t> taken(d.nodes.size() + d.outputs.size(), 0);
  for (int& o : d.outputs) {
    if (d.nodes[o].isOp() && !taken[o]) {
      taken[o] = 1;
      continue;
    }
    Node n;
    n.kind = Node::Kind::Op;
    n.op = Op::Add;
    n.args = {o, zero, -1, -1};
    d.nodes.push_back(n);
    o = static_cast<int>(d.nodes.size() - 1);
    taken.resize(d.nodes.size() + d.outputs.size(), 0);
    taken[o] = 1;
  }
  LinearProgram lp;
  Program& p = lp.program;
  std::vector<int> slot(d.nodes.size(), -1);  // opcode index of an op node
  std::map<uint32_t, int> const_slot;
  std::vector<int> order;
  std::vector<uint8_t> is_output(d.nodes.size(), 0);
  for (int o : d.outputs) is_output[o] = 1;
  // Post-order from the outputs' operands first, outputs last, so that outputs are the last
  // k opcodes whenever no output feeds another.
  // (Iterative: a DAG parsed from a long text can be thousands of nodes deep.)
  std::vector<std::pair<int, int>> stack;  // node, next operand to visit
  auto visit = [&](int root) {
    auto enter = [&](int id) {
      if (slot[id] < 0 && d.nodes[id].isOp()) stack.emplace_back(id, 0);
    };
    enter(root);
    while (!stack.empty()) {
      const int id = stack.back().first;
      if (slot[id] >= 0) {
        stack.pop_back();
        continue;
      }
      const int k = stack.back().second;
      if (k < arity(d.nodes[id].op)) {
        ++stack.back().second;
        enter(d.nodes[id].args[k]);
        continue;
      }
      slot[id] = static_cast<int>(order.size());
      order.push_back(id);
      stack.pop_back();
    }
  };
  for (int o : d.outputs)
    for (int k = 0; k < arity(d.nodes[o].op); ++k) visit(d.nodes[o].args[k]);
  for (int o : d.outputs) visit(o);
  if (order.size() > 255)
    return Status::error("formula too long: " + std::to_string(order.size()) +
                         " opcodes (at most 255)");
  for (int id : order) {
    const Node& n = d.nodes[id];
    Instr in;
    in.op = n.op;
    for (int k = 0; k < arity(n.op); ++k) {
      const Node& a = d.nodes[n.args[k]];
      Operand& opnd = in.args[k];
      if (a.isOp()) {
        opnd = {OperandKind::Reg, static_cast<uint8_t>(slot[n.args[k]])};
      } else if (a.kind == Node::Kind::Var) {
        if (a.index > 255) return Status::error("too many inputs (at most 256)");
        opnd = {OperandKind::Var, static_cast<uint8_t>(a.index)};
      } else {
        const float f = static_cast<float>(a.value);
        const uint32_t bits = std::bit_cast<uint32_t>(f);
        auto it = const_slot.find(bits);
        if (it == const_slot.end()) {
          if (p.constants.size() >= 255)
            return Status::error("formula has more than 255 distinct constants");
          it = const_slot.emplace(bits, static_cast<int>(p.constants.size())).first;
          p.constants.push_back(f);
        }
        opnd = {OperandKind::Const, static_cast<uint8_t>(it->second)};
      }
    }
    p.code.push_back(in);
  }
  for (int o : d.outputs) p.outputs.push_back(static_cast<uint8_t>(slot[o]));
  const size_t k = d.outputs.size();
  bool last = p.code.size() >= k;
  for (size_t j = 0; last && j < k; ++j) last = p.outputs[j] == p.code.size() - k + j;
  lp.output_mode = last ? OutputMode::Last : OutputMode::Designated;
  return lp;
}

// ---------------------------------------------------------------------------------------
// Intervals

std::vector<Interval> nodeIntervals(const Dag& d, const std::vector<Interval>& domain) {
  std::vector<Interval> iv(d.nodes.size());
  for (size_t i = 0; i < d.nodes.size(); ++i) {
    const Node& n = d.nodes[i];
    switch (n.kind) {
      case Node::Kind::Var:
        iv[i] = n.index >= 0 && n.index < static_cast<int>(domain.size())
                    ? inputInterval(domain[n.index])
                    : Interval{};
        break;
      case Node::Kind::Const:
        iv[i] = Interval{n.value, n.value, std::isnan(n.value)};
        break;
      case Node::Kind::Op: {
        Interval a[kMaxArity];
        for (int k = 0; k < arity(n.op) && k < kMaxArity; ++k) a[k] = iv[n.args[k]];
        iv[i] = opInterval(n.op, a);
        break;
      }
    }
  }
  return iv;
}

bool provenUnguarded(const Dag& d, int id, const std::vector<Interval>& iv) {
  const Node& n = d.nodes[id];
  if (!n.isOp()) return true;
  Interval a[kMaxArity];
  for (int k = 0; k < arity(n.op) && k < kMaxArity; ++k) a[k] = iv[n.args[k]];
  return provenUnguarded(n.op, a);
}

// ---------------------------------------------------------------------------------------
// Evaluation

double applyOp(Precision p, Op op, double a, double b, double c, double d) {
  switch (p) {
    case Precision::Float:
      return sem::applyDynamic<float>(op, static_cast<float>(a), static_cast<float>(b),
                                      static_cast<float>(c), static_cast<float>(d));
    case Precision::Double:
      return sem::applyDynamic<double>(op, a, b, c, d);
    case Precision::Half:
      return applyHalf(op, static_cast<float>(a), static_cast<float>(b), static_cast<float>(c),
                       static_cast<float>(d));
  }
  return 0;
}

namespace {
double roundIn(Precision p, double v) {
  switch (p) {
    case Precision::Float:
      return static_cast<float>(v);
    case Precision::Double:
      return v;
    case Precision::Half:
      return roundToHalf(static_cast<float>(v));
  }
  return v;
}
}  // namespace

std::vector<double> evaluateRow(const Dag& d, const double* inputs, Precision p) {
  std::vector<double> v(d.nodes.size(), 0.0);
  for (size_t i = 0; i < d.nodes.size(); ++i) {
    const Node& n = d.nodes[i];
    switch (n.kind) {
      case Node::Kind::Var:  // an input the DAG does not have reads as NaN, not out of bounds
        v[i] = n.index >= 0 && (d.num_inputs <= 0 || n.index < d.num_inputs)
                   ? roundIn(p, inputs[n.index])
                   : std::nan("");
        break;
      case Node::Kind::Const:
        v[i] = roundIn(p, n.value);
        break;
      case Node::Kind::Op: {
        double a[kMaxArity] = {0, 0, 0, 0};
        for (int k = 0; k < arity(n.op) && k < kMaxArity; ++k) a[k] = v[n.args[k]];
        v[i] = applyOp(p, n.op, a[0], a[1], a[2], a[3]);
        break;
      }
    }
  }
  std::vector<double> out;
  for (int o : d.outputs) out.push_back(v[o]);
  return out;
}

// ---------------------------------------------------------------------------------------
// Simplification

namespace {

// Builds the simplified DAG bottom-up, keeping the interval of every node it adds so that
// the proven rewrites can ask about values (expr.hpp states what each rewrite needs).
class Simplifier {
 public:
  Simplifier(const SimplifyOptions& o, Dag& out) : o_(o), out_(out) {}

  int var(int index) {
    return track(out_.var(index), [&] {
      return index < static_cast<int>(o_.domain.size()) ? inputInterval(o_.domain[index])
                                                        : Interval{};
    });
  }
  int constant(double v) {
    return track(out_.constant(v), [&] { return Interval{v, v, std::isnan(v)}; });
  }

  // Builds op(args) in `out`, applying the rewrites and folding.
  int make(Op op, std::array<int, kMaxArity> a) {
    const int ar = arity(op);
    bool all_const = true;
    for (int k = 0; k < ar; ++k) all_const = all_const && node(a[k]).isConst();
    if (all_const) {
      double v[kMaxArity] = {0, 0, 0, 0};
      for (int k = 0; k < ar; ++k) v[k] = node(a[k]).value;
      const double r = applyOp(o_.precision, op, v[0], v[1], v[2], v[3]);
      if (std::isfinite(r)) return constant(r);
    }
    if (o_.exact) {
      const int r = rewrite(op, a);
      if (r >= 0) return r;
    }
    return raw(op, a);
  }

  // pow(x, c) with x >= 0 proven.
  int powRewrite(int base, int expo) {
    const Node& e = node(expo);
    if (!e.isConst()) return -1;
    const double c = e.value;
    if (c == 0) return constant(1.0);
    if (c == 1) return base;
    if (c == 2) return make1(Op::Square, base);
    if (c == 3) return make2(Op::Mul, make1(Op::Square, base), base);
    if (c == 4) return make1(Op::Square, make1(Op::Square, base));
    if (c == 0.5) return make1(Op::Sqrt, base);
    return -1;
  }

  const Interval& iv(int id) const { return iv_[id]; }
  // Whether the node being built may change a zero's sign (no divisor sees it; simplify()).
  void setSignFree(bool on) { sign_free_ = on; }

 private:
  const Node& node(int id) const { return out_.nodes[id]; }
  int make1(Op op, int a) { return make(op, {a, -1, -1, -1}); }
  int make2(Op op, int a, int b) { return make(op, {a, b, -1, -1}); }
  int make3(Op op, int a, int b, int c) { return make(op, {a, b, c, -1}); }

  template <class F>
  int track(int id, F interval) {
    if (id >= static_cast<int>(iv_.size())) {
      iv_.resize(id + 1);
      memo_.resize(id + 1, -1);
      iv_[id] = interval();
    }
    return id;
  }
  int raw(Op op, std::array<int, kMaxArity> a) {
    return track(out_.op(op, a), [&] {
      Interval args[kMaxArity];
      for (int k = 0; k < arity(op) && k < kMaxArity; ++k) args[k] = iv_[a[k]];
      return opInterval(op, args);
    });
  }

  bool isC(int id, double v) const { return node(id).isConst() && node(id).value == v; }
  bool isPosZero(int id) const { return isC(id, 0) && !std::signbit(node(id).value); }
  bool isNegZero(int id) const { return isC(id, 0) && std::signbit(node(id).value); }
  bool isNeg(int id) const { return node(id).isOp() && node(id).op == Op::Neg; }
  bool isOp(int id, Op op) const { return node(id).isOp() && node(id).op == op; }
  bool isNegConst(int id) const { return node(id).isConst() && node(id).value < 0; }
  int arg0(int id) const { return node(id).args[0]; }
  int negConst(int id) { return constant(-node(id).value); }
  bool finite(int id) const { return !iv_[id].nan && iv_[id].finite(); }
  // Which factor of a*b is a constant 0 with the other proven finite (so the product is a
  // zero; 0*Inf is NaN): 0 or 1, else -1.
  int zeroTimesFinite(int a, int b) const {
    if (isC(a, 0) && finite(b)) return 0;
    if (isC(b, 0) && finite(a)) return 1;
    return -1;
  }

  // The value never has its sign bit set (it is >= +0 or NaN-free positive): products,
  // quotients, sums and the like of such values, and the operators that return >= +0.
  bool nonNegSigned(int id) {
    if (memo_[id] >= 0) return memo_[id];
    const Node& n = node(id);
    const Interval& x = iv_[id];
    bool r = false;
    if (n.isConst()) {
      r = !std::signbit(n.value) && !std::isnan(n.value);
    } else if (!n.isOp()) {
      r = !x.nan && x.lo >= 0 && !std::signbit(x.lo);  // a -0 entry makes lo -0 (tableDomain)
    } else if (!x.nan && x.lo > 0) {
      r = true;
    } else {
      const auto& a = n.args;
      switch (opInfo(n.op).nonneg) {
        case OpNonNeg::Always:
          r = !x.nan;
          break;
        case OpNonNeg::IfOperands:  // div: a / guard(b), guard(b) >= +1e-20 when b >= +0
          r = true;
          for (int k = 0; k < arity(n.op) && k < kMaxArity; ++k) r = r && nonNegSigned(a[k]);
          break;
        case OpNonNeg::IfBranches:
          r = nonNegSigned(a[2]) && nonNegSigned(a[3]);
          break;
        case OpNonNeg::Never:  // may be negative, or -0 (x - x is +0, but -0 - +0 is -0)
          break;
      }
    }
    memo_[id] = r;
    return r;
  }
  // The value may be -0 somewhere on the domain (a zero's sign reaches div/rcp's guard, so
  // rewrites must keep it).
  bool mayBeNegZero(int id) {
    if (sign_free_) return false;  // no zero's sign reaches a divisor from here
    const Node& n = node(id);
    if (n.isConst()) return n.value == 0 && std::signbit(n.value);
    if (iv_[id].excludesZero() || nonNegSigned(id)) return false;
    if (n.isOp() && n.op == Op::Add)  // RN(x + y) = -0 only for -0 + -0
      return mayBeNegZero(n.args[0]) && mayBeNegZero(n.args[1]);
    return true;
  }
  // a <= b on the domain, NaN-free, and a tie is never a zero (so min/max returning either
  // operand at a tie gives the same bits).
  bool below(int a, int b) const {
    const Interval &x = iv_[a], &y = iv_[b];
    return !x.nan && !y.nan && x.hi <= y.lo && (sign_free_ || x.hi < y.lo || y.lo > 0 || x.hi < 0);
  }

  int rewrite(Op op, const std::array<int, kMaxArity>& a) {
    const bool dom = o_.domain_rewrites;
    switch (op) {
      case Op::Add:
        if (isNegZero(a[1]) || (isPosZero(a[1]) && !mayBeNegZero(a[0]))) return a[0];
        if (isNegZero(a[0]) || (isPosZero(a[0]) && !mayBeNegZero(a[1]))) return a[1];
        if (isNegConst(a[1])) return make2(Op::Sub, a[0], negConst(a[1]));
        if (isNeg(a[1])) return make2(Op::Sub, a[0], arg0(a[1]));
        if (isNeg(a[0])) return make2(Op::Sub, a[1], arg0(a[0]));
        break;
      case Op::Sub:
        if (isPosZero(a[1]) || (isNegZero(a[1]) && !mayBeNegZero(a[0]))) return a[0];
        if (isNegZero(a[0]) || (isPosZero(a[0]) && (sign_free_ || iv_[a[1]].excludesZero())))
          return make1(Op::Neg, a[1]);
        if (isNegConst(a[1])) return make2(Op::Add, a[0], negConst(a[1]));
        if (isNeg(a[1])) return make2(Op::Add, a[0], arg0(a[1]));
        if (a[0] == a[1] && finite(a[0])) return constant(0.0);
        break;
      case Op::Mul:
        if (isC(a[1], 1)) return a[0];
        if (isC(a[0], 1)) return a[1];
        if (isC(a[1], -1)) return make1(Op::Neg, a[0]);
        if (isC(a[0], -1)) return make1(Op::Neg, a[1]);
        if (isNeg(a[0]) && isNeg(a[1])) return make2(Op::Mul, arg0(a[0]), arg0(a[1]));
        if (isNeg(a[0]) && node(a[1]).isConst()) return make2(Op::Mul, arg0(a[0]), negConst(a[1]));
        if (isNeg(a[1]) && node(a[0]).isConst()) return make2(Op::Mul, negConst(a[0]), arg0(a[1]));
        // A weight fitted to 0: the zero's sign is the constant's when the other factor never
        // has its sign bit set, and matters only where it reaches a divisor.
        if (const int k = zeroTimesFinite(a[0], a[1]);
            k >= 0 && (sign_free_ || nonNegSigned(a[1 - k])))
          return constant(sign_free_ ? 0.0 : node(a[k]).value);
        break;
      case Op::Div:
        if (isC(a[1], 1)) return a[0];
        if (isC(a[1], -1)) return make1(Op::Neg, a[0]);
        if (isC(a[0], 1)) return make1(Op::Rcp, a[1]);
        break;
      case Op::Mad: {
        if (isC(a[0], 1)) return make2(Op::Add, a[1], a[2]);
        if (isC(a[1], 1)) return make2(Op::Add, a[0], a[2]);
        if (isC(a[0], -1)) return make2(Op::Sub, a[2], a[1]);
        if (isC(a[1], -1)) return make2(Op::Sub, a[2], a[0]);
        if (isNegZero(a[2])) return make2(Op::Mul, a[0], a[1]);
        if (isPosZero(a[2])) {
          const Interval f[2] = {iv_[a[0]], iv_[a[1]]};
          if (sign_free_ || opInterval(Op::Mul, f).excludesZero())
            return make2(Op::Mul, a[0], a[1]);
        }
        if ((sign_free_ || iv_[a[2]].excludesZero()) && zeroTimesFinite(a[0], a[1]) >= 0)
          return a[2];
        if (node(a[0]).isConst() && node(a[1]).isConst())
          return make2(Op::Add, make2(Op::Mul, a[0], a[1]), a[2]);
        if (isNeg(a[0]) && isNeg(a[1])) return make3(Op::Mad, arg0(a[0]), arg0(a[1]), a[2]);
        if (isNeg(a[0]) && node(a[1]).isConst())
          return make3(Op::Mad, arg0(a[0]), negConst(a[1]), a[2]);
        if (isNeg(a[1]) && node(a[0]).isConst())
          return make3(Op::Mad, negConst(a[0]), arg0(a[1]), a[2]);
        break;
      }
      case Op::Neg:
        if (isNeg(a[0])) return arg0(a[0]);
        break;
      case Op::Pow:
        // pow(a, b) is exp2(b * log2(a)) with the protected log2 and exp2 (ops.hpp): with a
        // constant base the logarithm folds and a multiply and an exp2 remain, bit for bit.
        if (node(a[0]).isConst()) {
          const double l = applyOp(o_.precision, Op::Log2, node(a[0]).value, 0, 0, 0);
          if (std::isfinite(l)) return make1(Op::Exp2, make2(Op::Mul, a[1], constant(l)));
        }
        break;
      case Op::Square:
        if (isNeg(a[0]) || isOp(a[0], Op::Abs)) return make1(Op::Square, arg0(a[0]));
        break;
      case Op::Abs: {
        if (isNeg(a[0]) || isOp(a[0], Op::Abs)) return make1(Op::Abs, arg0(a[0]));
        if (isOp(a[0], Op::Square)) return a[0];
        const Interval& x = iv_[a[0]];
        if (dom && !x.nan && x.lo >= 0 && !mayBeNegZero(a[0])) return a[0];
        if (dom && !x.nan && (x.hi < 0 || (sign_free_ && x.hi <= 0))) return make1(Op::Neg, a[0]);
        break;
      }
      case Op::Saturate: {
        if (isOp(a[0], Op::Saturate)) return a[0];
        const Interval& x = iv_[a[0]];
        if (dom && x.hi <= 0) return constant(0.0);  // NaN -> 0 as well
        if (dom && !x.nan && x.lo >= 1) return constant(1.0);
        if (dom && !x.nan && x.lo >= 0 && x.hi <= 1 && !mayBeNegZero(a[0])) return a[0];
        break;
      }
      case Op::Min:  // a < b ? a : b
        if (a[0] == a[1]) return a[0];
        if (dom && iv_[a[1]].hi <= iv_[a[0]].lo) return a[1];  // NaN in either gives b too
        if (dom && below(a[0], a[1])) return a[0];
        break;
      case Op::Max:  // a > b ? a : b
        if (a[0] == a[1]) return a[0];
        if (dom && iv_[a[1]].lo >= iv_[a[0]].hi) return a[1];
        if (dom && below(a[1], a[0])) return a[0];
        break;
      case Op::Select: {  // a > b ? c : d
        if (a[2] == a[3] || a[0] == a[1]) return a[3];
        const Interval &x = iv_[a[0]], &y = iv_[a[1]];
        if (dom && !x.nan && !y.nan && x.lo > y.hi) return a[2];
        if (dom && x.hi <= y.lo) return a[3];  // NaN -> d as well
        break;
      }
      default:  // no rewrite of its own (constant operands are folded before): rewrites are
        break;  // optional, a missing one costs an optimisation and never changes a value
    }
    return -1;
  }

  const SimplifyOptions& o_;
  Dag& out_;
  bool sign_free_ = false;    // see setSignFree
  std::vector<Interval> iv_;  // per node of out_
  std::vector<int8_t> memo_;  // nonNegSigned per node; -1 = not yet known
};
}  // namespace

// Per node: whether the sign of a zero value can reach the divisor of a div or rcp (where the
// guard keeps it: 1/guard(+0) = +1e20, 1/guard(-0) = -1e20) through operators that pass a
// zero's sign on. Elsewhere (outputs, comparisons, sums with a nonzero term, abs, exp2, ...)
// +0 and -0 give the same values, so rewrites there may change it.
static std::vector<uint8_t> zeroSignReachesDivisor(const Dag& d, const std::vector<uint8_t>& live) {
  std::vector<uint8_t> sens(d.nodes.size(), 0);
  for (int i = static_cast<int>(d.nodes.size()) - 1; i >= 0; --i) {
    const Node& c = d.nodes[i];
    if (!live[i] || !c.isOp()) continue;
    for (int k = 0; k < arity(c.op) && k < kMaxArity; ++k) {
      bool s = false;
      switch (opInfo(c.op).zero_sign) {
        case OpZeroSign::Reads:
          s = true;
          break;
        case OpZeroSign::DivisorReads:
          s = k == 1 || sens[i];
          break;
        case OpZeroSign::Passes:
          s = sens[i];
          break;
        case OpZeroSign::BranchesPass:
          s = k >= 2 && sens[i];
          break;
        case OpZeroSign::Blocks:  // the same value for +0 and -0
          break;
      }
      if (s) sens[c.args[k]] = 1;
    }
  }
  return sens;
}

Dag simplify(const Dag& d, const SimplifyOptions& opts) {
  Dag out;
  out.num_inputs = d.num_inputs;
  Simplifier s(opts, out);
  std::vector<int> map(d.nodes.size(), -1);
  const auto live = d.reachable();
  const auto sens = zeroSignReachesDivisor(d, live);
  for (size_t i = 0; i < d.nodes.size(); ++i) {
    if (!live[i]) continue;
    const Node& n = d.nodes[i];
    switch (n.kind) {
      case Node::Kind::Var:
        map[i] = s.var(n.index);
        break;
      case Node::Kind::Const: {
        double v = n.value;
        if (opts.precision == Precision::Float) v = static_cast<float>(v);
        if (opts.precision == Precision::Half) v = roundToHalf(static_cast<float>(v));
        map[i] = s.constant(v);
        break;
      }
      case Node::Kind::Op: {
        std::array<int, kMaxArity> a{-1, -1, -1, -1};
        for (int k = 0; k < arity(n.op); ++k) a[k] = map[n.args[k]];
        s.setSignFree(!sens[i]);
        int r = -1;
        if (n.op == Op::Pow && opts.pow_rewrites) {
          const Interval& b = s.iv(a[0]);
          if (!b.nan && b.lo >= 0 && b.hi <= FLT_MAX) r = s.powRewrite(a[0], a[1]);
        }
        map[i] = r >= 0 ? r : s.make(n.op, a);
        break;
      }
    }
  }
  for (int o : d.outputs) out.outputs.push_back(map[o]);
  return out.compact();
}

// ---------------------------------------------------------------------------------------
// Costs

int countPiecewise(const Dag& d) {
  const auto r = d.reachable();
  int n = 0;
  for (size_t i = 0; i < d.nodes.size(); ++i)
    if (r[i] && d.nodes[i].isOp() && opInfo(d.nodes[i].op).piecewise) ++n;
  return n;
}

}  // namespace lgp
