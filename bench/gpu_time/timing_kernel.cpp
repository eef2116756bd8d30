// The timing kernel: see timing_kernel.hpp.
#include "timing_kernel.hpp"

#include <cmath>
#include <cstdio>
#include <utility>

namespace lgp::bench {
namespace {

// A float literal both languages read as float32 ("1.0", "0.25", "1e-05" -> "1.0e-05").
std::string lit(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.9g", static_cast<double>(static_cast<float>(v)));
  std::string s = buf;
  if (s.find_first_of(".en") == std::string::npos) s += ".0";
  if (s.find('.') == std::string::npos && s.find('e') != std::string::npos)
    s.insert(s.find('e'), ".0");
  return s;
}

// The step of input j's walk: fractional parts of square roots of primes, irrational and
// pairwise independent, so the inputs do not move in lockstep.
double stepOf(size_t j) {
  static const int primes[] = {2, 3, 5, 7, 11, 13, 17, 19, 23, 29, 31, 37};
  const double r = std::sqrt(static_cast<double>(primes[j % 12]));
  return r - std::floor(r);
}

// The walk's interval for input j: the domain's where finite, else [0, 1].
std::pair<double, double> rangeOf(const std::vector<Interval>& domain, size_t j) {
  if (j < domain.size() && domain[j].finite() && domain[j].hi >= domain[j].lo)
    return {domain[j].lo, domain[j].hi};
  return {0.0, 1.0};
}

constexpr double kStartScale = 1.0 / 4096.0;

}  // namespace

float walkInput(const std::vector<Interval>& domain, size_t j, uint32_t i, uint32_t k) {
  const auto [lo, hi] = rangeOf(domain, j);
  const float s = static_cast<float>(i & 4095u) * static_cast<float>(kStartScale);
  const float u = s * static_cast<float>(1.0 + static_cast<double>(j)) +
                  static_cast<float>(k) * static_cast<float>(stepOf(j));
  return static_cast<float>(lo) + static_cast<float>(hi - lo) * (u - std::floor(u));
}

Expected<std::string> timingKernel(const emit::Emitted& e, emit::Language lang,
                                   const std::vector<Interval>& domain, emit::KernelBody body) {
  if (!emit::languageInfo(lang).shader)
    return Status::error("timing kernel: " + std::string(emit::languageInfo(lang).title) +
                         " does not run on a GPU");
  if (e.output_access.empty() || e.function_name.empty())
    return Status::error("timing kernel: the emitted function has no outputs");
  const bool glsl = lang == emit::Language::Glsl;
  const std::string frac = glsl ? "fract" : "frac";
  std::string s;
  if (glsl) {
    s += "#version 450\n"
         "layout(local_size_x = " +
         std::to_string(kTimingWorkgroup) +
         ") in;\n"
         "layout(std430, set = 0, binding = 0) writeonly buffer LgpOut { float lgp_out[]; };\n"
         "layout(push_constant) uniform LgpPc { uint lgp_iters; };\n";
  } else {
    s += "[[vk::binding(0, 0)]] RWStructuredBuffer<float> lgp_out;\n"
         "struct LgpPc { uint iters; };\n"
         "[[vk::push_constant]] ConstantBuffer<LgpPc> lgp_pc;\n";
  }
  s += "\n" + (body == emit::KernelBody::Formula ? e.code : e.io_baseline) + "\n";
  if (glsl) {
    s += "void main() {\n  uint lgp_i = gl_GlobalInvocationID.x;\n  uint lgp_n = lgp_iters;\n";
  } else {
    s += "[numthreads(" + std::to_string(kTimingWorkgroup) +
         ", 1, 1)]\n"
         "void main(uint3 lgp_id : SV_DispatchThreadID) {\n"
         "  uint lgp_i = lgp_id.x;\n  uint lgp_n = lgp_pc.iters;\n";
  }
  // Per-invocation starts from the low 12 bits of the index (exact in float32).
  s += "  float lgp_s = float(lgp_i & 4095u) * " + lit(kStartScale) + ";\n";
  s += "  float lgp_acc = 0.0;\n";
  s += "  for (uint lgp_k = 0u; lgp_k < lgp_n; ++lgp_k) {\n";
  s += "    float lgp_t = float(lgp_k);\n";
  const size_t ni = static_cast<size_t>(e.num_inputs);
  std::string args;
  for (size_t j = 0; j < ni; ++j) {
    const auto [lo, hi] = rangeOf(domain, j);
    const std::string x = "lgp_x" + std::to_string(j);
    s += "    float " + x + " = " + lit(lo) + " + " + lit(hi - lo) + " * " + frac + "(lgp_s * " +
         lit(1.0 + static_cast<double>(j)) + " + lgp_t * " + lit(stepOf(j)) + ");\n";
    args += (j ? ", " : "") + x;
  }
  s += "    " + e.return_type + " lgp_v = " + e.function_name + "(" + args + ");\n";
  for (const std::string& a : e.output_access) s += "    lgp_acc += lgp_v" + a + ";\n";
  s += "  }\n  lgp_out[lgp_i] = lgp_acc;\n}\n";
  return s;
}

}  // namespace lgp::bench
