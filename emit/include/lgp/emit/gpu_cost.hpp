// Measured GPU cost: emitted code compiled to real AMD ISA by Mesa's ACO compiler, through the
// RADV Vulkan driver's null device (RADV_FORCE_FAMILY), which compiles for a chosen GPU family
// without a GPU. No GPU is used or needed, and a real one is never touched: the compile runs in
// a child process (lgp-gpu-worker) whose environment selects RADV's manifest and a family, and
// which refuses any device but RADV's "Null hardware".
//
// What is measured. The emitted function is wrapped in a compute shader that loads its inputs
// from a buffer and stores its outputs (compute_shader.hpp). The same shader around the
// function's I/O-only twin (Emitted::io_baseline: same signature, returns the inputs it reads)
// is compiled too, and the difference of ACO's statistics is the formula's own cost: what it
// adds to any shader that already has its inputs in registers. ACO reports, per shader:
//   Instructions        machine instructions (s_ and v_; the cost objective's unit)
//   Latency             cycles of one wave through the shader, by ACO's scheduler model
//   Inverse Throughput  cycles per wave when waves overlap, by the same model
//   VGPRs, SGPRs        registers allocated (occupancy)
// By default the code is emitted as `lgp emit --lang hlsl --fast` writes it: guards that
// interval analysis proves unreachable on the table's domain are dropped (the code is then
// bit-identical to the protected form on the domain), the others stay and are counted.
//
// Results are cached in the process, keyed by the hash of the shader text, which is a function
// of the canonical (simplified) program, the names and the options.
//
// Requirements: the build found Vulkan and glslang (CMake option LGP_WITH_GPU), and Mesa's
// RADV driver is installed (Debian: mesa-vulkan-drivers). Where anything is missing every
// function returns an error that says what, and callers go on without measured cost.
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "lgp/config/config.hpp"
#include "lgp/core/status.hpp"
#include "lgp/emit/emit.hpp"
#include "lgp/eval/cost_model.hpp"
#include "lgp/search/search.hpp"

namespace lgp::emit {

struct IsaStats {
  double instructions = 0;
  double latency = 0;
  double inverse_throughput = 0;
  double vgprs = 0;
  double sgprs = 0;
  double code_bytes = 0;
};
IsaStats operator-(const IsaStats& a, const IsaStats& b);
// {"instructions", "latency", "inverse_throughput", "vgprs"} (the fields fronts record).
nlohmann::json toJson(const IsaStats& s);

// Whether measurement works here: the worker is built and found, RADV's manifest is installed
// and its null device answers for `f`. `detail`: the device and driver, or why not.
struct GpuBackendStatus {
  bool available = false;
  std::string detail;
};
GpuBackendStatus isaBackendStatus(GpuFamily f = GpuFamily::Rdna2);

// Absolute statistics of one compute shader with the layout of compute_shader.hpp.
Expected<IsaStats> shaderIsaStats(GpuFamily f, Language lang, const std::string& shader);
// Marginal statistics of emitted code (HLSL or GLSL, float or half): its kernel minus the
// kernel around its I/O-only twin.
Expected<IsaStats> measureEmitted(const Emitted& e, Language lang, Precision precision,
                                  GpuFamily f);

// emitProgram, plus a header line that states what this very code costs compiled to AMD ISA,
// per GPU family (ACO instructions / latency / VGPRs over its I/O-only twin), or why it could
// not be measured. C++, or no header: emitProgram alone. What `lgp emit` prints and the Python
// module's Member.emit returns, byte for byte.
Expected<Emitted> emitMeasured(const EmitInput& in, Language lang, EmitOptions opts);

struct MeasureOptions {
  std::vector<GpuFamily> families = allGpuFamilies();
  Language lang = Language::Hlsl;
  bool fast = true;  // emit as --fast does (see above)
};
// "hlsl --fast", the emission the figures are for.
std::string describe(const MeasureOptions& o);

// The measured cost of one program: {"rdna2": {stats}, "rdna3": {...}, ...}.
Expected<nlohmann::json> measureProgram(const EmitInput& in, const MeasureOptions& o);

// The archive's measurement for objectives.measured_cost.in_search (Search::setCostMeasure):
// a final program of a run on `t` (the run's transforms appended, as emitted), measured on
// `family`, in instructions. Thread-compatible (the cache and worker pool are shared).
std::function<std::optional<double>(const Program&)> archiveCostMeasure(const RunConfig& cfg,
                                                                        const Table& t,
                                                                        GpuFamily family);
// Sets it on `s` (with the calibrated model of the family and its worst held-out error as the
// pre-filter), or says why it cannot.
Status enableMeasuredCostInSearch(Search& s);

// Adds "cost_measured" (measureProgram) to every member and every scored reference of a front
// (lgp-front/1), and a top-level "cost_measured_info": {"emitted", "families", "device",
// "driver"}. Where measurement is unavailable nothing is added but
// "cost_measured_info": {"unavailable": why}; a member that fails alone gets
// "cost_measured": {"error": why}. Never fails the front.
void addMeasuredCost(nlohmann::json& front, const MeasureOptions& o = {});

}  // namespace lgp::emit
