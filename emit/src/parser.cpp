// Recursive-descent parser for infix formulas (grammar in parser.hpp).
#include "lgp/emit/parser.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <optional>
#include <set>

#include "lgp/eval/semantics.hpp"

namespace lgp::emit {

namespace {

// The function names the op table's language columns spell an operator with, where the
// spelling is a plain call of the operands in order (GLSL's mix and inversesqrt, C++'s
// std::exp2): code written in any language reads back.
const std::map<std::string, Op>& spelledCalls() {
  static const std::map<std::string, Op> calls = [] {
    std::map<std::string, Op> m;
    for (const auto& info : allOps())
      for (std::string_view t : {info.infix, info.hlsl, info.glsl, info.cpp}) {
        std::string call = "(";
        for (int k = 0; k < info.arity; ++k) call += (k ? ", {" : "{") + std::to_string(k) + "}";
        call += ")";
        if (t.size() <= call.size() || t.substr(t.size() - call.size()) != call) continue;
        std::string fn(t.substr(0, t.size() - call.size()));
        if (fn.rfind("std::", 0) == 0) fn = fn.substr(5);
        const bool ident = !fn.empty() && std::all_of(fn.begin(), fn.end(), [](char c) {
          return std::isalnum(static_cast<unsigned char>(c)) || c == '_';
        });
        if (ident && fn != info.name) m.emplace(fn, info.op);
      }
    return m;
  }();
  return calls;
}

enum class Tok { Num, Name, Punct, Newline, End };

struct Token {
  Tok kind = Tok::End;
  std::string text;
  double value = 0;
  size_t pos = 0;  // byte offset, for messages
};

Expected<std::vector<Token>> lex(const std::string& s, const std::string& where) {
  std::vector<Token> out;
  size_t i = 0;
  auto err = [&](size_t p, const std::string& m) {
    return Status::error(where + ": column " + std::to_string(p + 1) + ": " + m);
  };
  while (i < s.size()) {
    const char ch = s[i];
    if (ch == '\n') {
      out.push_back({Tok::Newline, "\n", 0, i});
      ++i;
      continue;
    }
    if (std::isspace(static_cast<unsigned char>(ch))) {
      ++i;
      continue;
    }
    if (ch == '/' && i + 1 < s.size() && s[i + 1] == '/') {
      while (i < s.size() && s[i] != '\n') ++i;
      continue;
    }
    if (ch == '/' && i + 1 < s.size() && s[i + 1] == '*') {
      const size_t e = s.find("*/", i + 2);
      if (e == std::string::npos) return err(i, "unterminated /* comment");
      i = e + 2;
      continue;
    }
    if (std::isdigit(static_cast<unsigned char>(ch)) ||
        (ch == '.' && i + 1 < s.size() && std::isdigit(static_cast<unsigned char>(s[i + 1])))) {
      // Decimal only, as in tables: strtod would also read 0x10 (16) and 0x1p3 (8).
      if (ch == '0' && i + 1 < s.size() && (s[i + 1] == 'x' || s[i + 1] == 'X'))
        return err(i, "hexadecimal numbers are not accepted (write the decimal value)");
      const char* begin = s.c_str() + i;
      char* end = nullptr;
      const double v = std::strtod(begin, &end);
      size_t j = i + static_cast<size_t>(end - begin);
      if (j < s.size() &&
          (s[j] == 'f' || s[j] == 'F' || s[j] == 'h' || s[j] == 'H' || s[j] == 'l' || s[j] == 'L'))
        ++j;
      if (j < s.size() &&
          (std::isalnum(static_cast<unsigned char>(s[j])) || s[j] == '_' || s[j] == '.'))
        return err(i, "malformed number '" + s.substr(i, j + 1 - i) + "'");
      out.push_back({Tok::Num, s.substr(i, j - i), v, i});
      i = j;
      continue;
    }
    if (std::isalpha(static_cast<unsigned char>(ch)) || ch == '_') {
      size_t j = i;
      while (j < s.size()) {
        if (std::isalnum(static_cast<unsigned char>(s[j])) || s[j] == '_') {
          ++j;
        } else if (s[j] == ':' && j + 2 < s.size() && s[j + 1] == ':' &&
                   (std::isalpha(static_cast<unsigned char>(s[j + 2])) || s[j + 2] == '_')) {
          j += 2;
        } else {
          break;
        }
      }
      out.push_back({Tok::Name, s.substr(i, j - i), 0, i});
      i = j;
      continue;
    }
    if ((ch == '>' || ch == '<') && i + 1 < s.size() && s[i + 1] == '=') {
      out.push_back({Tok::Punct, s.substr(i, 2), 0, i});
      i += 2;
      continue;
    }
    if (std::string_view("+-*/^(),;=?:<>").find(ch) != std::string_view::npos) {
      out.push_back({Tok::Punct, std::string(1, ch), 0, i});
      ++i;
      continue;
    }
    return err(i, std::string("unexpected character '") + ch + "'");
  }
  // Newlines are statement separators only after a complete operand and outside
  // parentheses; otherwise they are whitespace.
  std::vector<Token> t;
  int depth = 0;
  for (const Token& tk : out) {
    if (tk.kind == Tok::Punct && tk.text == "(") ++depth;
    if (tk.kind == Tok::Punct && tk.text == ")") --depth;
    if (tk.kind == Tok::Newline) {
      const bool after_operand =
          !t.empty() && (t.back().kind == Tok::Num || t.back().kind == Tok::Name ||
                         (t.back().kind == Tok::Punct && t.back().text == ")"));
      if (depth == 0 && after_operand) t.push_back({Tok::Punct, ";", 0, tk.pos});
      continue;
    }
    t.push_back(tk);
  }
  t.push_back({Tok::End, "", 0, s.size()});
  return t;
}

struct PExpr {
  int id = -1;
  bool bare_mul = false;  // an unparenthesised product a*b at this level
  int ma = -1, mb = -1;
  std::vector<int> tuple;  // float2(...) etc.
  std::string cmp;         // a parenthesised comparison ca cmp cb, only valid before '?'
  int ca = -1, cb = -1;
  bool scalar() const { return tuple.empty() && cmp.empty(); }
};

PExpr val(int id) {
  PExpr e;
  e.id = id;
  return e;
}
PExpr product(int id, bool bare, int a, int b) {
  PExpr e;
  e.id = id;
  e.bare_mul = bare;
  e.ma = a;
  e.mb = b;
  return e;
}
PExpr tupleOf(const std::vector<int>& v) {
  PExpr e;
  e.id = v[0];
  e.tuple = v;
  return e;
}

constexpr const char* kNotScalar =
    "a vector (float2 ...) or a comparison cannot be used here (comparisons only as the "
    "condition of '? :', vectors only as the final value)";

struct Statement {
  std::string assigned;  // empty for a bare expression
  PExpr value;
};

class Parser {
 public:
  // `unread`: the outputs assigned and not read since, shared by all texts of a formula.
  Parser(Dag& d, const ParseOptions& o, std::map<std::string, int>& scope,
         std::set<std::string>& unread)
      : d_(d), o_(o), scope_(scope), unread_(unread) {}

