// HLSL / GLSL / C++ rendering of a simplified DAG (see emit.hpp and emit/README.md).
#include "lgp/emit/emit.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <map>
#include <set>

#include "helpers.hpp"
#include "lgp/core/text_check.hpp"
#include "lgp/emit/half.hpp"
#include "lgp/eval/semantics.hpp"
#include "lgp/io/result.hpp"
#include "metrics.hpp"
#include "syntax.hpp"

namespace lgp::emit {

using detail::Ctx;
using detail::Helper;
using detail::HelperSet;
using detail::replaceAll;

const LanguageInfo& languageInfo(Language l) {
  for (const auto& i : allLanguages())
    if (i.lang == l) return i;
  return allLanguages()[0];
}

std::string_view toString(Language l) {
  return languageInfo(l).name;
}

std::optional<Language> languageFromString(std::string_view s) {
  for (const auto& i : allLanguages())
    if (i.name == s) return i.lang;
  if (s == "c++") return Language::Cpp;
  return std::nullopt;
}

std::string languageChoices() {
  std::string s;
  const auto& all = allLanguages();
  for (size_t i = 0; i < all.size(); ++i)
    s += (i == 0 ? "" : (i + 1 == all.size() ? " or " : ", ")) + std::string(all[i].name);
  return s;
}

namespace {
bool isIdentifier(std::string_view s) {
  if (s.empty() || std::isdigit(static_cast<unsigned char>(s[0]))) return false;
  for (char ch : s)
    if (!(std::isalnum(static_cast<unsigned char>(ch)) || ch == '_')) return false;
  return true;
}

// Reserved words of HLSL, GLSL and C++ that are plausible column names.
const std::set<std::string>& reservedWords() {
  static const std::set<std::string> k = {
      "auto",     "bool",      "break",    "case",    "centroid", "char",     "class",  "const",
      "continue", "default",   "delete",   "discard", "do",       "double",   "else",   "enum",
      "extern",   "false",     "flat",     "float",   "for",      "half",     "if",     "in",
      "inline",   "inout",     "input",    "int",     "line",     "linear",   "long",   "main",
      "matrix",   "namespace", "new",      "out",     "output",   "packed",   "point",  "precise",
      "register", "return",    "sample",   "sampler", "shared",   "short",    "signed", "static",
      "struct",   "switch",    "template", "texture", "this",     "triangle", "true",   "typedef",
      "uniform",  "union",     "unsigned", "using",   "vec2",     "vec3",     "vec4",   "vector",
      "void",     "volatile",  "while",    "min",     "max",      "abs",      "sqrt",   "exp",
      "exp2",     "log",       "log2",     "pow",     "sin",      "cos",      "lerp",   "mix",
      "saturate", "clamp",     "rcp",      "rsqrt",   "mad",      "fma",      "select", "float2",
      "float3",   "float4",    "half2",    "std",     "operator", "private",  "public", "protected",
      "virtual",  "friend"};
  return k;
}

// What each language writes differently (syntax.hpp's row of the language).
std::string localQualifier(Language l) {
  return std::string(detail::syntaxOf(l).local_qualifier);
}
// rcp where the protection is proven unreachable (`one`: 1 in the context's precision).
std::string rawRcp(Language l, const std::string& one) {
  return detail::replaceAll(std::string(detail::syntaxOf(l).raw_rcp), "$1", one);
}
bool nativeSaturate(Language l) {
  return detail::syntaxOf(l).native_saturate;
}
// saturate where its NaN branch is proven unreachable.
std::string rawClamp01(Language l, const std::string& zero, const std::string& one) {
  return detail::replaceAll(
      detail::replaceAll(std::string(detail::syntaxOf(l).raw_clamp01), "$0", zero), "$1", one);
}
// min and max are written as the language's own (the GPU's) where it orders NaN like the
// interpreter; elsewhere (C++'s std::min) helpers unless NaN is proven absent.
bool rawMinMax(Language l) {
  return detail::syntaxOf(l).raw_min_max;
}
// Whether results of two to four outputs can be a vector (float2, vec3); else a struct.
bool hasVectorTypes(Language l) {
  return !detail::syntaxOf(l).vector_prefix[static_cast<int>(Precision::Float)].empty();
}
std::string functionQualifier(Language l) {
  return std::string(detail::syntaxOf(l).function_qualifier);
}
std::string unusedParameter(Language l) {
  return std::string(detail::syntaxOf(l).unused_parameter);
}
std::string halfRequirement(Language l) {
  return std::string(detail::syntaxOf(l).half_requirement);
}
// The #include lines the code needs (`vm`: the exact-math helpers).
std::string includeLines(Language l, bool vm) {
  const auto& syn = detail::syntaxOf(l);
  if (syn.includes.empty()) return "";
  return std::string(syn.includes) + (vm ? std::string(syn.vm_includes) : "") + "\n";
}

std::string stripOuterParens(const std::string& s) {
  if (s.size() < 2 || s.front() != '(' || s.back() != ')') return s;
  int depth = 0;
  for (size_t i = 0; i < s.size(); ++i) {
    if (s[i] == '(') ++depth;
    if (s[i] == ')') --depth;
    if (depth == 0 && i + 1 < s.size()) return s;  // the first '(' closes early
  }
  return s.substr(1, s.size() - 2);
}

// Substitutes operands into a template. An operand that is a whole function argument
// (between '(' or ", " and ')' or ',') loses its outer parentheses: `saturate(x - y)`
// rather than `saturate((x - y))`.
std::string applyTemplate(std::string_view t, const std::vector<std::string>& a) {
  std::string s;
  for (size_t i = 0; i < t.size(); ++i) {
    if (t[i] == '{' && i + 2 < t.size() && t[i + 2] == '}' && t[i + 1] >= '0' && t[i + 1] <= '3') {
      const bool open =
          i > 0 &&
          (t[i - 1] == '('
               ? i > 1 && (std::isalnum(static_cast<unsigned char>(t[i - 2])) || t[i - 2] == '_')
               : (i > 1 && t[i - 1] == ' ' && t[i - 2] == ','));
      const bool close = i + 3 < t.size() && (t[i + 3] == ')' || t[i + 3] == ',');
      const std::string& arg = a[t[i + 1] - '0'];
      s += open && close ? stripOuterParens(arg) : arg;
      i += 2;
    } else {
      s += t[i];
    }
  }
  return s;
}

int placeholderCount(std::string_view t, int k) {
  const std::string ph = "{" + std::to_string(k) + "}";
  int n = 0;
  for (size_t p = t.find(ph); p != std::string_view::npos; p = t.find(ph, p + 1)) ++n;
  return n;
}

std::string fmtMetric(double v) {
  char buf[32];
  if (!std::isfinite(v)) return v > 0 ? "inf" : (v < 0 ? "-inf" : "nan");
  std::snprintf(buf, sizeof buf, "%.4g", v);
  return buf;
}

class Renderer {
 public:
  Renderer(const Dag& d, const Ctx& c, const EmitOptions& o, std::vector<Interval> iv,
           std::vector<std::string> params)
      : d_(d), c_(c), o_(o), iv_(std::move(iv)), params_(std::move(params)) {
    uses_ = d_.useCounts();
    name_.resize(d_.nodes.size());
    prefix_ = "t";
    for (const auto& p : params_)
      if (p.size() > 1 && p[0] == 't' &&
          std::all_of(p.begin() + 1, p.end(), [](char ch) { return std::isdigit(ch); }))
        prefix_ = "lgp_t";
  }

