// The timing kernel of bench/gpu_time: an emitted HLSL or GLSL function evaluated many times
// per invocation on inputs the kernel makes itself, so that the GPU's arithmetic, not memory,
// is what a dispatch takes. The same kernel around the function's I/O-only twin
// (Emitted::io_baseline) is the baseline: the difference of the two is the formula's own time,
// as the difference of the two compiled kernels is its measured instruction count
// (emit/gpu_cost.hpp).
//
// Interface (both languages): set 0 binding 0, a float32 storage buffer with one value per
// invocation (the sum of every output over the iterations, so nothing is dead code); a 4-byte
// push constant, the iteration count; 128 invocations per workgroup; entry point `main`.
// Iteration k of invocation i evaluates input j at lo_j + (hi_j - lo_j) * frac(s_ij + k a_j):
// an additive-recurrence walk over the domain (a_j irrational, s_ij a per-invocation start), so
// every evaluation sees different inputs inside the table's domain.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "lgp/core/status.hpp"
#include "lgp/emit/compute_shader.hpp"
#include "lgp/emit/emit.hpp"

namespace lgp::bench {

inline constexpr unsigned kTimingWorkgroup = 128;

// Input j of invocation i at iteration k, in float32 as the kernel computes it (a GPU may fuse
// the multiply-adds, so the kernel's value can differ in the last bits).
float walkInput(const std::vector<Interval>& domain, size_t j, uint32_t i, uint32_t k);

// `e` emitted in float for `lang` (HLSL or GLSL); `domain` per input (empty or unbounded
// intervals walk [0, 1]).
Expected<std::string> timingKernel(const emit::Emitted& e, emit::Language lang,
                                   const std::vector<Interval>& domain, emit::KernelBody body);

}  // namespace lgp::bench