  Expected<std::vector<Statement>> parse(const std::string& text, const std::string& where) {
    where_ = where;
    auto toks = lex(text, where);
    if (!toks) return toks.status();
    t_ = std::move(*toks);
    p_ = 0;
    std::vector<Statement> out;
    while (true) {
      while (isP(";")) ++p_;
      if (t_[p_].kind == Tok::End) break;
      Statement st;
      if (!statement(st)) return Status::error(err_);
      out.push_back(std::move(st));
      if (t_[p_].kind == Tok::End) break;
      if (!isP(";"))
        return Status::error(at("expected ';' or the end, found '" + t_[p_].text + "'"));
    }
    if (out.empty()) return Status::error(where + ": empty formula");
    return out;
  }

 private:
  bool isP(std::string_view s) const { return t_[p_].kind == Tok::Punct && t_[p_].text == s; }
  std::string at(const std::string& m) const {
    return where_ + ": column " + std::to_string(t_[p_].pos + 1) + ": " + m;
  }
  bool fail(const std::string& m) {
    if (err_.empty()) err_ = at(m);
    return false;
  }
  // Nesting guard: parentheses, call arguments, unary signs and '? :' branches each take one
  // level (and a few stack frames) while they are open.
  struct Nest {
    Parser& p;
    explicit Nest(Parser& q) : p(q) { ++p.depth_; }
    ~Nest() { --p.depth_; }
    Nest(const Nest&) = delete;
    Nest& operator=(const Nest&) = delete;
  };
  bool tooDeep() {
    if (depth_ <= kMaxFormulaNesting) return false;
    fail("nested deeper than " + std::to_string(kMaxFormulaNesting) +
         " levels (parentheses, function calls, unary signs and '? :' count)");
    return true;
  }