  std::string ref(int id) {
    const Node& n = d_.nodes[id];
    if (n.kind == Node::Kind::Var) return params_[n.index];
    if (n.kind == Node::Kind::Const) return detail::literal(n.value, c_);
    if (!name_[id].empty()) return name_[id];
    if (uses_[id] > 1) return bind(id);
    return expr(id);
  }

  std::string bind(int id) {
    if (!d_.nodes[id].isOp()) return ref(id);
    if (!name_[id].empty()) return name_[id];
    const std::string e = expr(id);
    const std::string nm = prefix_ + std::to_string(counter_++);
    body_ += "  " + localQualifier(c_.lang) + detail::scalarType(c_) + " " + nm + " = " +
             stripOuterParens(e) + ";\n";
    name_[id] = nm;
    return nm;
  }

  std::string expr(int id) {
    const Node& n = d_.nodes[id];
    const std::string t = opTemplate(id);
    std::vector<std::string> a(kMaxArity);
    for (int k = 0; k < arity(n.op); ++k)
      a[k] = placeholderCount(t, k) > 1 ? bind(n.args[k]) : ref(n.args[k]);
    return applyTemplate(t, a);
  }

  // The output expression with the inverse target transform applied, with the same
  // protected semantics as the scorer (objectives.cpp): exp, v > 0 ? v*v : 0, rcp.
  std::string output(int id, TargetTransform tr) {
    switch (tr) {
      case TargetTransform::None:
        return ref(id);
      case TargetTransform::Log:
        return useHelper(Helper::Exp, "lgp_exp(" + stripOuterParens(ref(id)) + ")");
      case TargetTransform::Sqrt: {
        const std::string v = bind(id), zero = detail::literal(0.0, c_);
        return "(" + v + " > " + zero + " ? " + v + " * " + v + " : " + zero + ")";
      }
      case TargetTransform::Rcp:
        return useHelper(Helper::Rcp, "lgp_rcp(" + stripOuterParens(ref(id)) + ")");
    }
    return ref(id);
  }

  const std::string& body() const { return body_; }
  const HelperSet& helpers() const { return helpers_; }
  const std::set<std::string>& rawOps() const { return raw_ops_; }

 private:
  std::string useHelper(Helper h, const std::string& call) {
    detail::addWithDeps(helpers_, h, c_);
    return call;
  }

  // The op table's spelling with its literals in the context's precision (the C++ column
  // writes float literals).
  std::string fix(std::string_view t) const {
    std::string s(t);
    if (c_.prec == Precision::Double) {
      s = replaceAll(s, "1.0f", "1.0");
      s = replaceAll(s, "0.0f", "0.0");
    }
    return s;
  }

