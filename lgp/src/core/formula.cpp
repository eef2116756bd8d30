// The formula printer (see formula.hpp).
#include "lgp/core/formula.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <utility>

namespace lgp {

namespace {

// Precedence of a printed term, lowest first; an operand printed below what its position
// needs gets parentheses.
enum Prec : int { kTernary = 0, kAdd = 1, kMul = 2, kUnary = 3, kPow = 4, kAtom = 5 };

// A printed sub-expression: `body` with precedence `prec`, negated when `neg` (a leading
// unary minus, kept apart so that sums can turn it into subtraction and products can move
// it to the front). A negated body is always at least a product.
struct Term {
  std::string body;
  int prec = kAtom;
  bool neg = false;
  bool number = false;  // a literal (possibly p/q): written first in a product
  std::string text() const { return neg ? "-" + body : body; }
  int textPrec() const { return neg ? kMul : prec; }
};

std::string paren(const std::string& s) {
  return "(" + s + ")";
}
// The whole term where precedence `p` is needed.
std::string at(const Term& t, int p) {
  return t.textPrec() >= p ? t.text() : paren(t.text());
}
// The term without its sign where precedence `p` is needed.
std::string bodyAt(const Term& t, int p) {
  return t.prec >= p ? t.body : paren(t.body);
}

int significantDigits(const std::string& s) {
  int n = 0;
  bool lead = true;
  for (char c : s) {
    if (c == 'e' || c == 'E') break;
    if (c < '0' || c > '9') continue;
    if (lead && c == '0') continue;
    lead = false;
    ++n;
  }
  return n;
}

// A non-negative constant: shortest round-trip digits, or p/q when the value is exactly the
// float nearest a fraction whose decimal expansion does not terminate (what snapping makes).
Term constantTerm(double v) {
  Term t;
  t.number = true;
  t.neg = std::signbit(v);
  v = std::fabs(v);
  const float f = static_cast<float>(v);
  if (static_cast<double>(f) != v) {
    t.body = formatDouble(v);
    return t;
  }
  t.body = formatFloat(f);
  if (significantDigits(t.body) < 7) return t;
  for (int q : {3, 6, 7, 9, 11, 12}) {
    const double p = std::nearbyint(v * q);
    if (p < 1 || p > 1000 || std::gcd(static_cast<int>(p), q) != 1) continue;
    if (static_cast<float>(p) / static_cast<float>(q) == f) {
      t.body = std::to_string(static_cast<int>(p)) + "/" + std::to_string(q);
      t.prec = kMul;
      return t;
    }
  }
  return t;
}

class Printer {
 public:
  Printer(const Dag& d, const std::vector<std::string>& inputs) : d_(d), inputs_(inputs) {
    names_.resize(d.nodes.size());
  }

  // A node where it is used: its name if it has one, else its expression.
  Term ref(int id) const {
    if (!names_[id].empty()) return Term{names_[id], kAtom, false, false};
    return term(id);
  }

  // A node's own expression (what its statement assigns when it is named).
  Term term(int id) const {
    const Node& n = d_.nodes[id];
    if (n.kind == Node::Kind::Var)
      return Term{n.index >= 0 && n.index < static_cast<int>(inputs_.size())
                      ? inputs_[n.index]
                      : "x" + std::to_string(n.index),
                  kAtom, false, false};
    if (n.kind == Node::Kind::Const) return constantTerm(n.value);
    const auto& a = n.args;
    switch (n.op) {
      case Op::Add:
        return sum(ref(a[0]), ref(a[1]), true);
      case Op::Sub:
        return sum(ref(a[0]), ref(a[1]), false);
      case Op::Mad:
        return sum(product(a[0], a[1]), ref(a[2]), true);
      case Op::Mul:
        return product(a[0], a[1]);
      case Op::Div: {  // (-a)/b = a/(-b) = -(a/b): the guard is odd
        const Term x = ref(a[0]), y = ref(a[1]);
        return Term{bodyAt(x, kMul) + "/" + bodyAt(y, kUnary), kMul, x.neg != y.neg, false};
      }
      case Op::Rcp: {
        const Term x = ref(a[0]);
        return Term{"1/" + bodyAt(x, kUnary), kMul, x.neg, false};
      }
      case Op::Neg: {
        Term x = ref(a[0]);
        if (x.textPrec() < kMul) return Term{paren(x.text()), kAtom, true, false};
        x.neg = !x.neg;
        return x;
      }
      case Op::Square:
        return squareOf(a[0]);
      case Op::Abs: {  // abs(-x) = abs(x)
        Term x = ref(a[0]);
        x.neg = false;
        return call("abs", {x.text()});
      }
      case Op::Select:
        return Term{at(ref(a[0]), kAdd) + " > " + at(ref(a[1]), kAdd) + " ? " +
                        at(ref(a[2]), kAdd) + " : " + ref(a[3]).text(),
                    kTernary, false, false};
      default: {
        std::vector<std::string> args;
        for (int k = 0; k < arity(n.op); ++k) args.push_back(ref(a[k]).text());
        return call(std::string(opName(n.op)), args);
      }
    }
  }

