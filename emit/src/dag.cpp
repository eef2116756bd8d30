// DAG construction, simplification, interval analysis and scalar evaluation (see dag.hpp).
#include "lgp/emit/dag.hpp"

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <functional>
#include <map>
#include <string>

#include "lgp/emit/half.hpp"
#include "lgp/eval/semantics.hpp"

namespace lgp::emit {

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

int Dag::add(const Node& n) {
  Node c = n;
  if (c.kind == Node::Kind::Op) {
    for (int i = arity(c.op); i < kMaxArity; ++i) c.args[i] = -1;
  } else {
    c.args = {-1, -1, -1, -1};
  }
  for (size_t i = 0; i < nodes.size(); ++i)
    if (sameNode(nodes[i], c)) return static_cast<int>(i);
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
  Dag d = src;
  // Outputs must be distinct opcodes: a leaf output, or one that repeats an earlier output,
  // gets its own `add(x, 0)` (appended without hash-consing, so copies stay distinct).
  const int zero = d.constant(0.0);
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
  std::function<void(int)> visit = [&](int id) {
    if (slot[id] >= 0 || !d.nodes[id].isOp()) return;
    for (int k = 0; k < arity(d.nodes[id].op); ++k) visit(d.nodes[id].args[k]);
    slot[id] = static_cast<int>(order.size());
    order.push_back(id);
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

namespace {
constexpr double kInf = std::numeric_limits<double>::infinity();

Interval whole() {
  return Interval{-kInf, kInf, true};
}

// Outward widening for float rounding; magnitudes beyond FLT_MAX may be inf in float.
Interval widen(Interval v) {
  if (std::isnan(v.lo) || std::isnan(v.hi)) return whole();
  const double m = std::max(std::fabs(v.lo), std::fabs(v.hi));
  if (std::isfinite(m)) {
    const double w = m * 0x1p-20 + 0x1p-126;
    v.lo -= w;
    v.hi += w;
  }
  if (v.lo < -FLT_MAX) v.lo = -kInf;
  if (v.hi > FLT_MAX) v.hi = kInf;
  return v;
}

Interval mk(double lo, double hi, bool nan) {
  if (std::isnan(lo) || std::isnan(hi)) return whole();
  return Interval{lo, hi, nan};
}

Interval ivAdd(Interval a, Interval b) {
  return mk(a.lo + b.lo, a.hi + b.hi, a.nan || b.nan || !a.finite() || !b.finite());
}
Interval ivNeg(Interval a) {
  return Interval{-a.hi, -a.lo, a.nan};
}
Interval ivSub(Interval a, Interval b) {
  return ivAdd(a, ivNeg(b));
}
Interval ivMul(Interval a, Interval b) {
  const double p[4] = {a.lo * b.lo, a.lo * b.hi, a.hi * b.lo, a.hi * b.hi};
  double lo = kInf, hi = -kInf;
  for (double v : p) {
    if (std::isnan(v)) return whole();
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  }
  return mk(lo, hi, a.nan || b.nan || !a.finite() || !b.finite());
}
// Protected reciprocal: 1/guard(b).
Interval ivRcp(Interval b) {
  const double g = kDivGuard;
  if (b.lo > 0) {
    const double lo = std::max(b.lo, g);
    return mk(1.0 / std::max(b.hi, lo), 1.0 / lo, b.nan);
  }
  if (b.hi < 0) {
    const double hi = std::min(b.hi, -g);
    return mk(1.0 / hi, 1.0 / std::min(b.lo, hi), b.nan);
  }
  return Interval{-1.0 / g, 1.0 / g, b.nan};
}
Interval ivDiv(Interval a, Interval b) {
  Interval r = ivMul(a, ivRcp(b));
  r.nan = r.nan || !b.finite();  // inf / inf
  return r;
}
Interval ivMono(Interval a, double (*f)(double)) {
  return mk(f(a.lo), f(a.hi), a.nan);
}
double clampExpD(double x) {
  return std::clamp(x, -double(kExpClamp), double(kExpClamp));
}
double floorPosD(double x) {
  return std::max(x, double(kMinPos));
}
Interval ivExp2(Interval a) {
  return ivMono(a, [](double x) { return std::exp2(clampExpD(x)); });
}
Interval ivLog2(Interval a) {
  return ivMono(a, [](double x) { return std::log2(floorPosD(x)); });
}
Interval ivScale(Interval a, double s) {
  return ivMul(a, Interval{s, s, false});
}
Interval ivMin(Interval a, Interval b) {
  return Interval{std::min(a.lo, b.lo), std::min(a.hi, b.hi), a.nan || b.nan};
}
Interval ivMax(Interval a, Interval b) {
  return Interval{std::max(a.lo, b.lo), std::max(a.hi, b.hi), a.nan || b.nan};
}
Interval ivHull(Interval a, Interval b) {
  return Interval{std::min(a.lo, b.lo), std::max(a.hi, b.hi), a.nan || b.nan};
}

Interval opInterval(Op op, const Interval& a, const Interval& b, const Interval& c,
                    const Interval& d) {
  switch (op) {
    case Op::Add:
      return ivAdd(a, b);
    case Op::Sub:
      return ivSub(a, b);
    case Op::Mul:
      return ivMul(a, b);
    case Op::Div:
      return ivDiv(a, b);
    case Op::Mad:
      return ivAdd(widen(ivMul(a, b)), c);
    case Op::Neg:
      return ivNeg(a);
    case Op::Rcp:
      return ivRcp(a);
    case Op::Sqrt:
      return ivMono(a, [](double x) { return std::sqrt(std::max(x, 0.0)); });
    case Op::Rsqrt: {
      Interval r = ivMono(a, [](double x) { return 1.0 / std::sqrt(floorPosD(x)); });
      return Interval{r.hi, r.lo, r.nan};
    }
    case Op::Square: {
      if (a.lo >= 0) return mk(a.lo * a.lo, a.hi * a.hi, a.nan);
      if (a.hi <= 0) return mk(a.hi * a.hi, a.lo * a.lo, a.nan);
      return mk(0.0, std::max(a.lo * a.lo, a.hi * a.hi), a.nan);
    }
    case Op::Exp2:
      return ivExp2(a);
    case Op::Log2:
      return ivLog2(a);
    case Op::Exp:
      return ivExp2(widen(ivScale(a, sem::kLog2E)));
    case Op::Log:
      return ivScale(widen(ivLog2(a)), sem::kLn2);
    case Op::Pow: {
      Interval l = widen(ivLog2(a));
      Interval e = widen(ivMul(b, l));
      return ivExp2(e);
    }
    case Op::Sin:
    case Op::Cos:
      return Interval{-1.0, 1.0, a.nan || !a.finite()};
    case Op::Min:
      return ivMin(a, b);
    case Op::Max:
      return ivMax(a, b);
    case Op::Abs: {
      if (a.lo >= 0) return a;
      if (a.hi <= 0) return ivNeg(a);
      return Interval{0.0, std::max(-a.lo, a.hi), a.nan};
    }
    case Op::Saturate:
      return Interval{std::clamp(a.lo, 0.0, 1.0), std::clamp(a.hi, 0.0, 1.0), false};
    case Op::Lerp:
      return ivAdd(a, widen(ivMul(widen(ivSub(b, a)), c)));
    case Op::Select:
      return ivHull(c, d);
  }
  return whole();
}
}  // namespace

std::vector<Interval> nodeIntervals(const Dag& d, const std::vector<Interval>& domain) {
  std::vector<Interval> iv(d.nodes.size());
  for (size_t i = 0; i < d.nodes.size(); ++i) {
    const Node& n = d.nodes[i];
    switch (n.kind) {
      case Node::Kind::Var:
        if (n.index < static_cast<int>(domain.size())) {
          // The interpreter reads inputs as float: round the bounds outward to float.
          Interval v = domain[n.index];
          v.nan = v.nan && !(std::isfinite(v.lo) && std::isfinite(v.hi));
          if (std::isnan(v.lo) || std::isnan(v.hi)) {
            v = whole();
          } else {
            float lo = static_cast<float>(v.lo), hi = static_cast<float>(v.hi);
            if (lo > v.lo) lo = std::nextafter(lo, -INFINITY);
            if (hi < v.hi) hi = std::nextafter(hi, INFINITY);
            v.lo = lo;
            v.hi = hi;
          }
          iv[i] = v;
        } else {
          iv[i] = whole();
        }
        break;
      case Node::Kind::Const:
        iv[i] = Interval{n.value, n.value, std::isnan(n.value)};
        break;
      case Node::Kind::Op: {
        Interval a[kMaxArity];
        for (int k = 0; k < arity(n.op) && k < kMaxArity; ++k) a[k] = iv[n.args[k]];
        iv[i] = widen(opInterval(n.op, a[0], a[1], a[2], a[3]));
        break;
      }
    }
  }
  return iv;
}

bool isProtected(Op op) {
  switch (op) {
    case Op::Div:
    case Op::Rcp:
    case Op::Sqrt:
    case Op::Rsqrt:
    case Op::Exp2:
    case Op::Log2:
    case Op::Exp:
    case Op::Log:
    case Op::Pow:
    case Op::Saturate:
      return true;
    case Op::Add:
    case Op::Sub:
    case Op::Mul:
    case Op::Mad:
    case Op::Neg:
    case Op::Square:
    case Op::Sin:
    case Op::Cos:
    case Op::Min:
    case Op::Max:
    case Op::Abs:
    case Op::Lerp:
    case Op::Select:
      return false;
  }
  return false;
}

bool provenUnguarded(const Dag& d, int id, const std::vector<Interval>& iv) {
  const Node& n = d.nodes[id];
  if (!n.isOp()) return true;
  const Interval& a = iv[n.args[0]];
  const double g = kDivGuard, m = kMinPos, e = kExpClamp;
  auto noGuard = [&](const Interval& b) { return !b.nan && (b.lo >= g || b.hi <= -g); };
  switch (n.op) {
    case Op::Div:
      return noGuard(iv[n.args[1]]);
    case Op::Rcp:
      return noGuard(a);
    case Op::Sqrt:
      return !a.nan && a.lo >= 0;
    case Op::Rsqrt:
    case Op::Log2:
    case Op::Log:
      return !a.nan && a.lo > m;
    case Op::Exp2:
      return !a.nan && a.lo >= -e && a.hi <= e;
    case Op::Exp: {
      const Interval s = widen(ivScale(a, sem::kLog2E));
      return !s.nan && s.lo >= -e && s.hi <= e;
    }
    case Op::Pow: {
      if (a.nan || !(a.lo > m)) return false;
      const Interval s = widen(ivMul(iv[n.args[1]], widen(ivLog2(a))));
      return !s.nan && s.lo >= -e && s.hi <= e;
    }
    case Op::Saturate:
      return !a.nan;
    case Op::Min:
    case Op::Max:
      return !a.nan && !iv[n.args[1]].nan;
    case Op::Add:
    case Op::Sub:
    case Op::Mul:
    case Op::Mad:
    case Op::Neg:
    case Op::Square:
    case Op::Sin:
    case Op::Cos:
    case Op::Abs:
    case Op::Lerp:
    case Op::Select:
      return true;
  }
  return false;
}

// ---------------------------------------------------------------------------------------
// Evaluation

namespace {
double applyIn(Precision p, Op op, double a, double b, double c, double d) {
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
      case Node::Kind::Var:
        v[i] = roundIn(p, inputs[n.index]);
        break;
      case Node::Kind::Const:
        v[i] = roundIn(p, n.value);
        break;
      case Node::Kind::Op: {
        double a[kMaxArity] = {0, 0, 0, 0};
        for (int k = 0; k < arity(n.op) && k < kMaxArity; ++k) a[k] = v[n.args[k]];
        v[i] = applyIn(p, n.op, a[0], a[1], a[2], a[3]);
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
class Simplifier {
 public:
  Simplifier(const SimplifyOptions& o, Dag& out) : o_(o), out_(out) {}

  bool isC(int id, double v) const {
    const Node& n = out_.nodes[id];
    return n.isConst() && n.value == v;
  }
  bool isNeg(int id) const {
    const Node& n = out_.nodes[id];
    return n.isOp() && n.op == Op::Neg;
  }
  bool isNegConst(int id) const {
    const Node& n = out_.nodes[id];
    return n.isConst() && n.value < 0;
  }
  int arg0(int id) const { return out_.nodes[id].args[0]; }

  // Builds op(args) in `out`, applying the exact rewrites and folding.
  int make(Op op, std::array<int, kMaxArity> a) {
    const int ar = arity(op);
    bool all_const = true;
    for (int k = 0; k < ar; ++k) all_const = all_const && out_.nodes[a[k]].isConst();
    if (all_const) {
      double v[kMaxArity] = {0, 0, 0, 0};
      for (int k = 0; k < ar && k < kMaxArity; ++k) v[k] = out_.nodes[a[k]].value;
      const double r = applyIn(o_.precision, op, v[0], v[1], v[2], v[3]);
      if (std::isfinite(r)) return out_.constant(r);
    }
    if (o_.exact) {
      switch (op) {
        case Op::Add:
          if (isC(a[1], 0)) return a[0];
          if (isC(a[0], 0)) return a[1];
          if (isNegConst(a[1])) return make(Op::Sub, {a[0], negConst(a[1]), -1, -1});
          if (isNeg(a[1])) return make(Op::Sub, {a[0], arg0(a[1]), -1, -1});
          if (isNeg(a[0])) return make(Op::Sub, {a[1], arg0(a[0]), -1, -1});
          break;
        case Op::Sub:
          if (isC(a[1], 0)) return a[0];
          if (isC(a[0], 0)) return make(Op::Neg, {a[1], -1, -1, -1});
          if (isNegConst(a[1])) return make(Op::Add, {a[0], negConst(a[1]), -1, -1});
          if (isNeg(a[1])) return make(Op::Add, {a[0], arg0(a[1]), -1, -1});
          break;
        case Op::Mul:
          if (isC(a[1], 1)) return a[0];
          if (isC(a[0], 1)) return a[1];
          if (isC(a[1], -1)) return make(Op::Neg, {a[0], -1, -1, -1});
          if (isC(a[0], -1)) return make(Op::Neg, {a[1], -1, -1, -1});
          break;
        case Op::Div:
          if (isC(a[1], 1)) return a[0];
          if (isC(a[1], -1)) return make(Op::Neg, {a[0], -1, -1, -1});
          if (isC(a[0], 1)) return make(Op::Rcp, {a[1], -1, -1, -1});
          break;
        case Op::Mad:
          if (isC(a[0], 1)) return make(Op::Add, {a[1], a[2], -1, -1});
          if (isC(a[1], 1)) return make(Op::Add, {a[0], a[2], -1, -1});
          if (isC(a[0], -1)) return make(Op::Sub, {a[2], a[1], -1, -1});
          if (isC(a[1], -1)) return make(Op::Sub, {a[2], a[0], -1, -1});
          if (isC(a[2], 0)) return make(Op::Mul, {a[0], a[1], -1, -1});
          if (out_.nodes[a[0]].isConst() && out_.nodes[a[1]].isConst())
            return make(Op::Add, {make(Op::Mul, {a[0], a[1], -1, -1}), a[2], -1, -1});
          break;
        case Op::Neg:
          if (isNeg(a[0])) return arg0(a[0]);
          break;
        case Op::Rcp:
        case Op::Sqrt:
        case Op::Rsqrt:
        case Op::Square:
        case Op::Exp2:
        case Op::Log2:
        case Op::Exp:
        case Op::Log:
        case Op::Pow:
        case Op::Sin:
        case Op::Cos:
        case Op::Min:
        case Op::Max:
        case Op::Abs:
        case Op::Saturate:
        case Op::Lerp:
        case Op::Select:
          break;
      }
    }
    return out_.op(op, a);
  }

  int negConst(int id) { return out_.constant(-out_.nodes[id].value); }

  // pow(x, c) with x >= 0 proven on the domain.
  int powRewrite(int base, int expo) {
    const Node& e = out_.nodes[expo];
    if (!e.isConst()) return -1;
    const double c = e.value;
    if (c == 0) return out_.constant(1.0);
    if (c == 1) return base;
    if (c == 2) return make(Op::Square, {base, -1, -1, -1});
    if (c == 3) return make(Op::Mul, {make(Op::Square, {base, -1, -1, -1}), base, -1, -1});
    if (c == 4) return make(Op::Square, {make(Op::Square, {base, -1, -1, -1}), -1, -1, -1});
    if (c == 0.5) return make(Op::Sqrt, {base, -1, -1, -1});
    return -1;
  }

 private:
  const SimplifyOptions& o_;
  Dag& out_;
};
}  // namespace

Dag simplify(const Dag& d, const SimplifyOptions& opts) {
  Dag out;
  out.num_inputs = d.num_inputs;
  Simplifier s(opts, out);
  std::vector<Interval> iv;
  if (opts.pow_rewrites) iv = nodeIntervals(d, opts.domain);
  std::vector<int> map(d.nodes.size(), -1);
  const auto live = d.reachable();
  for (size_t i = 0; i < d.nodes.size(); ++i) {
    if (!live[i]) continue;
    const Node& n = d.nodes[i];
    switch (n.kind) {
      case Node::Kind::Var:
        map[i] = out.var(n.index);
        break;
      case Node::Kind::Const: {
        double v = n.value;
        if (opts.precision == Precision::Float) v = static_cast<float>(v);
        if (opts.precision == Precision::Half) v = roundToHalf(static_cast<float>(v));
        map[i] = out.constant(v);
        break;
      }
      case Node::Kind::Op: {
        std::array<int, kMaxArity> a{-1, -1, -1, -1};
        for (int k = 0; k < arity(n.op); ++k) a[k] = map[n.args[k]];
        int r = -1;
        if (n.op == Op::Pow && opts.pow_rewrites) {
          const Interval& b = iv[n.args[0]];
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
// Infix, costs

std::vector<std::string> dagInfix(const Dag& d, const std::vector<std::string>& input_names) {
  const auto uses = d.useCounts();
  std::vector<std::string> name(d.nodes.size());
  std::vector<uint8_t> done(d.nodes.size(), 0);
  int counter = 0;
  std::string lets;
  auto leaf = [&](int id) -> std::string {
    const Node& n = d.nodes[id];
    if (n.kind == Node::Kind::Var)
      return n.index < static_cast<int>(input_names.size()) ? input_names[n.index]
                                                            : "x" + std::to_string(n.index);
    const float f = static_cast<float>(n.value);
    return static_cast<double>(f) == n.value ? formatFloat(f) : formatDouble(n.value);
  };
  std::function<std::string(int)> render = [&](int id) -> std::string {
    const Node& n = d.nodes[id];
    if (!n.isOp()) return leaf(id);
    if (!name[id].empty()) return name[id];
    std::vector<std::string> a(kMaxArity);
    for (int k = 0; k < arity(n.op); ++k) a[k] = render(n.args[k]);
    std::string e = fillOpTemplate(opInfo(n.op).infix, a);
    if (uses[id] > 1) {
      // Bind in front of the current output: the name stays valid for later outputs.
      std::string nm;
      do {
        nm = "t";
        nm += std::to_string(counter++);
      } while (std::find(input_names.begin(), input_names.end(), nm) != input_names.end());
      lets += nm + " = " + e + "; ";
      name[id] = nm;
      return nm;
    }
    return e;
  };
  std::vector<std::string> out;
  for (int o : d.outputs) {
    lets.clear();
    std::string e = render(o);
    out.push_back(lets + e);
  }
  return out;
}

int countPiecewise(const Dag& d) {
  const auto r = d.reachable();
  int n = 0;
  for (size_t i = 0; i < d.nodes.size(); ++i)
    if (r[i] && d.nodes[i].isOp() && opInfo(d.nodes[i].op).piecewise) ++n;
  return n;
}

double dagCost(const Dag& d, const std::array<double, kNumOps>& cost) {
  const auto r = d.reachable();
  double c = 0;
  for (size_t i = 0; i < d.nodes.size(); ++i)
    if (r[i] && d.nodes[i].isOp()) c += cost[static_cast<int>(d.nodes[i].op)];
  return c;
}

}  // namespace lgp::emit
