// The export languages' syntax rows (syntax.hpp).
#include "syntax.hpp"

namespace lgp::emit::detail {

namespace {

constexpr std::string_view kShaderGuard =
    "$T lgp_guard($T b) { return abs(b) < $G ? (b < $0 ? -$G : $G) : b; }";
constexpr std::string_view kShaderRsqrt = "$T lgp_rsqrt($T a) { return $RSQRT(a > $M ? a : $M); }";

// Whether kLanguages lists `l` (a row here without one there fails to compile).
constexpr bool listed(Language l) {
  for (const auto& i : kLanguages)
    if (i.lang == l) return true;
  return false;
}

constexpr LanguageSyntax kHlsl = {
    .lang = Language::Hlsl,
    .spelling = &OpInfo::hlsl,
    .scalar_type = {"float", "double", "half"},
    .vector_prefix = {"float", "double", "half"},
    .literal_suffix = {"", "", "h"},
    .half_infinity = "((half)asfloat(0x7F800000u))",
    .half_requirement = "",
    .includes = "",
    .vm_includes = "",
    .function_qualifier = "",
    .local_qualifier = "",
    .unused_parameter = "",
    .struct_return = "  $S lgp_r = {$L};\n  return lgp_r;\n",
    .raw_rcp = "rcp({0})",
    .raw_clamp01 = "saturate({0})",
    .native_saturate = true,  // D3D: saturate(NaN) = 0
    .raw_min_max = true,
    .primitive_prefix = "",
    .abs = "abs",
    .rsqrt = "rsqrt",
    .guard_helper = kShaderGuard,
    .rsqrt_helper = kShaderRsqrt,
    .helper_qualifier = "",
    .kernel_prologue = "",
    .kernel_half_line = "",
    .kernel_bindings =
        "[[vk::binding(0, 0)]] StructuredBuffer<float> lgp_in;\n"
        "[[vk::binding(1, 0)]] RWStructuredBuffer<float> lgp_out;\n"
        "struct LgpRows { uint rows; };\n"
        "[[vk::push_constant]] ConstantBuffer<LgpRows> lgp_pc;\n",
    .kernel_rows = "lgp_pc.rows",
    .kernel_main_open =
        "[numthreads(64, 1, 1)]\n"
        "void main(uint3 lgp_id : SV_DispatchThreadID) {\n"
        "  uint lgp_i = lgp_id.x;\n",
    .half_needs_float16 = false,  // half is relaxed precision: it runs everywhere
};
static_assert(kHlsl.lang == Language::Hlsl && listed(Language::Hlsl));

constexpr LanguageSyntax kGlsl = {
    .lang = Language::Glsl,
    .spelling = &OpInfo::glsl,
    .scalar_type = {"float", "double", "float16_t"},
    .vector_prefix = {"vec", "vec", "f16vec"},
    .literal_suffix = {"", "", "hf"},
    .half_infinity = "float16_t(uintBitsToFloat(0x7F800000u))",
    .half_requirement =
        "Needs #extension GL_EXT_shader_explicit_arithmetic_types_float16 : require",
    .includes = "",
    .vm_includes = "",
    .function_qualifier = "",
    .local_qualifier = "",
    .unused_parameter = "",
    .struct_return = "  return $S($L);\n",
    .raw_rcp = "($1 / {0})",
    .raw_clamp01 = "clamp({0}, $0, $1)",
    .native_saturate = false,
    .raw_min_max = true,
    .primitive_prefix = "",
    .abs = "abs",
    .rsqrt = "inversesqrt",
    .guard_helper = kShaderGuard,
    .rsqrt_helper = kShaderRsqrt,
    .helper_qualifier = "",
    .kernel_prologue = "#version 450\n",
    .kernel_half_line = "#extension GL_EXT_shader_explicit_arithmetic_types_float16 : require\n",
    .kernel_bindings =
        "layout(local_size_x = 64) in;\n"
        "layout(std430, set = 0, binding = 0) readonly buffer LgpIn { float lgp_in[]; };\n"
        "layout(std430, set = 0, binding = 1) writeonly buffer LgpOut { float lgp_out[]; };\n"
        "layout(push_constant) uniform LgpRows { uint lgp_rows; };\n",
    .kernel_rows = "lgp_rows",
    .kernel_main_open = "void main() {\n  uint lgp_i = gl_GlobalInvocationID.x;\n",
    .half_needs_float16 = true,
};
static_assert(kGlsl.lang == Language::Glsl && listed(Language::Glsl));

constexpr LanguageSyntax kCpp = {
    .lang = Language::Cpp,
    .spelling = &OpInfo::cpp,
    .scalar_type = {"float", "double", "half"},
    .vector_prefix = {"", "", ""},
    .literal_suffix = {"f", "", ""},
    .half_infinity = "std::numeric_limits<float>::infinity()",  // no half (validate)
    .half_requirement = "",
    .includes = "#include <algorithm>\n#include <cmath>\n",
    .vm_includes = "#include <cstdint>\n#include <cstring>\n",
    .function_qualifier = "inline ",  // several translation units may include the code
    .local_qualifier = "const ",
    .unused_parameter = "[[maybe_unused]] ",
    .struct_return = "  return $S{$L};\n",
    .raw_rcp = "($1 / {0})",
    .raw_clamp01 = "std::clamp({0}, $0, $1)",
    .native_saturate = false,
    .raw_min_max = false,  // std::min orders NaN unlike the interpreter
    .primitive_prefix = "std::",
    .abs = "std::fabs",
    .rsqrt = "",
    .guard_helper = "$T lgp_guard($T b) { return std::fabs(b) < $G ? std::copysign($G, b) : b; }",
    .rsqrt_helper = "$T lgp_rsqrt($T a) { return $1 / $SQRT(a > $M ? a : $M); }",
    .helper_qualifier = "inline ",
    .kernel_prologue = "",
    .kernel_half_line = "",
    .kernel_bindings = "",
    .kernel_rows = "",
    .kernel_main_open = "",
    .half_needs_float16 = false,
};
static_assert(kCpp.lang == Language::Cpp && listed(Language::Cpp));

}  // namespace

const LanguageSyntax& syntaxOf(Language l) {
  switch (l) {
    case Language::Hlsl:
      return kHlsl;
    case Language::Glsl:
      return kGlsl;
    case Language::Cpp:
      return kCpp;
  }
  return kHlsl;
}

}  // namespace lgp::emit::detail