  std::string opTemplate(int id) {
    const Node& n = d_.nodes[id];
    const OpInfo& info = opInfo(n.op);
    const bool vm = detail::exactMath(c_);
    const std::string_view raw_t = detail::opSpelling(info, c_.lang);
    const bool raw = o_.fast && provenUnguarded(d_, id, iv_);
    auto markRaw = [&] { raw_ops_.insert(std::string(info.name)); };
    const std::string one = detail::literal(1.0, c_), zero = detail::literal(0.0, c_);
    const std::string l2e = detail::literal(
        c_.prec == Precision::Double ? sem::kLog2E : double(float(sem::kLog2E)), c_);
    const std::string ln2 =
        detail::literal(c_.prec == Precision::Double ? sem::kLn2 : double(float(sem::kLn2)), c_);
    auto vmUse = [&](std::string s) {
      if (vm) detail::addWithDeps(helpers_, Helper::Vm, c_);
      return s;
    };
    switch (n.op) {
      case Op::Add:
      case Op::Sub:
      case Op::Mul:
      case Op::Mad:
      case Op::Neg:
      case Op::Square:
      case Op::Abs:
      case Op::Lerp:
      case Op::Select:
        return fix(raw_t);
      case Op::Div:
        if (raw) return markRaw(), fix(raw_t);
        return useHelper(Helper::Div, "lgp_div({0}, {1})");
      case Op::Rcp:
        if (raw) return markRaw(), rawRcp(c_.lang, one);
        return useHelper(Helper::Rcp, "lgp_rcp({0})");
      case Op::Sqrt:
        if (raw) return markRaw(), detail::primitive("sqrt", c_) + "({0})";
        return useHelper(Helper::Sqrt, "lgp_sqrt({0})");
      case Op::Rsqrt:
        if (raw) return markRaw(), fix(raw_t);
        return useHelper(Helper::Rsqrt, "lgp_rsqrt({0})");
      case Op::Exp2:
        if (raw) return markRaw(), vmUse(detail::primitive("exp2", c_) + "({0})");
        return useHelper(Helper::Exp2, "lgp_exp2({0})");
      case Op::Log2:
        if (raw) return markRaw(), vmUse(detail::primitive("log2", c_) + "({0})");
        return useHelper(Helper::Log2, "lgp_log2({0})");
      case Op::Exp:
        if (raw) return markRaw(), vm ? vmUse("lgp_vm_exp2({0} * " + l2e + ")") : fix(raw_t);
        return useHelper(Helper::Exp, "lgp_exp({0})");
      case Op::Log:
        if (raw) return markRaw(), vm ? vmUse("(lgp_vm_log2({0}) * " + ln2 + ")") : fix(raw_t);
        return useHelper(Helper::Log, "lgp_log({0})");
      case Op::Pow:
        if (raw) return markRaw(), vm ? vmUse("lgp_vm_exp2({1} * lgp_vm_log2({0}))") : fix(raw_t);
        return useHelper(Helper::Pow, "lgp_pow({0}, {1})");
      case Op::Sin:
      case Op::Cos:
        if (vm) return vmUse("lgp_vm_" + std::string(info.name) + "({0})");
        return fix(raw_t);
      case Op::Min:
      case Op::Max:
        if (raw || rawMinMax(c_.lang)) return fix(raw_t);
        return useHelper(n.op == Op::Min ? Helper::Min : Helper::Max,
                         n.op == Op::Min ? "lgp_min({0}, {1})" : "lgp_max({0}, {1})");
      case Op::Saturate:
        if (nativeSaturate(c_.lang)) return fix(raw_t);
        if (raw) return markRaw(), rawClamp01(c_.lang, zero, one);
        return useHelper(Helper::Saturate, "lgp_saturate({0})");
    }
    return fix(raw_t);
  }