  std::vector<std::string> names_;  // per node: the name it is printed as (empty: inline)

 private:
  // An operand node that is printed inline (no name) and is `op`.
  bool inlinedOp(int id, Op op) const {
    return names_[id].empty() && d_.nodes[id].isOp() && d_.nodes[id].op == op;
  }
  // An inlined square(x) or x*x: its x, else -1.
  int squared(int id) const {
    if (inlinedOp(id, Op::Square)) return d_.nodes[id].args[0];
    if (inlinedOp(id, Op::Mul) && d_.nodes[id].args[0] == d_.nodes[id].args[1])
      return d_.nodes[id].args[0];
    return -1;
  }
  // x^2 (and x^4 for the square of a square), the way the parser reads them back; signs
  // drop: (-x)^2 = x^2.
  Term squareOf(int id) const {
    const int inner = squared(id);
    if (inner >= 0) return Term{bodyAt(ref(inner), kAtom) + "^4", kPow, false, false};
    return Term{bodyAt(ref(id), kAtom) + "^2", kPow, false, false};
  }

  static Term call(const std::string& fn, const std::vector<std::string>& args) {
    std::string s = fn + "(";
    for (size_t k = 0; k < args.size(); ++k) s += (k ? ", " : "") + args[k];
    return Term{s + ")", kAtom, false, false};
  }

  // a + b or a - b. Exact rewrites of the text: a + (-b) = a - b, a - (-b) = a + b, and
  // a + b = b + a (to put a positive operand first, and to avoid parenthesising a sum on the
  // right, which parses left to right).
  static Term sum(Term x, Term y, bool plus) {
    if (plus && ((y.textPrec() < kMul && x.textPrec() >= kMul) ||
                 (x.neg && !y.neg && y.textPrec() >= kMul)))
      std::swap(x, y);
    const char* op = plus ? " + " : " - ";
    if (y.neg) {
      op = plus ? " - " : " + ";
      y.neg = false;
    }
    return Term{at(x, kAdd) + op + at(y, kMul), kAdd, false, false};
  }

  // a*b: signs move to the front ((-a)*b = a*(-b) = -(a*b)); a literal factor goes first, and
  // a product on the right is swapped to the left rather than parenthesised (a*b = b*a).
  Term product(int ia, int ib) const {
    for (auto [sq, x] : {std::pair{ia, ib}, std::pair{ib, ia}})
      if (squared(sq) == x) {  // x^2*x = x^3
        const Term b = ref(x);
        return Term{bodyAt(b, kAtom) + "^3", kPow, b.neg, false};
      }
    if (ia == ib) return squareOf(ia);  // x*x = x^2 (square computes x*x)
    Term x = ref(ia), y = ref(ib);
    const bool neg = x.neg != y.neg;
    x.neg = y.neg = false;
    if ((y.number && !x.number) || (!x.number && y.prec < kUnary && x.prec >= kUnary))
      std::swap(x, y);
    return Term{bodyAt(x, kMul) + "*" + bodyAt(y, kUnary), kMul, neg, false};
  }

  const Dag& d_;
  const std::vector<std::string>& inputs_;
};

// Worth a name when used twice or more: any operator except the negation of a leaf.
bool bindable(const Dag& d, int id) {
  const Node& n = d.nodes[id];
  if (!n.isOp()) return false;
  return !(n.op == Op::Neg && d.nodes[n.args[0]].isLeaf());
}

class Namer {
 public:
  Namer(const std::vector<std::string>& a, const std::vector<std::string>& b) {
    taken_.insert(taken_.end(), a.begin(), a.end());
    taken_.insert(taken_.end(), b.begin(), b.end());
  }
  std::string fresh() {
    std::string nm;
    do {
      nm = "t" + std::to_string(next_++);
    } while (std::find(taken_.begin(), taken_.end(), nm) != taken_.end());
    return nm;
  }