  bool expect(std::string_view s) {
    if (isP(s)) {
      ++p_;
      return true;
    }
    return fail("expected '" + std::string(s) + "', found '" +
                (t_[p_].kind == Tok::End ? std::string("end of formula") : t_[p_].text) + "'");
  }

  static bool isTypeWord(const std::string& s) {
    return s == "float" || s == "half" || s == "double" || s == "const" || s == "auto" ||
           s == "min16float";
  }

  bool statement(Statement& st) {
    // [type...] NAME = expr
    size_t q = p_;
    while (t_[q].kind == Tok::Name && isTypeWord(t_[q].text) && t_[q + 1].kind == Tok::Name) ++q;
    if (t_[q].kind == Tok::Name && t_[q + 1].kind == Tok::Punct && t_[q + 1].text == "=") {
      const std::string name = t_[q].text;
      p_ = q + 2;
      if (isInput(name)) return fail("cannot assign to the input '" + name + "'");
      if (!expr(st.value)) return false;
      // A second assignment to an output before its value is read would silently drop the
      // first (`B = mu; B = r`); reading it in between (a swap) is fine.
      if (isOutput(name) && !unread_.insert(name).second) {
        p_ = q;  // the column of the name
        return fail("the output '" + name +
                    "' is assigned again before its value is used; the first assignment "
                    "would be dropped");
      }
      if (!st.value.scalar()) return fail("a vector or bare comparison cannot be assigned");
      st.assigned = name;
      scope_[name] = st.value.id;
      return true;
    }
    if (t_[p_].kind == Tok::Name && t_[p_].text == "return") ++p_;
    if (!expr(st.value)) return false;
    if (!st.value.cmp.empty()) return fail("a comparison must be followed by '? a : b'");
    return true;
  }

  bool isOutput(const std::string& n) const {
    return std::find(o_.output_names.begin(), o_.output_names.end(), n) != o_.output_names.end();
  }

  bool isInput(const std::string& n) const {
    for (const auto& s : o_.input_names)
      if (s == n) return true;
    return o_.aliases.count(n) > 0;
  }

  int mk(Op op, std::array<int, kMaxArity> a) {
    bool all_const = true;
    for (int k = 0; k < arity(op); ++k) all_const = all_const && d_.nodes[a[k]].isConst();
    if (all_const) {
      float v[kMaxArity] = {0, 0, 0, 0};
      for (int k = 0; k < arity(op) && k < kMaxArity; ++k)
        v[k] = static_cast<float>(d_.nodes[a[k]].value);
      const float r = sem::applyDynamic<float>(op, v[0], v[1], v[2], v[3]);
      if (std::isfinite(r)) return d_.constant(r);
    }
    return d_.op(op, a);
  }
  int mk1(Op op, int a) { return mk(op, {a, -1, -1, -1}); }
  int mk2(Op op, int a, int b) { return mk(op, {a, b, -1, -1}); }

