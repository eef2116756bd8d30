// The compute-shader wrapper of compute_shader.hpp.
#include "lgp/emit/compute_shader.hpp"

namespace lgp::emit {

Expected<std::string> computeShader(const Emitted& e, Language lang, Precision precision,
                                    KernelBody body) {
  if (lang == Language::Cpp)
    return Status::error("compute shader: only HLSL and GLSL run on a GPU");
  if (precision == Precision::Double) return Status::error("compute shader: no double precision");
  if (e.output_access.empty() || e.function_name.empty())
    return Status::error("compute shader: the emitted function has no outputs");
  const bool glsl = lang == Language::Glsl;
  const bool half = precision == Precision::Half;
  const std::string T = glsl ? (half ? "float16_t" : "float") : (half ? "half" : "float");
  const size_t ni = static_cast<size_t>(e.num_inputs), k = e.output_access.size();
  std::string s;
  if (glsl) {
    s += "#version 450\n";
    if (half) s += "#extension GL_EXT_shader_explicit_arithmetic_types_float16 : require\n";
    s += "layout(local_size_x = 64) in;\n"
         "layout(std430, set = 0, binding = 0) readonly buffer LgpIn { float lgp_in[]; };\n"
         "layout(std430, set = 0, binding = 1) writeonly buffer LgpOut { float lgp_out[]; };\n"
         "layout(push_constant) uniform LgpRows { uint lgp_rows; };\n";
  } else {
    s += "[[vk::binding(0, 0)]] StructuredBuffer<float> lgp_in;\n"
         "[[vk::binding(1, 0)]] RWStructuredBuffer<float> lgp_out;\n"
         "struct LgpRows { uint rows; };\n"
         "[[vk::push_constant]] ConstantBuffer<LgpRows> lgp_pc;\n";
  }
  s += "\n" + (body == KernelBody::Formula ? e.code : e.io_baseline) + "\n";
  const std::string rows = glsl ? "lgp_rows" : "lgp_pc.rows";
  if (glsl) {
    s += "void main() {\n  uint lgp_i = gl_GlobalInvocationID.x;\n";
  } else {
    s += "[numthreads(64, 1, 1)]\nvoid main(uint3 lgp_id : SV_DispatchThreadID) {\n"
         "  uint lgp_i = lgp_id.x;\n";
  }
  s += "  if (lgp_i >= " + rows + ") return;\n";
  s += "  " + e.return_type + " lgp_v = " + e.function_name + "(";
  for (size_t i = 0; i < ni; ++i) {
    const std::string load =
        "lgp_in[lgp_i * " + std::to_string(ni) + "u + " + std::to_string(i) + "u]";
    s += (i ? ", " : "") + (half ? T + "(" + load + ")" : load);
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
