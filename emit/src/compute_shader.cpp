// The compute-shader wrapper of compute_shader.hpp.
#include "lgp/emit/compute_shader.hpp"

namespace lgp::emit {

namespace {
// What a language's kernel is made of around the emitted function: its bindings, the row
// count's name, the entry point's opening and the scalar type of `precision`.
struct KernelSyntax {
  std::string bindings, rows, main_open, type;
};

Expected<KernelSyntax> kernelSyntax(Language lang, bool half) {
  switch (lang) {
    case Language::Glsl:
      return KernelSyntax{
          std::string("#version 450\n") +
              (half ? "#extension GL_EXT_shader_explicit_arithmetic_types_float16 : require\n"
                    : "") +
              "layout(local_size_x = 64) in;\n"
              "layout(std430, set = 0, binding = 0) readonly buffer LgpIn { float lgp_in[]; };\n"
              "layout(std430, set = 0, binding = 1) writeonly buffer LgpOut { float lgp_out[]; "
              "};\n"
              "layout(push_constant) uniform LgpRows { uint lgp_rows; };\n",
          "lgp_rows", "void main() {\n  uint lgp_i = gl_GlobalInvocationID.x;\n",
          half ? "float16_t" : "float"};
    case Language::Hlsl:
      return KernelSyntax{
          "[[vk::binding(0, 0)]] StructuredBuffer<float> lgp_in;\n"
          "[[vk::binding(1, 0)]] RWStructuredBuffer<float> lgp_out;\n"
          "struct LgpRows { uint rows; };\n"
          "[[vk::push_constant]] ConstantBuffer<LgpRows> lgp_pc;\n",
          "lgp_pc.rows",
          "[numthreads(64, 1, 1)]\nvoid main(uint3 lgp_id : SV_DispatchThreadID) {\n"
          "  uint lgp_i = lgp_id.x;\n",
          half ? "half" : "float"};
    case Language::Cpp:
      break;
  }
  return Status::error("compute shader: " + std::string(languageInfo(lang).title) +
                       " does not run on a GPU");
}
}  // namespace

Expected<std::string> computeShader(const Emitted& e, Language lang, Precision precision,
                                    KernelBody body) {
  if (precision == Precision::Double) return Status::error("compute shader: no double precision");
  if (e.output_access.empty() || e.function_name.empty())
    return Status::error("compute shader: the emitted function has no outputs");
  const bool half = precision == Precision::Half;
  auto syn = kernelSyntax(lang, half);
  if (!syn) return syn.status();
  const size_t ni = static_cast<size_t>(e.num_inputs), k = e.output_access.size();
  std::string s = syn->bindings;
  s += "\n" + (body == KernelBody::Formula ? e.code : e.io_baseline) + "\n";
  s += syn->main_open;
  s += "  if (lgp_i >= " + syn->rows + ") return;\n";
  s += "  " + e.return_type + " lgp_v = " + e.function_name + "(";
  for (size_t i = 0; i < ni; ++i) {
    const std::string load =
        "lgp_in[lgp_i * " + std::to_string(ni) + "u + " + std::to_string(i) + "u]";
    s += (i ? ", " : "") + (half ? syn->type + "(" + load + ")" : load);
  }
  s += ");\n";
  for (size_t j = 0; j < k; ++j) {
    const std::string v = "lgp_v" + e.output_access[j];
    s += "  lgp_out[lgp_i * " + std::to_string(k) + "u + " + std::to_string(j) +
         "u] = " + (half ? "float(" + v + ")" : v) + ";\n";
  }
  s += "}\n";
  return s;
}

}  // namespace lgp::emit