  bool expr(PExpr& out) {
    Nest nest(*this);
    if (tooDeep()) return false;
    PExpr a;
    if (!additive(a)) return false;
    std::string cmp = a.cmp;
    PExpr b;
    if (!cmp.empty()) {  // (x > y) ? ...
      b.id = a.cb;
      a = val(a.ca);
    }
    if (cmp.empty() && (isP(">") || isP("<") || isP(">=") || isP("<="))) {
      cmp = t_[p_].text;
      ++p_;
      if (!additive(b)) return false;
      if (!a.scalar() || !b.scalar()) return fail("a vector or comparison cannot be compared");
    }
    if (!cmp.empty()) {
      if (!isP("?")) {
        out = PExpr{};
        out.cmp = cmp;
        out.ca = a.id;
        out.cb = b.id;
        return true;  // only valid inside parentheses followed by '?' (checked by users)
      }
      ++p_;
      PExpr c, e;
      if (!expr(c) || !expect(":") || !expr(e)) return false;
      if (!c.scalar() || !e.scalar())
        return fail("vectors and bare comparisons are not allowed in '? :'");
      // a > b ? c : e = select(a, b, c, e); a < b ? c : e = select(b, a, c, e);
      // a >= b ? c : e = select(b, a, e, c) (differs only for NaN operands).
      int sa = a.id, sb = b.id, sc = c.id, se = e.id;
      if (cmp == "<") std::swap(sa, sb);
      if (cmp == ">=") std::swap(sa, sb), std::swap(sc, se);
      if (cmp == "<=") std::swap(sc, se);
      out = val(mk(Op::Select, {sa, sb, sc, se}));
      return true;
    }
    out = a;
    return true;
  }

  bool additive(PExpr& out) {
    PExpr l;
    if (!term(l)) return false;
    while (isP("+") || isP("-")) {
      const bool plus = t_[p_].text == "+";
      ++p_;
      PExpr r;
      if (!term(r)) return false;
      if (!l.scalar() || !r.scalar()) return fail(kNotScalar);
      int id;
      if (plus && o_.fuse_mad && l.bare_mul) {
        id = mk(Op::Mad, {l.ma, l.mb, r.id, -1});
      } else if (plus && o_.fuse_mad && r.bare_mul) {
        id = mk(Op::Mad, {r.ma, r.mb, l.id, -1});
      } else {
        id = mk2(plus ? Op::Add : Op::Sub, l.id, r.id);
      }
      l = val(id);
    }
    out = l;
    return true;
  }

  bool term(PExpr& out) {
    PExpr l;
    if (!unary(l)) return false;
    while (isP("*") || isP("/")) {
      const bool mul = t_[p_].text == "*";
      ++p_;
      PExpr r;
      if (!unary(r)) return false;
      if (!l.scalar() || !r.scalar()) return fail(kNotScalar);
      if (mul) {
        const int id = mk2(Op::Mul, l.id, r.id);
        const bool bare = d_.nodes[id].isOp() && d_.nodes[id].op == Op::Mul;
        l = product(id, bare, l.id, r.id);
      } else {
        const Node& n = d_.nodes[l.id];
        const int id = (n.isConst() && n.value == 1.0 && !d_.nodes[r.id].isConst())
                           ? mk1(Op::Rcp, r.id)
                           : mk2(Op::Div, l.id, r.id);
        l = val(id);
      }
    }
    out = l;
    return true;
  }

  bool unary(PExpr& out) {
    if (isP("-") || isP("+")) {
      Nest nest(*this);
      if (tooDeep()) return false;
      const bool neg = t_[p_].text == "-";
      ++p_;
      PExpr a;
      if (!unary(a)) return false;
      if (!a.scalar()) return fail(kNotScalar);
      if (!neg) {
        out = val(a.id);
        return true;
      }
      const Node& n = d_.nodes[a.id];
      out = val(n.isConst() ? d_.constant(static_cast<float>(-n.value)) : mk1(Op::Neg, a.id));
      return true;
    }
    return power(out);
  }

  bool power(PExpr& out) {
    PExpr b;
    if (!primary(b)) return false;
    if (!isP("^")) {
      out = b;
      return true;
    }
    ++p_;
    PExpr e;
    if (!unary(e)) return false;
    if (!b.scalar() || !e.scalar()) return fail(kNotScalar);
    const Node& en = d_.nodes[e.id];
    int id;
    if (en.isConst() && en.value == 1) {
      id = b.id;
    } else if (en.isConst() && en.value == 2) {
      id = mk1(Op::Square, b.id);
    } else if (en.isConst() && en.value == 3) {
      id = mk2(Op::Mul, mk1(Op::Square, b.id), b.id);
    } else if (en.isConst() && en.value == 4) {
      id = mk1(Op::Square, mk1(Op::Square, b.id));
    } else {
      id = mk2(Op::Pow, b.id, e.id);
    }
    out = val(id);
    return true;
  }

