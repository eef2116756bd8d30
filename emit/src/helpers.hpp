// Per-language text of the protected-operator helpers and of literals (private to emit/).
#pragma once

#include <bitset>
#include <string>

#include "lgp/emit/dag.hpp"
#include "lgp/emit/emit.hpp"

namespace lgp::emit::detail {

// In dependency order: a helper only calls helpers listed before it.
enum class Helper : int {
  Vm,  // C++ exact math: the interpreter's exp2/log2/sin/cos
  Guard,
  Div,
  Rcp,
  Sqrt,
  Rsqrt,
  Log2,
  Exp2,
  Log,
  Exp,
  Pow,
  Saturate,
  Min,
  Max,
  Count
};
using HelperSet = std::bitset<static_cast<int>(Helper::Count)>;

struct Ctx {
  Language lang = Language::Cpp;
  Precision prec = Precision::Float;
  bool exact_math = false;  // C++ float only
};

// The operator's raw spelling in the language (the op table's column).
std::string_view opSpelling(const OpInfo& info, Language l);
// C++ float with the interpreter's own exp2/log2/sin/cos (EmitOptions::exact_math).
bool exactMath(const Ctx& c);
std::string scalarType(const Ctx& c);
// A literal of the context's type: shortest round-trip digits of the value in that
// precision, with a decimal point and the language's suffix (f for C++ float, h for half).
std::string literal(double v, const Ctx& c);
// Names of the math primitives: "std::exp2", "lgp_vm_exp2" or "exp2", ...
std::string primitive(std::string_view fn, const Ctx& c);
std::string helperName(Helper h);
// Replaces every occurrence of `from` in `s`.
std::string replaceAll(std::string s, std::string_view from, const std::string& to);
// Adds the helpers `h` depends on.
void addWithDeps(HelperSet& set, Helper h, const Ctx& c);
// The definitions of every helper in `set`, in dependency order, each behind an #ifndef.
std::string helperBlock(const HelperSet& set, const Ctx& c);

}  // namespace lgp::emit::detail
