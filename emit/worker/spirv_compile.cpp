// glslang front end to SPIR-V: see spirv_compile.hpp.
#include "spirv_compile.hpp"

#include <glslang/Public/ResourceLimits.h>
#include <glslang/Public/ShaderLang.h>
#include <glslang/SPIRV/GlslangToSpv.h>

namespace lgp::spirv {

std::vector<uint32_t> compileCompute(const std::string& lang, const std::string& source) {
  const bool hlsl = lang == "hlsl";
  if (!hlsl && lang != "glsl")
    throw CompileError("lang: expected glsl or hlsl, got '" + lang + "'");
  glslang::TShader shader(EShLangCompute);
  const char* text = source.c_str();
  shader.setStrings(&text, 1);
  shader.setEnvInput(hlsl ? glslang::EShSourceHlsl : glslang::EShSourceGlsl, EShLangCompute,
                     glslang::EShClientVulkan, 100);
  shader.setEnvClient(glslang::EShClientVulkan, glslang::EShTargetVulkan_1_1);
  shader.setEnvTarget(glslang::EShTargetSpv, glslang::EShTargetSpv_1_3);
  shader.setEntryPoint("main");
  shader.setSourceEntryPoint("main");
  auto msgs = static_cast<EShMessages>(EShMsgSpvRules | EShMsgVulkanRules |
                                       (hlsl ? EShMsgReadHlsl : EShMsgDefault));
  if (!shader.parse(GetDefaultResources(), hlsl ? 500 : 450, false, msgs))
    throw CompileError(std::string("shader compile: ") + shader.getInfoLog());
  glslang::TProgram program;
  program.addShader(&shader);
  if (!program.link(msgs)) throw CompileError(std::string("shader link: ") + program.getInfoLog());
  std::vector<uint32_t> spirv;
  glslang::SpvOptions opt;
  opt.disableOptimizer = true;
  glslang::GlslangToSpv(*program.getIntermediate(EShLangCompute), spirv, &opt);
  return spirv;
}

}  // namespace lgp::spirv