  // A name's node: a let-bound name, a table input (after aliases), or xI for input I. An xI
  // whose I is not an input index (out of range, or too long for any integer) is reported
  // here; other unknown names give nullopt.
  std::optional<int> lookup(const std::string& name, bool& bad_index) {
    bad_index = false;
    if (auto it = scope_.find(name); it != scope_.end()) {
      unread_.erase(name);
      return it->second;
    }
    std::string n = name;
    if (auto it = o_.aliases.find(name); it != o_.aliases.end()) n = it->second;
    for (size_t i = 0; i < o_.input_names.size(); ++i)
      if (o_.input_names[i] == n) return d_.var(static_cast<int>(i));
    if (name.size() > 1 && name[0] == 'x' &&
        name.find_first_not_of("0123456789", 1) == std::string::npos) {
      const char* first = name.data() + 1;
      const char* last = name.data() + name.size();
      size_t i = 0;
      const auto [end, ec] = std::from_chars(first, last, i);
      if (ec == std::errc() && end == last && i < o_.input_names.size())
        return d_.var(static_cast<int>(i));
      bad_index = true;
    }
    return std::nullopt;
  }

  bool primary(PExpr& out) {
    const Token tk = t_[p_];
    if (tk.kind == Tok::Num) {
      if (!std::isfinite(static_cast<float>(tk.value)))
        return fail("the constant " + tk.text +
                    " is outside the range of float (magnitude at most 3.4028235e38)");
      ++p_;
      out = val(d_.constant(static_cast<float>(tk.value)));
      return true;
    }
    if (tk.kind == Tok::Punct && tk.text == "(") {
      ++p_;
      PExpr e;
      if (!expr(e) || !expect(")")) return false;
      out = e;
      out.bare_mul = false;
      return true;
    }
    if (tk.kind != Tok::Name)
      return fail(tk.kind == Tok::End ? "unexpected end of formula"
                                      : "unexpected '" + tk.text + "'");
    ++p_;
    if (!isP("(")) {
      bool bad_index = false;
      auto v = lookup(tk.text, bad_index);
      if (!v) {
        std::string ins;
        for (const auto& s : o_.input_names) ins += (ins.empty() ? "" : ", ") + s;
        --p_;
        if (bad_index)
          return fail("input index '" + tk.text + "' out of range: " +
                      (o_.input_names.empty()
                           ? std::string("the table has no inputs")
                           : "the table has " + std::to_string(o_.input_names.size()) +
                                 " inputs, x0 to x" + std::to_string(o_.input_names.size() - 1) +
                                 " (" + ins + ")"));
        return fail("unknown name '" + tk.text + "' (table inputs: " + ins +
                    "; map a formula name to an input with an alias, e.g. " + tk.text + "=" +
                    (o_.input_names.empty() ? std::string("x0") : o_.input_names[0]) + ")");
      }
      out = val(*v);
      return true;
    }
    ++p_;
    std::vector<int> args;
    if (!isP(")")) {
      while (true) {
        PExpr a;
        if (!expr(a)) return false;
        if (!a.scalar()) return fail(kNotScalar);
        args.push_back(a.id);
        if (isP(",")) {
          ++p_;
          continue;
        }
        break;
      }
    }
    if (!expect(")")) return false;
    return call(tk.text, args, out);
  }

