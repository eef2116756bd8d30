// How each export language writes what the emitters produce: one row per language
// (syntax.cpp), so that a new language is its `Language` value, its `kLanguages` row, its row
// here and its spelling column of the op table (private to emit/).
#pragma once

#include <array>
#include <string>
#include <string_view>

#include "lgp/core/expr.hpp"
#include "lgp/core/ops.hpp"
#include "lgp/emit/emit.hpp"

namespace lgp::emit::detail {

// Per precision, in `Precision`'s order (float, double, half).
using PerPrecision = std::array<std::string_view, 3>;

struct LanguageSyntax {
  Language lang;
  std::string_view OpInfo::*spelling;  // the op table's column of raw spellings

  // Types and literals.
  PerPrecision scalar_type;           // "float", "half", "float16_t"
  PerPrecision vector_prefix;         // + the component count; "" = no vector types (a struct)
  PerPrecision literal_suffix;        // "f" for C++ float, "h" / "hf" for half
  std::string_view half_infinity;     // an infinite binary16 value: no language has a literal
  std::string_view half_requirement;  // for the header ("" = nothing)

  // The function around the formula.
  std::string_view includes;     // #include lines ("" = none)
  std::string_view vm_includes;  // and those of the exact-math helpers
  std::string_view function_qualifier;
  std::string_view local_qualifier;   // of a local
  std::string_view unused_parameter;  // the mark of a parameter the formula does not read
  std::string_view struct_return;     // return of a struct: $S its type, $L the values

  // Operators whose protection is proven unreachable, and primitives; $0, $1: 0, 1 in the
  // context's precision.
  std::string_view raw_rcp;
  std::string_view raw_clamp01;
  bool native_saturate;               // the language's own saturate has the interpreter's semantics
  bool raw_min_max;                   // its min and max order NaN like the interpreter
  std::string_view primitive_prefix;  // of a math primitive: "std::"
  std::string_view abs;               // its abs
  std::string_view rsqrt;             // its rsqrt ("" = none: 1 / sqrt)

  // The protected-operator helpers where the language differs ($-placeholders of helpers.cpp).
  std::string_view guard_helper;
  std::string_view rsqrt_helper;
  std::string_view helper_qualifier;

  // A compute kernel around the function (shader languages: compute_shader.hpp).
  std::string_view kernel_prologue;   // before the bindings
  std::string_view kernel_half_line;  // where the kernel is in half precision
  std::string_view kernel_bindings;
  std::string_view kernel_rows;       // the row count's name
  std::string_view kernel_main_open;  // the entry point's opening
  bool half_needs_float16;            // half is binary16 arithmetic (a device needs shaderFloat16)
};

const LanguageSyntax& syntaxOf(Language l);

}  // namespace lgp::emit::detail