  const Dag& d_;
  Ctx c_;
  const EmitOptions& o_;
  std::vector<Interval> iv_;
  std::vector<std::string> params_;
  std::vector<int> uses_;
  std::vector<std::string> name_;
  std::string prefix_;
  int counter_ = 0;
  std::string body_;
  HelperSet helpers_;
  std::set<std::string> raw_ops_;
};

std::string vectorType(const Ctx& c, size_t k) {
  const std::string_view prefix = detail::syntaxOf(c.lang).vector_prefix[static_cast<int>(c.prec)];
  return prefix.empty() ? "" : std::string(prefix) + std::to_string(k);
}

std::string metricsLine(const nlohmann::json& m) {
  if (!m.is_object()) return "";
  std::string s;
  for (const char* key : {"rmse", "max_abs", "mae", "mean_rel", "r2"}) {
    if (!m.contains(key) || !m[key].is_number()) continue;
    s += std::string(s.empty() ? "" : " ") + key + " " + fmtMetric(m[key].get<double>());
  }
  return s;
}

std::string metricsLine(const OutputMetrics& m) {
  return "rmse " + fmtMetric(m.rmse) + " max_abs " + fmtMetric(m.max_abs) + " mae " +
         fmtMetric(m.mae) + " mean_rel " + fmtMetric(m.mean_rel) + " r2 " + fmtMetric(m.r2);
}

}  // namespace

std::string commentText(std::string_view text) {
  // A newline would end the // comment and start code; a backslash (or the trigraph ??/)
  // at the end of the line would continue the comment onto the next line. Bytes outside
  // printable ASCII, '%' and '\\' are written as %XX, and a '?' after a '?' as %3F, so
  // neither can appear.
  static constexpr char kHex[] = "0123456789ABCDEF";
  std::string out;
  for (size_t i = 0; i < text.size(); ++i) {
    const auto c = static_cast<unsigned char>(text[i]);
    const bool plain = c >= 0x20 && c < 0x7f && c != '%' && c != '\\' &&
                       !(c == '?' && i > 0 && text[i - 1] == '?');
    if (plain) {
      out += static_cast<char>(c);
    } else {
      out += '%';
      out += kHex[c >> 4];
      out += kHex[c & 15];
    }
  }
  return out;
}

std::string sanitizeIdentifier(std::string_view name) {
  std::string s;
  for (char ch : name) s += (std::isalnum(static_cast<unsigned char>(ch)) || ch == '_') ? ch : '_';
  if (s.empty() || std::isdigit(static_cast<unsigned char>(s[0]))) s = "_" + s;
  if (s.rfind("lgp_", 0) == 0 || s.rfind("gl_", 0) == 0 || s.find("__") != std::string::npos)
    s = "v_" + s;
  if (reservedWords().count(s)) s += "_";
  return s;
}

Status EmitOptions::validate(Language lang) const {
  if (!isIdentifier(function_name) || reservedWords().count(function_name) ||
      function_name.rfind("lgp_vm_", 0) == 0)
    return Status::error("function name: '" + function_name +
                         "' is not a usable identifier (letters, digits, _; not a keyword)");
  // The languages that offer an option, for the message of one that does not.
  auto offering = [](bool LanguageInfo::*has) {
    std::string s;
    for (const auto& i : allLanguages())
      if (i.*has) s += (s.empty() ? "" : " and ") + std::string(i.title);
    return s;
  };
  const LanguageInfo& info = languageInfo(lang);
  if (precision == Precision::Half && !info.half)
    return Status::error("precision: half is only available for " + offering(&LanguageInfo::half) +
                         " (got " + std::string(info.name) + ")");
  if (precision == Precision::Double && !info.double_precision)
    return Status::error("precision: double is only available for " +
                         offering(&LanguageInfo::double_precision) + " (got " +
                         std::string(info.name) + ")");
  if (exact_math && (!info.exact_math || precision != Precision::Float))
    return Status::error("exact_math: only for " + offering(&LanguageInfo::exact_math) +
                         " with float precision");
  return Status::ok();
}

namespace {

// A program the emitter can walk: outputs, transforms and constants as the table says, and
// every operand reading something that exists before it.
Status checkEmitInput(const EmitInput& in) {
  const size_t k = in.program.outputs.size();
  const int ni = static_cast<int>(in.input_names.size());
  if (k == 0) return Status::error("program: has no outputs");
  if (!in.output_names.empty() && in.output_names.size() != k)
    return Status::error("outputs: the program has " + std::to_string(k) +
                         " outputs but the table names " + std::to_string(in.output_names.size()));
  if (!in.transforms.empty() && in.transforms.size() != k)
    return Status::error("transforms: expected one per output (" + std::to_string(k) + ")");
  for (float c : in.program.constants)
    if (!std::isfinite(c)) return Status::error("program: a constant is not finite");
  for (size_t i = 0; i < in.program.code.size(); ++i)
    for (int a = 0; a < arity(in.program.code[i].op); ++a) {
      const Operand& o = in.program.code[i].args[a];
      if (o.kind == OperandKind::Var && o.index >= ni)
        return Status::error("program: opcode " + std::to_string(i) + " reads input x" +
                             std::to_string(o.index) + " but the table has " + std::to_string(ni) +
                             " inputs");
      if (o.kind == OperandKind::Const && o.index >= in.program.constants.size())
        return Status::error("program: opcode " + std::to_string(i) + " reads constant c" +
                             std::to_string(o.index) + " which does not exist");
      if (o.kind == OperandKind::Reg && o.index >= i)
        return Status::error("program: opcode " + std::to_string(i) + " reads a later register r" +
                             std::to_string(o.index));
    }
  for (uint8_t o : in.program.outputs)
    if (o >= in.program.code.size())
      return Status::error("program: output refers to opcode " + std::to_string(o) +
                           " which does not exist");
  return Status::ok();
}

// Identifiers for names from a table: sanitized, and made distinct by appending '_'.
std::vector<std::string> identifiers(const std::vector<std::string>& names) {
  std::vector<std::string> ids;
  for (const auto& n : names) {
    std::string p = sanitizeIdentifier(n);
    while (std::find(ids.begin(), ids.end(), p) != ids.end()) p += "_";
    ids.push_back(p);
  }
  return ids;
}

// The emitted function's outside: its parameters, its outputs' names and how they are
// returned (a scalar, a vector, or a struct for C++ and for more than four outputs).
struct Interface {
  Language lang;
  size_t k;
  std::string T;  // the scalar type
  bool use_struct;
  std::string struct_name, ret_type;
  std::vector<std::string> params, onames;

  Interface(const EmitInput& in, const Ctx& ctx, Language l, const EmitOptions& opts)
      : lang(l),
        k(in.program.outputs.size()),
        T(detail::scalarType(ctx)),
        use_struct(k > 1 && (!hasVectorTypes(l) || k > 4)),
        struct_name(opts.function_name + "_result"),
        ret_type(k == 1 ? T : (use_struct ? struct_name : vectorType(ctx, k))),
        params(identifiers(in.input_names)) {
    std::vector<std::string> outs;
    for (size_t j = 0; j < k; ++j)
      outs.push_back(j < in.output_names.size() ? in.output_names[j] : "y" + std::to_string(j));
    onames = identifiers(outs);
  }

