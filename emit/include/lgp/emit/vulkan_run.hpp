// Emitted shaders executed by a real Vulkan driver: Mesa's lavapipe, a conformant Vulkan
// implementation that runs on the CPU (Debian: mesa-vulkan-drivers). The emitted GLSL or HLSL
// is wrapped in the compute shader of compute_shader.hpp, compiled to SPIR-V by glslang (HLSL
// through its HLSL front end, as DXC's SPIR-V output would be), and dispatched over every row
// of a table; the results are read back and compared, row by row, with what lgp computes.
// The driver runs in the lgp-gpu-worker child process (gpu_process.hpp), which refuses any
// device but a CPU one.
//
// Variants and what they are compared with:
//   GLSL float, HLSL float   the float32 interpreter (the search's own numbers)
//   GLSL half                float16_t arithmetic (GL_EXT_shader_explicit_arithmetic_types,
//                            where the device has shaderFloat16)
//   HLSL half                glslang marks `half` RelaxedPrecision (it has no float16 overloads
//                            of the intrinsics), and lavapipe lowers relaxed precision to 16-bit
//                            arithmetic
//   both halves are compared with lgp's binary16 emulation of the same code (lgp/core/half.hpp)
// GPU math is not the interpreter's: exp2/log2/rsqrt/rcp are approximations within the
// Vulkan precision rules (a few ulp), and a multiply feeding an add may be fused. Agreement is
// therefore reported in ulp, both pointwise (of the reference value) and scaled (of the largest
// |value| of the output over the table, which stays meaningful where a formula cancels to
// nearly 0).
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "lgp/core/table.hpp"
#include "lgp/emit/emit.hpp"

namespace lgp::emit {

struct VulkanStatus {
  bool available = false;
  std::string detail;    // the device and driver, or why not
  bool float16 = false;  // shaderFloat16
};
VulkanStatus vulkanRunStatus();

// Runs the kernel around `e` (emitted for `lang` in `precision`) over every row of t's inputs:
// the results as [output][row].
Expected<std::vector<std::vector<float>>> runEmitted(const Emitted& e, Language lang,
                                                     Precision precision, const Table& t);

struct OutputAgreement {
  std::string name;
  double max_abs_diff = 0;    // |driver - reference| over the rows
  double max_ulp = 0;         // the same in ulps of each reference value (its precision)
  double max_scaled_ulp = 0;  // in ulps of the output's largest |reference| over the table
  size_t nonfinite = 0;       // rows where exactly one side is not finite
  OutputMetrics driver;       // the driver's results against the table's ground truth
  OutputMetrics reference;    // the reference's, for comparison
};

// Per output: the driver's values ([output][row]) against reference values of precision
// `ref_precision` (the fields above), and both against t's ground truth.
std::vector<OutputAgreement> compareValues(const std::vector<std::vector<float>>& driver,
                                           const std::vector<std::vector<double>>& reference,
                                           Precision ref_precision, const Table& t,
                                           const std::vector<std::string>& names);

struct VulkanCheck {
  Language lang = Language::Glsl;
  Precision precision = Precision::Float;
  std::string reference;  // "float32 interpreter" or "binary16 emulation"
  bool skipped = false;   // e.g. half on a device without shaderFloat16
  std::string why;
  std::vector<OutputAgreement> outputs;
  double worstScaledUlp() const;
};
nlohmann::json toJson(const VulkanCheck& c);

struct VerifyOptions {
  std::vector<Language> langs = {Language::Glsl, Language::Hlsl};
  std::vector<Precision> precisions = {Precision::Float, Precision::Half};
  // The code is emitted as with these EmitOptions (`lgp emit --fast`, `--no-pow-rewrites`,
  // `--no-domain-rewrites`).
  bool fast = false;
  bool pow_rewrites = true;
  bool domain_rewrites = true;
};
// Every language x precision of `o`, on every row of `t`. The reference is the member as
// scored, whatever domain `in` claims: the float32 interpreter's values of the program (in
// half, the binary16 emulation of its DAG) without rewrites that hold on a domain only, so
// that code emitted for the front's domain disagrees on rows outside it, as a shader would.
Expected<std::vector<VulkanCheck>> verifyOnVulkan(const EmitInput& in, const Table& t,
                                                  const VerifyOptions& o = {});

// The ulp of `v` in float32 (precision Float) or binary16 (Half): the spacing of that format's
// numbers at |v| (subnormal spacing below the smallest normal).
double ulpOf(double v, Precision p);

}  // namespace lgp::emit