 private:
  std::vector<std::string> taken_;
  int next_ = 0;
};

// Uses as the text spells them: x*x and x^2*x (an unshared square), alone or as the product
// of a mad, name x once.
void printedUses(const Dag& d, const std::vector<uint8_t>& live, std::vector<int>& uses) {
  for (size_t id = 0; id < d.nodes.size(); ++id) {
    const Node& n = d.nodes[id];
    if (!live[id] || !n.isOp() || (n.op != Op::Mul && n.op != Op::Mad)) continue;
    const int a = n.args[0], b = n.args[1];
    if (a == b) {
      --uses[a];
      continue;
    }
    for (auto [sq, x] : {std::pair{a, b}, std::pair{b, a}}) {
      const Node& s = d.nodes[sq];
      const bool square =
          s.isOp() && (s.op == Op::Square || (s.op == Op::Mul && s.args[0] == s.args[1]));
      if (square && s.args[0] == x && uses[sq] == 1) {
        --uses[x];
        break;
      }
    }
  }
}

std::string outputName(const std::vector<std::string>& names, size_t j) {
  return j < names.size() ? names[j] : "y" + std::to_string(j);
}

// Operands name earlier nodes, outputs name nodes: what the printer relies on. A DAG built
// by hand that breaks it prints as "<malformed DAG>" instead of being read out of bounds.
bool wellFormed(const Dag& d) {
  for (size_t i = 0; i < d.nodes.size(); ++i) {
    const Node& n = d.nodes[i];
    if (n.isOp())
      for (int k = 0; k < arity(n.op); ++k)
        if (n.args[k] < 0 || static_cast<size_t>(n.args[k]) >= i) return false;
  }
  for (int o : d.outputs)
    if (o < 0 || static_cast<size_t>(o) >= d.nodes.size()) return false;
  return true;
}
constexpr const char* kMalformed = "<malformed DAG>";

}  // namespace

std::string Formula::text() const {
  std::string s;
  for (const auto& st : statements) s += (s.empty() ? "" : "; ") + st.name + " = " + st.expr;
  return s;
}

Formula printFormula(const Dag& d, const std::vector<std::string>& input_names,
                     const std::vector<std::string>& output_names) {
  if (!wellFormed(d)) {
    Formula f;
    for (size_t j = 0; j < d.outputs.size(); ++j)
      f.statements.push_back({outputName(output_names, j), kMalformed, static_cast<int>(j)});
    return f;
  }
  auto uses = d.useCounts();
  const auto live = d.reachable();
  printedUses(d, live, uses);
  const size_t k = d.outputs.size();
  std::vector<std::string> outs;
  for (size_t j = 0; j < k; ++j) outs.push_back(outputName(output_names, j));
  Printer pr(d, input_names);
  Namer namer(input_names, outs);
  Formula f;
  for (size_t id = 0; id < d.nodes.size(); ++id) {
    if (!live[id] || uses[id] < 2 || !bindable(d, static_cast<int>(id))) continue;
    const std::string name = namer.fresh();
    f.statements.push_back({name, pr.term(static_cast<int>(id)).text(), -1});
    pr.names_[id] = name;
  }
  for (size_t j = 0; j < k; ++j)
    f.statements.push_back({outs[j], pr.ref(d.outputs[j]).text(), static_cast<int>(j)});
  return f;
}

std::vector<std::string> printOutputs(const Dag& d, const std::vector<std::string>& input_names) {
  std::vector<std::string> result;
  if (!wellFormed(d)) return std::vector<std::string>(d.outputs.size(), kMalformed);
  const size_t n = d.nodes.size();
  for (int out : d.outputs) {
    // Uses within this output's sub-DAG only, so that the text stands alone.
    std::vector<int> uses(n, 0);
    std::vector<uint8_t> reach(n, 0);
    reach[out] = 1;
    for (int i = out; i >= 0; --i) {
      if (!reach[i] || !d.nodes[i].isOp()) continue;
      for (int a = 0; a < arity(d.nodes[i].op); ++a) {
        reach[d.nodes[i].args[a]] = 1;
        ++uses[d.nodes[i].args[a]];
      }
    }
    printedUses(d, reach, uses);
    Printer pr(d, input_names);
    Namer namer(input_names, {});
    std::string lets;
    for (int id = 0; id < out; ++id) {
      if (!reach[id] || uses[id] < 2 || !bindable(d, id)) continue;
      const std::string name = namer.fresh();
      lets += name + " = " + pr.term(id).text() + "; ";
      pr.names_[id] = name;
    }
    result.push_back(lets + pr.ref(out).text());
  }
  return result;
}

SimplifyOptions formulaSimplifyOptions(const std::vector<Interval>& domain) {
  SimplifyOptions o;
  o.domain = domain;
  return o;
}

Dag formulaDag(const Program& p, int num_inputs, const std::vector<Interval>& domain) {
  return simplify(buildDag(p, num_inputs), formulaSimplifyOptions(domain));
}

std::string programFormula(const Program& p, const std::vector<std::string>& input_names,
                           const std::vector<std::string>& output_names,
                           const std::vector<Interval>& domain) {
  return printFormula(formulaDag(p, static_cast<int>(input_names.size()), domain), input_names,
                      output_names)
      .text();
}

std::vector<std::string> toInfix(const Program& p, const std::vector<std::string>& input_names) {
  SimplifyOptions o;
  o.pow_rewrites = false;  // bit-identical for every input (see program.hpp)
  return printOutputs(simplify(buildDag(p, static_cast<int>(input_names.size())), o), input_names);
}

}  // namespace lgp