  bool call(std::string name, const std::vector<int>& a, PExpr& out) {
    const std::string given = name;
    if (name.rfind("std::", 0) == 0) name = name.substr(5);
    if (name.rfind("lgp_", 0) == 0) name = name.substr(4);
    // C's float functions and other names no language column of the op table spells.
    static const std::map<std::string, std::string> kAlias = {
        {"fabs", "abs"},   {"fabsf", "abs"}, {"fmin", "min"}, {"fminf", "min"},  {"fmax", "max"},
        {"fmaxf", "max"},  {"fma", "mad"},   {"fmaf", "mad"}, {"sqr", "square"}, {"exp2f", "exp2"},
        {"log2f", "log2"}, {"expf", "exp"},  {"logf", "log"}, {"powf", "pow"},   {"sqrtf", "sqrt"},
        {"sinf", "sin"},   {"cosf", "cos"}};
    if (auto it = kAlias.find(name); it != kAlias.end()) name = it->second;
    if (auto it = spelledCalls().find(name); it != spelledCalls().end())
      name = std::string(opName(it->second));
    auto arityErr = [&](size_t want) {
      return fail("'" + given + "' takes " + std::to_string(want) + " argument" +
                  (want == 1 ? "" : "s") + ", got " + std::to_string(a.size()));
    };
    if (name == "float" || name == "half" || name == "double" || name == "min16float") {
      if (a.size() != 1) return arityErr(1);
      out = val(a[0]);
      return true;
    }
    if (name == "clamp") {
      if (a.size() != 3) return arityErr(3);
      const Node &lo = d_.nodes[a[1]], &hi = d_.nodes[a[2]];
      const int id = (lo.isConst() && lo.value == 0 && hi.isConst() && hi.value == 1)
                         ? mk1(Op::Saturate, a[0])
                         : mk2(Op::Min, mk2(Op::Max, a[0], a[1]), a[2]);
      out = val(id);
      return true;
    }
    for (const char* v : {"float", "half", "vec"}) {
      const std::string pre = v;
      if (name.rfind(pre, 0) == 0 && name.size() == pre.size() + 1 && name.back() >= '2' &&
          name.back() <= '4') {
        const size_t n = static_cast<size_t>(name.back() - '0');
        if (a.size() != n) return arityErr(n);
        out = tupleOf(a);
        return true;
      }
    }
    auto op = opFromString(name);
    if (!op) return fail("unknown function '" + given + "'");
    if (static_cast<int>(a.size()) != arity(*op)) return arityErr(arity(*op));
    std::array<int, kMaxArity> args{-1, -1, -1, -1};
    for (size_t k = 0; k < a.size(); ++k) args[k] = a[k];
    out = val(mk(*op, args));
    return true;
  }

  Dag& d_;
  const ParseOptions& o_;
  std::map<std::string, int>& scope_;
  std::set<std::string>& unread_;
  std::vector<Token> t_;
  size_t p_ = 0;
  int depth_ = 0;
  std::string where_;
  std::string err_;
};

std::string joinNames(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& x : v) s += (s.empty() ? "" : ", ") + x;
  return s;
}

}  // namespace

