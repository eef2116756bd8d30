// The cost objective: what a formula costs on a GPU (or a CPU), predicted from the program
// without compiling it. docs/cost-models.md derives every figure.
//
// A program is costed as the shader would compute it: the simplified expression DAG that the
// front prints and the emitters render (core/formula.hpp: effective opcodes, duplicates merged,
// constants folded, rewrites proven on the table's domain), each node once. Its cost is
//   sum over operator nodes   op[n]
// + sum over protected nodes  guard[n]   unless interval analysis on `domain` proves the
//                                        protected branch unreachable (emitted raw by --fast)
// + sum over constants        literal    for each distinct constant that the AMD ISA cannot
//                                        encode inline (anything but 0, +-0.5, +-1, +-2, +-4)
// plus the inverse target transforms and linear-scaling opcodes the exported code appends.
//
// The `rdna` and `gcn` tables are least-squares fits of that form to the instruction counts
// that Mesa's ACO compiler produces for RDNA2 (navi21) and GCN5 (vega10) through RADV's null
// device (emit/gpu_cost.hpp, bench/cost); `gpu-generic` is their mean. `nvidia` (issue-rate
// ratios from NVIDIA's documentation) and `cpu` (AVX2 reciprocal throughputs) are hand tables:
// no null device exists for them. The measured cost itself (`cost_measured` in fronts) comes
// from compiling the emitted code, not from this model.
#pragma once

#include <array>
#include <optional>
#include <string_view>
#include <vector>

#include "lgp/core/expr.hpp"
#include "lgp/core/interval.hpp"
#include "lgp/core/ops.hpp"
#include "lgp/core/program.hpp"

namespace lgp {

enum class TargetTransform : uint8_t;  // objectives.hpp

// AMD GPU families whose ISA the GPU-cost backend compiles to (RADV_FORCE_FAMILY names).
enum class GpuFamily : uint8_t { Rdna2, Rdna3, Gcn5 };
inline constexpr int kNumGpuFamilies = 3;
inline constexpr std::array<std::string_view, kNumGpuFamilies> kGpuFamilyNames = {"rdna2", "rdna3",
                                                                                  "gcn5"};
// RADV's name of a chip of the family: navi21 (RX 6800/6900), gfx1100 (RX 7900), vega10
// (RX Vega 56/64).
inline constexpr std::array<std::string_view, kNumGpuFamilies> kGpuFamilyChips = {
    "navi21", "gfx1100", "vega10"};
inline std::string_view toString(GpuFamily f) {
  return kGpuFamilyNames[static_cast<int>(f)];
}
std::optional<GpuFamily> gpuFamilyFromString(std::string_view s);
// Every family, in enum order (RDNA2, RDNA3, GCN5).
std::vector<GpuFamily> allGpuFamilies();

// Whether `v` is one of the float constants AMD's ISA encodes inline in an instruction
// (0, +-0.5, +-1, +-2, +-4; 1/(2 pi) is inline too, but no formula needs it).
bool inlineConstant(double v);

// The features the model prices, counted on a DAG: operator nodes per op (a product read only
// by adds and subtractions counted as fused into each, which then count as mads: the
// instructions it compiles to), protected nodes per op whose guard interval analysis cannot
// remove, distinct non-inline constants, and modifiers that cannot fold. The calibration
// (emit/cost_calibration.hpp) fits the prices.
struct CostFeatures {
  std::array<int, kNumOps> ops{};
  std::array<int, kNumOps> guards{};
  int literals = 0;
  // neg and abs are source modifiers of the instruction that reads them, and saturate is the
  // clamp bit of the one that writes its operand; these count the ones that cannot fold: a
  // neg or abs stored as an output, a saturate of an input, a constant, a select or a value
  // other nodes read unclamped.
  int unfolded_neg_abs = 0;
  int unfolded_saturate = 0;
};
CostFeatures costFeatures(const Dag& d, const std::vector<Interval>& domain);

// How closely a calibrated table predicts the measured instructions of programs it was not
// fitted on (bench/cost: the held-out fifth of the random corpus, against the family named):
// RMS and worst absolute error in instructions, and R^2. None for the hand tables (nvidia, cpu).
struct CostCalibration {
  std::string_view family;
  double rmse;
  double worst_abs;
  double r2;
};
std::optional<CostCalibration> costCalibration(CostTarget t);

// Per-operator costs of a model, after config overrides.
struct CostModel {
  CostTarget target = CostTarget::GpuGeneric;
  std::array<double, kNumOps> cost{};   // per operator node
  std::array<double, kNumOps> guard{};  // extra per protected node whose guard stays
  CostExtras extras{};                  // literals and modifiers that cannot fold
  // Per input; the guards proven unreachable on it cost nothing. Empty: the whole line.
  std::vector<Interval> domain;

  static CostModel preset(CostTarget t, std::vector<Interval> domain = {});
  // The simplified DAG of `p` (formulaDag on `domain`) costed by dagCost.
  double programCost(const Program& p) const;
  // A DAG as given (already simplified, e.g. by the emitter).
  double dagCost(const Dag& d) const;
  // The price of counted features (what dagCost sums).
  double price(const CostFeatures& f) const;
  // Cost of the inverse transforms the emitted code appends (log -> exp, sqrt -> square,
  // rcp -> rcp), added to every member's cost so fronts stay honest.
  double transformCost(const std::vector<TargetTransform>& t) const;
};

// The cost of `p` under every target's preset model, inverse transforms included: the
// `cost_by_target` of fronts and scored formulas.
std::array<double, kNumCostTargets> costByTarget(const Program& p,
                                                 const std::vector<Interval>& domain,
                                                 const std::vector<TargetTransform>& transforms);

}  // namespace lgp
