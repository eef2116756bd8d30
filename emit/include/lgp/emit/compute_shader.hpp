// An emitted HLSL or GLSL function wrapped in a Vulkan compute shader that evaluates it on every
// row of a table: what the GPU cost is measured on (gpu_cost.hpp) and what runs in a driver
// (vulkan_run.hpp).
//
// Interface of the shader (the same for both languages, so one host program drives either):
//   set 0, binding 0  read-only storage buffer of float32, row-major, num_inputs per row
//   set 0, binding 1  storage buffer of float32, row-major, one value per output per row
//   push constant     uint: the number of rows
//   64 invocations per workgroup, one row each; entry point `main`.
// Inputs are converted to the function's precision on load (half: rounded to binary16, as the
// half emulation of lgp/core/half.hpp does) and results back to float32 on store.
// GLSL is `#version 450` (plus GL_EXT_shader_explicit_arithmetic_types_float16 for half); HLSL
// is written for SPIR-V compilers (glslang, DXC): `[[vk::binding]]`, `[[vk::push_constant]]`.
#pragma once

#include <string>

#include "lgp/emit/emit.hpp"

namespace lgp::emit {

// `e` must have been emitted for `lang` (HLSL or GLSL) in `precision`; `body` selects what the
// kernel calls: the formula (e.code, with its helpers) or its I/O-only twin (e.io_baseline).
enum class KernelBody { Formula, IoBaseline };
Expected<std::string> computeShader(const Emitted& e, Language lang, Precision precision,
                                    KernelBody body = KernelBody::Formula);

}  // namespace lgp::emit