Expected<ParsedFormula> parseFormula(const std::vector<std::string>& texts,
                                     const ParseOptions& opts) {
  const size_t k = opts.output_names.size();
  if (k == 0) return Status::error("formula: the table has no outputs");
  if (texts.empty()) return Status::error("formula: no expression given");
  if (texts.size() != 1 && texts.size() != k)
    return Status::error("expr: got " + std::to_string(texts.size()) + " expressions for " +
                         std::to_string(k) + " outputs (" + joinNames(opts.output_names) +
                         "); give one per output, or one that assigns every output");
  size_t bytes = 0;
  for (const auto& t : texts) bytes += t.size();
  if (bytes > kMaxFormulaBytes)
    return Status::error("expr: " + std::to_string(bytes) + " bytes, more than the limit of " +
                         std::to_string(kMaxFormulaBytes) + " for one formula");
  for (const auto& [from, to] : opts.aliases)
    if (std::find(opts.input_names.begin(), opts.input_names.end(), to) == opts.input_names.end())
      return Status::error("alias " + from + "=" + to + ": '" + to +
                           "' is not a table input (inputs: " + joinNames(opts.input_names) + ")");
  ParsedFormula pf;
  Dag& d = pf.dag;
  d.num_inputs = static_cast<int>(opts.input_names.size());
  std::map<std::string, int> scope;
  std::set<std::string> unread;
  std::vector<std::vector<Statement>> all;
  for (size_t i = 0; i < texts.size(); ++i) {
    Parser p(d, opts, scope, unread);
    auto st = p.parse(texts[i], texts.size() == 1 ? "expr" : "expr[" + std::to_string(i) + "]");
    if (!st) return st.status();
    all.push_back(std::move(*st));
  }
  auto isOutputName = [&](const std::string& n) {
    return std::find(opts.output_names.begin(), opts.output_names.end(), n) !=
           opts.output_names.end();
  };
  // An expression that ends by assigning a name that is no output (`C = mu` on a table
  // whose output is B) names an output the table does not have.
  for (size_t i = 0; i < all.size(); ++i) {
    const std::string& last = all[i].back().assigned;
    if (!last.empty() && !isOutputName(last))
      return Status::error(
          (texts.size() == 1 ? std::string("expr") : "expr[" + std::to_string(i) + "]") +
          ": its last statement assigns '" + last +
          "', which is not an output of the table (outputs: " + joinNames(opts.output_names) +
          "); end with an output's assignment or a bare expression");
  }
  std::vector<int> outs(k, -1);
  if (texts.size() == k) {
    bool by_name = true;
    std::vector<std::string> names;
    for (const auto& st : all) {
      const auto& last = st.back();
      by_name = by_name && isOutputName(last.assigned) &&
                std::find(names.begin(), names.end(), last.assigned) == names.end();
      names.push_back(last.assigned);
    }
    by_name = by_name && k > 1;
    for (size_t j = 0; j < k; ++j) {
      const auto& last = all[j].back();
      if (!last.value.tuple.empty())
        return Status::error("expr[" + std::to_string(j) +
                             "]: a vector value needs a single "
                             "expression for all outputs");
      if (by_name) {
        const size_t o =
            std::find(opts.output_names.begin(), opts.output_names.end(), last.assigned) -
            opts.output_names.begin();
        outs[o] = last.value.id;
      } else {
        outs[j] = last.value.id;
      }
    }
  } else if (texts.size() == 1) {
    const auto& st = all[0];
    bool all_named = true;
    for (const auto& n : opts.output_names) all_named = all_named && scope.count(n) > 0;
    std::vector<int> bare;
    for (const auto& s : st)
      if (s.assigned.empty() && s.value.tuple.empty()) bare.push_back(s.value.id);
    if (all_named) {
      for (size_t j = 0; j < k; ++j) outs[j] = scope[opts.output_names[j]];
    } else if (st.back().value.tuple.size() == k) {
      outs = st.back().value.tuple;
    } else if (bare.size() == k) {
      outs = bare;
    } else {
      std::string missing;
      for (const auto& n : opts.output_names)
        if (!scope.count(n)) missing += (missing.empty() ? "" : ", ") + n;
      return Status::error("expr: the table has " + std::to_string(k) + " outputs (" +
                           joinNames(opts.output_names) +
                           "); assign each of them (missing: " + missing + "), return a " +
                           std::to_string(k) + "-vector, or give one expression per output");
    }
  } else {
    return Status::error("expr: got " + std::to_string(texts.size()) + " expressions for " +
                         std::to_string(k) + " outputs (" + joinNames(opts.output_names) +
                         "); give one per output, or one that assigns every output");
  }
  d.outputs = outs;
  d = d.compact();
  auto lp = toProgram(d);
  if (!lp) return lp.status();
  pf.program = std::move(lp->program);
  pf.shape.num_inputs = std::max(1, d.num_inputs);
  pf.shape.num_outputs = static_cast<int>(k);
  pf.shape.max_length = std::max<int>(1, static_cast<int>(pf.program.code.size()));
  pf.shape.num_constants = static_cast<int>(pf.program.constants.size());
  pf.shape.output_mode = lp->output_mode;
  pf.shape.ops = OpSet::all();
  if (Status s = validate(pf.program, pf.shape); !s)
    return Status::error("formula: internal error, parsed program is invalid: " + s.message());
  pf.infix = dagInfix(d, opts.input_names);
  return pf;
}

}  // namespace lgp::emit
