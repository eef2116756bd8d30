// GLSL or HLSL compute shaders to SPIR-V with glslang, as every lgp program that hands a shader
// to a Vulkan driver compiles it: the lgp-gpu-worker and the GPU timing benchmark
// (bench/gpu_time). Callers bracket their use with glslang::InitializeProcess/FinalizeProcess.
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

namespace lgp::spirv {

struct CompileError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// `lang` "glsl" (#version 450) or "hlsl" (glslang's HLSL front end, as DXC's SPIR-V output
// would be); entry point `main`; SPIR-V 1.3 for Vulkan 1.1, glslang's optimiser off (the driver
// optimises: what it gets is what users ship). Throws CompileError with glslang's log.
std::vector<uint32_t> compileCompute(const std::string& lang, const std::string& source);

}  // namespace lgp::spirv