  // The return statement for one value per output.
  std::string returnOf(const std::vector<std::string>& values) const {
    std::string list;
    for (size_t j = 0; j < values.size(); ++j)
      list += (j ? ", " : "") + stripOuterParens(values[j]);
    if (k == 1) return "  return " + list + ";\n";
    if (!use_struct) return "  return " + ret_type + "(" + list + ");\n";
    return detail::replaceAll(
        detail::replaceAll(std::string(detail::syntaxOf(lang).struct_return), "$S", struct_name),
        "$L", list);
  }
  // How a caller reads output j of the result ("" for a scalar).
  std::string access(size_t j) const {
    return k == 1 ? "" : use_struct ? "." + onames[j] : "." + std::string(1, "xyzw"[j]);
  }
  std::string signature(const std::string& name, const std::vector<uint8_t>& used) const {
    std::string sig = functionQualifier(lang) + ret_type + " " + name + "(";
    for (size_t i = 0; i < params.size(); ++i)
      sig +=
          (i ? ", " : "") + (used[i] ? std::string() : unusedParameter(lang)) + T + " " + params[i];
    return sig + ")";
  }
  std::string structDef() const {
    if (!use_struct) return "";
    std::string def = "struct " + struct_name + " {";
    for (size_t j = 0; j < k; ++j) def += " " + T + " " + onames[j] + ";";
    return def + " };\n";
  }
};

// The header comment's error lines: the front's metrics (float32 search, double reference)
// and, with a table, the emitted code's own in its precision.
Status errorLines(const EmitInput& in, const EmitOptions& opts, const Interface& f, const Dag& d,
                  const std::vector<TargetTransform>& tr,
                  const std::function<void(const std::string&)>& line) {
  for (const char* kind : {"float32", "double"}) {
    for (size_t j = 0; j < f.k; ++j) {
      if (!in.output_metrics.is_array() || j >= in.output_metrics.size()) break;
      const std::string m = metricsLine(in.output_metrics[j].value(kind, nlohmann::json()));
      if (m.empty()) continue;
      line(std::string(j == 0 ? (std::string(kind) == "float32" ? "Error (search, float32): "
                                                                : "Error (double reference): ")
                              : "                          ") +
           f.onames[j] + " " + m);
    }
  }
  if (opts.table) {
    auto m = detail::dagMetrics(d, *opts.table, tr, opts.precision);
    if (!m) return m.status();
    const std::string first =
        "Error (this code, " + std::string(toString(opts.precision)) + " arithmetic, on " +
        (opts.table_label.empty() ? std::string("the given table") : opts.table_label) + ", " +
        std::to_string(opts.table->rows()) + " rows): ";
    for (size_t j = 0; j < f.k; ++j)
      line((j == 0 ? first : std::string(first.size(), ' ')) + f.onames[j] + " " +
           metricsLine((*m)[j]));
  } else if (opts.precision == Precision::Half) {
    line("Error in half precision: not measured (no table given)");
  }
  return Status::ok();
}

// The header comment's cost lines: the emitted DAG's cost per target (and the search's when
// it differs), its piecewise operators, helpers and what --fast left unguarded.
void costLines(const EmitInput& in, const EmitOptions& opts, const Emitted& out,
               const std::function<void(const std::string&)>& line) {
  const Dag& d = out.dag;
  std::string cost;
  for (int t = 0; t < kNumCostTargets; ++t)
    cost += (t ? ", " : "") + std::string(kCostTargetNames[t]) + " " + fmtMetric(out.cost[t]);
  line("Cost: " + cost);
  if (in.cost_by_target.is_object()) {
    std::string sc;
    bool differs = false;
    for (int t = 0; t < kNumCostTargets; ++t) {
      const auto key = std::string(kCostTargetNames[t]);
      if (!in.cost_by_target.contains(key) || !in.cost_by_target[key].is_number()) continue;
      const double v = in.cost_by_target[key].get<double>();
      differs = differs || std::fabs(v - out.cost[t]) > 1e-9;
      sc += (sc.empty() ? "" : ", ") + key + " " + fmtMetric(v);
    }
    if (differs) line("      (as scored by the search: " + sc + ")");
  }
  std::string pw;
  std::map<std::string, int> pw_ops;
  for (const Node& n : d.nodes)
    if (n.isOp() && opInfo(n.op).piecewise) ++pw_ops[std::string(opName(n.op))];
  for (const auto& [nm, cnt] : pw_ops)
    pw += (pw.empty() ? "" : ", ") + nm + (cnt > 1 ? " x" + std::to_string(cnt) : "");
  line("Piecewise ops: " + std::to_string(out.piecewise) + (pw.empty() ? "" : " (" + pw + ")"));
  if (!out.helpers.empty()) {
    std::string hs;
    for (const auto& h : out.helpers)
      if (h != "lgp_vm") hs += (hs.empty() ? "" : ", ") + h;
    line("Protected ops call exact-semantics helpers: " + hs);
  }
  bool any_protected = false;
  for (const Node& n : d.nodes) any_protected = any_protected || (n.isOp() && isProtected(n.op));
  if (opts.fast && !any_protected && out.raw_ops.empty())
    line("--fast: no protected ops in this function");
  else if (opts.fast)
    line(out.raw_ops.empty() ? "--fast: no protected op could be proven unguarded on the domain"
                             : "--fast: raw " +
                                   [&] {
                                     std::string s;
                                     for (const auto& o : out.raw_ops)
                                       s += (s.empty() ? "" : ", ") + o;
                                     return s;
                                   }() +
                                   " (proven never to reach the protection on the domain)");
}

// The comment above the function: what it is, where it came from, how well and at what cost
// it fits. Every line goes through commentText: names, paths and formulas come from tables
// and configs written by others.
Expected<std::string> headerComment(const EmitInput& in, const EmitOptions& opts,
                                    const Interface& f, const Emitted& out,
                                    const std::vector<TargetTransform>& tr) {
  std::string hdr;
  auto line = [&](const std::string& s) { hdr += "// " + commentText(s) + "\n"; };
  const Language lang = f.lang;
  const int ni = static_cast<int>(f.params.size());
  line(opts.function_name + ": generated by lgp emit (" + std::string(toString(lang)) + ", " +
       std::string(toString(opts.precision)) + ")" +
       (opts.source.empty() ? "" : " from " + opts.source) + ". Re-emit rather than edit.");
  std::string dom;
  for (int i = 0; i < ni; ++i) {
    dom += (i ? ", " : "") + f.params[i];
    if (i < static_cast<int>(in.domain.size()) && in.domain[i].finite())
      dom += " in [" + formatFloat(static_cast<float>(in.domain[i].lo)) + ", " +
             formatFloat(static_cast<float>(in.domain[i].hi)) + "]";
  }
  line("Formula: " + out.formula);
  line("Fitted on: " +
       (in.table_desc.empty() ? std::string("(table not recorded)") : in.table_desc) + "; domain " +
       dom);
  std::string outs;
  for (size_t j = 0; j < f.k; ++j)
    outs += (j ? ", " : "") + f.onames[j] +
            (tr[j] == TargetTransform::None
                 ? ""
                 : " (fitted on " + std::string(toString(tr[j])) + ", inverse applied)");
  line(std::string(f.k > 1 ? "Returns " + (f.use_struct ? f.struct_name : f.ret_type) + ": "
                           : "Returns ") +
       outs);
  if (auto s = errorLines(in, opts, f, out.dag, tr, line); !s) return s;
  costLines(in, opts, out, line);
  for (const auto& l : opts.header_lines) line(l);
  if (opts.precision == Precision::Half)
    if (const std::string r = halfRequirement(lang); !r.empty()) line(r);
  if (const std::string w = halfRangeWarning(out); !w.empty()) line("Warning: " + w);
  if (opts.exact_math)  // C++ only (EmitOptions::validate)
    line(
        "Exact math: bit-identical to the lgp float32 interpreter (compile with "
        "-ffp-contract=off)");
  return hdr;
}

}  // namespace

std::string halfRangeWarning(const Emitted& e) {
  auto list = [](const std::vector<double>& v) {
    std::string cs;
    for (size_t i = 0; i < v.size(); ++i)
      cs += (i ? ", " : "") + formatFloat(static_cast<float>(v[i]));
    return "constant" + std::string(v.size() > 1 ? "s " : " ") + cs;
  };
  std::string w;
  if (!e.half_overflow.empty())
    w = list(e.half_overflow) + " beyond binary16's range (" + formatFloat(kHalfMax) +
        "): infinite in half";
  if (!e.half_underflow.empty())
    w += (w.empty() ? "" : "; ") + list(e.half_underflow) +
         " below binary16's smallest subnormal (" + formatFloat(kHalfMinSubnormal) + "): 0 in half";
  if (w.empty()) return "";
  return w + ", so this member does not suit a half export (use float)";
}

Expected<Emitted> emitProgram(const EmitInput& in, Language lang, const EmitOptions& opts) {
  if (Status s = opts.validate(lang); !s) return s;
  if (Status s = checkEmitInput(in); !s) return s;
  const size_t k = in.program.outputs.size();
  const int ni = static_cast<int>(in.input_names.size());

  Ctx ctx{lang, opts.precision, opts.exact_math};
  // The front printer's DAG (formula.hpp), folded in the emitted precision.
  SimplifyOptions so = formulaSimplifyOptions(in.domain);
  so.precision = opts.precision;
  so.pow_rewrites = opts.pow_rewrites;
  so.domain_rewrites = opts.domain_rewrites;
  Emitted out;
  Dag dag = buildDag(in.program, ni);
  if (opts.precision == Precision::Half) {
    // Folded in float32 first, as it was scored: a term the scored program drops (0 times a
    // constant beyond binary16's range, which half would make 0*inf = NaN) never reaches half.
    SimplifyOptions scored = so;
    scored.precision = Precision::Float;
    dag = simplify(dag, scored);
    for (const Node& n : dag.nodes) {
      if (!n.isConst() || !std::isfinite(n.value)) continue;
      const float h = roundToHalf(static_cast<float>(n.value));
      if (!std::isfinite(h)) out.half_overflow.push_back(n.value);
      if (h == 0.0f && n.value != 0.0) out.half_underflow.push_back(n.value);
    }
  }
  out.dag = simplify(dag, so);
  out.formula = printFormula(out.dag, in.input_names, in.output_names).text();
  const Dag& d = out.dag;
  const std::vector<Interval> iv = nodeIntervals(d, in.domain);
  const Interface f(in, ctx, lang, opts);
  std::vector<TargetTransform> tr = in.transforms;
  tr.resize(k, TargetTransform::None);

  Renderer r(d, ctx, opts, iv, f.params);
  std::vector<std::string> results;
  for (size_t j = 0; j < k; ++j) results.push_back(r.output(d.outputs[j], tr[j]));

  // Costs and piecewise count of what is emitted.
  for (int t = 0; t < kNumCostTargets; ++t) {
    const CostModel cm = CostModel::preset(static_cast<CostTarget>(t), in.domain);
    out.cost[t] = cm.dagCost(d) + cm.transformCost(tr);
  }
  out.piecewise = countPiecewise(d);
  for (int h = 0; h < static_cast<int>(Helper::Count); ++h)
    if (r.helpers().test(h)) out.helpers.push_back(detail::helperName(static_cast<Helper>(h)));
  out.raw_ops.assign(r.rawOps().begin(), r.rawOps().end());

  out.function_name = opts.function_name;
  out.num_inputs = ni;
  out.return_type = f.ret_type;
  for (size_t j = 0; j < k; ++j) out.output_access.push_back(f.access(j));
  std::vector<uint8_t> used(ni, 0);
  for (const Node& n : d.nodes)
    if (n.kind == Node::Kind::Var) used[n.index] = 1;
  const std::string sig = f.signature(opts.function_name, used);

  std::string hdr;
  if (opts.header) {
    auto h = headerComment(in, opts, f, out, tr);
    if (!h) return h.status();
    hdr = std::move(*h);
  }
  const std::string struct_def = f.structDef();
  std::string fn = hdr + struct_def;
  fn += sig + " {\n" + r.body() + f.returnOf(results) + "}\n";
  out.function = fn;
  {
    // The I/O-only twin: the same signature returning the inputs the formula reads.
    std::vector<std::string> src, values;
    for (int i = 0; i < ni; ++i)
      if (used[i]) src.push_back(f.params[i]);
    if (src.empty()) src.push_back(detail::literal(0.0, ctx));
    for (size_t j = 0; j < k; ++j) values.push_back(src[j % src.size()]);
    out.io_baseline = struct_def + sig + " {\n" + f.returnOf(values) + "}\n";
  }

  std::string code;
  if (opts.includes) code += includeLines(lang, r.helpers().test(static_cast<int>(Helper::Vm)));
  if (opts.helpers && r.helpers().any())
    code += "// lgp protected-operator helpers (see lgp emit/README.md)\n" +
            detail::helperBlock(r.helpers(), ctx) + "\n";
  code += fn;
  out.code = code;
  return out;
}

EmitInput emitInputForTable(const Program& p, const Table& t) {
  EmitInput in;
  in.program = p;
  in.input_names = t.input_names;
  in.output_names = t.output_names;
  in.domain = tableDomain(t);
  in.table_desc = std::to_string(t.rows()) + " rows";
  return in;
}

Expected<EmitInput> emitInputFromFront(const nlohmann::json& front, size_t member) {
  if (!front.is_object() || !front.contains("members") || !front["members"].is_array())
    return Status::error("front: /members is missing or not an array");
  const auto& members = front["members"];
  if (member >= members.size())
    return Status::error("member: index " + std::to_string(member) + " out of range (front has " +
                         std::to_string(members.size()) + " members)");
  return emitInputFromFrontEntry(front, members[member], "/members/" + std::to_string(member));
}

Expected<EmitInput> emitInputFromFrontEntry(const nlohmann::json& front, const nlohmann::json& m,
                                            const std::string& mpath) {
  if (!front.is_object() || !front.contains("table") || !front["table"].is_object())
    return Status::error("front: /table is missing");
  const auto& table = front["table"];
  EmitInput in;
  auto names = [&](const char* key, std::vector<std::string>& dst) -> Status {
    if (!table.contains(key) || !table[key].is_array())
      return Status::error(std::string("front: /table/") + key + " is missing or not an array");
    for (const auto& v : table[key]) {
      if (!v.is_string())
        return Status::error(std::string("front: /table/") + key + " must hold strings");
      if (auto s = checkNoControlCharacters(v.get<std::string>(),
                                            "front: /table/" + std::string(key) + "/" +
                                                std::to_string(dst.size()) + ": the column name");
          !s)
        return s;
      dst.push_back(v.get<std::string>());
    }
    return Status::ok();
  };
  if (Status s = names("inputs", in.input_names); !s) return s;
  if (Status s = names("outputs", in.output_names); !s) return s;
  auto prog = frontEntryProgram(front, m);
  if (!prog) return Status::error("front: " + mpath + "/" + prog.error());
  in.program = *prog;
  if (table.contains("domain") && table["domain"].is_object()) {
    for (const auto& n : in.input_names) {
      Interval iv;
      const auto& dm = table["domain"];
      if (dm.contains(n) && dm[n].is_array() && dm[n].size() == 2 && dm[n][0].is_number() &&
          dm[n][1].is_number()) {
        iv.lo = dm[n][0].get<double>();
        iv.hi = dm[n][1].get<double>();
        iv.nan = false;
        if (!(iv.lo <= iv.hi)) return Status::error("front: /table/domain/" + n + " has lo > hi");
      }
      in.domain.push_back(iv);
    }
  }
  if (m.contains("outputs") && m["outputs"].is_array()) {
    in.output_metrics = nlohmann::json::array();
    for (size_t j = 0; j < m["outputs"].size(); ++j) {
      const auto& o = m["outputs"][j];
      TargetTransform t = TargetTransform::None;
      if (o.contains("transform")) {
        if (!o["transform"].is_string())
          return Status::error("front: " + mpath + "/outputs/" + std::to_string(j) +
                               "/transform must be a string");
        auto tt = targetTransformFromString(o["transform"].get<std::string>());
        if (!tt)
          return Status::error("front: " + mpath + "/outputs/" + std::to_string(j) +
                               "/transform: unknown transform '" +
                               o["transform"].get<std::string>() + "'");
        t = *tt;
      }
      in.transforms.push_back(t);
      in.output_metrics.push_back({{"float32", o.value("float32", nlohmann::json())},
                                   {"double", o.value("double", nlohmann::json())}});
    }
  }
  if (m.contains("cost_by_target")) in.cost_by_target = m["cost_by_target"];
  std::string desc;
  if (table.contains("meta") && table["meta"].is_object()) {
    for (const char* key : {"name", "definition", "generator", "path"})
      if (table["meta"].contains(key) && table["meta"][key].is_string()) {
        desc = table["meta"][key].get<std::string>();
        break;
      }
  }
  if (front.contains("config") && front["config"].is_object() && front["config"].contains("data") &&
      front["config"]["data"].is_object())
    for (const char* key : {"path", "scene"})
      if (const auto& v = front["config"]["data"]; v.contains(key) && v[key].is_string())
        if (auto s = checkNoControlCharacters(v[key].get<std::string>(),
                                              std::string("front: /config/data/") + key);
            !s)
          return s;
  if (desc.empty() && front.contains("config") && front["config"].is_object()) {
    const auto& c = front["config"];
    if (c.contains("data") && c["data"].is_object()) {
      for (const char* key : {"path", "scene"})
        if (c["data"].contains(key) && c["data"][key].is_string() &&
            !c["data"][key].get<std::string>().empty()) {
          desc = c["data"][key].get<std::string>();
          break;
        }
    }
  }
  if (table.contains("rows") && table["rows"].is_number_integer())
    desc += (desc.empty() ? "" : ", ") + std::to_string(table["rows"].get<long long>()) + " rows";
  in.table_desc = desc;
  return in;
}

Expected<std::string> emitFromFront(const nlohmann::json& front, size_t member, Language lang,
                                    const EmitOptions& opts) {
  auto in = emitInputFromFront(front, member);
  if (!in) return in.status();
  EmitOptions o = opts;
  if (o.source.empty()) o.source = "front member " + std::to_string(member);
  auto e = emitProgram(*in, lang, o);
  if (!e) return e.status();
  return e->code;
}

Expected<size_t> selectMember(const nlohmann::json& front, const MemberSelector& sel) {
  if (!front.is_object() || !front.contains("members") || !front["members"].is_array())
    return Status::error("front: /members is missing or not an array");
  const auto& members = front["members"];
  const int criteria = sel.index.has_value() + sel.max_error.has_value() + sel.max_cost.has_value();
  if (criteria > 1)
    return Status::error("member selection: give one of --member, --max-error, --max-cost");
  if (members.empty()) return Status::error("front: has no members");
  if (sel.index) {
    if (*sel.index >= members.size())
      return Status::error("--member: " + std::to_string(*sel.index) + " out of range (front has " +
                           std::to_string(members.size()) + " members)");
    return *sel.index;
  }
  std::vector<double> err(members.size()), cost(members.size());
  for (size_t i = 0; i < members.size(); ++i) {
    const auto& m = members[i];
    const std::string path = "front: /members/" + std::to_string(i);
    if (!m.contains("error") || !m["error"].is_number())
      return Status::error(path + "/error is missing or not a number");
    err[i] = m["error"].get<double>();
    if (sel.cost_target.empty()) {
      if (!m.contains("cost") || !m["cost"].is_number())
        return Status::error(path + "/cost is missing or not a number");
      cost[i] = m["cost"].get<double>();
    } else {
      if (!m.contains("cost_by_target") || !m["cost_by_target"].contains(sel.cost_target) ||
          !m["cost_by_target"][sel.cost_target].is_number())
        return Status::error(path + "/cost_by_target/" + sel.cost_target + " is missing");
      cost[i] = m["cost_by_target"][sel.cost_target].get<double>();
    }
  }
  std::optional<size_t> best;
  for (size_t i = 0; i < members.size(); ++i) {
    if (sel.max_error && !(err[i] <= *sel.max_error)) continue;
    if (sel.max_cost && !(cost[i] <= *sel.max_cost)) continue;
    if (!best) {
      best = i;
      continue;
    }
    const size_t b = *best;
    const bool better = sel.max_error
                            ? (cost[i] < cost[b] || (cost[i] == cost[b] && err[i] < err[b]))
                            : (err[i] < err[b] || (err[i] == err[b] && cost[i] < cost[b]));
    if (better) best = i;
  }
  if (!best) {
    if (sel.max_error) {
      double lo = *std::min_element(err.begin(), err.end());
      return Status::error("--max-error: no member has error <= " + fmtMetric(*sel.max_error) +
                           " (lowest is " + fmtMetric(lo) + ")");
    }
    double lo = *std::min_element(cost.begin(), cost.end());
    return Status::error(
        "--max-cost: no member has cost <= " + fmtMetric(sel.max_cost.value_or(0)) +
        " (cheapest is " + fmtMetric(lo) + ")");
  }
  return *best;
}

}  // namespace lgp::emit
