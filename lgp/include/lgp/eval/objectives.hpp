// The three objectives of the search, all minimised:
//  error          RMSE (default), max-abs, MAE or mean relative error against the double
//                 ground truth, optionally weighted per row. When an output is fitted on a
//                 transformed target, the program's value is mapped
//                 back through the inverse transform and the error is measured on the
//                 original. Several outputs combine by mean (default) or max.
//  cost           sum over effective opcodes of the per-operator cost of a target model
//                 (cost_model.hpp).
//  discontinuity  weighted count of piecewise operators among effective opcodes whose branch
//                 may switch on the table's domain (discontinuity.hpp).
// This header holds the error (the Scorer measures nothing else) and the triple; the search
// adds the other two from their own models.
// A program whose output is NaN or Inf on any row gets error = +inf: it is the worst and
// never enters a front.
#pragma once

#include <array>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "lgp/core/ops.hpp"
#include "lgp/core/program.hpp"
#include "lgp/eval/cost_model.hpp"
#include "lgp/eval/fidelity.hpp"
#include "lgp/eval/interpreter.hpp"
#include "lgp/eval/metrics.hpp"

namespace lgp {

enum class TargetTransform : uint8_t { None, Log, Sqrt, Rcp };
enum class OutputCombine : uint8_t { Mean, Max };

std::string_view toString(ErrorMetric m);
std::string_view toString(TargetTransform t);
std::string_view toString(OutputCombine c);
std::optional<ErrorMetric> errorMetricFromString(std::string_view s);
std::optional<TargetTransform> targetTransformFromString(std::string_view s);
std::optional<OutputCombine> outputCombineFromString(std::string_view s);

// Forward map applied to the ground truth before fitting; the program predicts T(y).
double applyTransform(TargetTransform t, double y);
// Inverse, applied to predictions before measuring error.
double invertTransform(TargetTransform t, double v);

// The error is measured on channels: a channel is a weighted sum of the model's outputs
// (after inverse transforms) against the same sum of targets. Without channels every output
// is its own channel.
struct ErrorChannel {
  std::string name;
  std::vector<double> weights;  // one per output
};

struct ErrorConfig {
  ErrorMetric metric = ErrorMetric::Rmse;       // the objective
  OutputCombine combine = OutputCombine::Mean;  // across channels (outputs by default)
  std::vector<TargetTransform> transforms;      // per output; empty = none
  double rel_floor = 1e-6;                      // MeanRel divides by max(|y|, rel_floor)
  std::vector<ErrorChannel> channels;           // empty = one per output
  // error() fits each raw program output as a*f + b (weighted least squares against the
  // transformed target) before measuring; metrics() never scales.
  bool linear_scaling = false;
  // The output layer under linear scaling (program.genes): output o is b_o + sum over g <
  // genes of a_g f_(o*genes+g), a weighted least-squares fit over `genes` raw program outputs
  // (multi-gene regression, Searson et al. 2010). 1 is a*f + b.
  int genes = 1;
};

// Genes per output of the output layer, at most.
inline constexpr int kMaxGenes = 16;

// Scale and offset of one raw output under linear scaling (one gene of the output layer; the
// offset sits on the output's lead gene, see Scorer::scales()).
struct LinearScale {
  float a = 1.0f, b = 0.0f;
  bool identity() const { return a == 1.0f && b == 0.0f; }
  // The opcode that applies it: mul(f, a) when b = 0, add(f, b) when a = 1, else mad(f, a, b).
  Op op() const { return b == 0.0f ? Op::Mul : a == 1.0f ? Op::Add : Op::Mad; }
};


struct Objectives {
  double error = std::numeric_limits<double>::infinity();
  double cost = 0;
  double discontinuity = 0;
  bool finite() const { return error < std::numeric_limits<double>::infinity(); }
};

// Scorer sums errors in float per block (32 lanes, fixed order) and adds each block's partial
// sums to double totals in block order, so results depend only on the data. Against the same
// float predictions measured in double, with u = 2^-24, B the block size, Y = max |y| of the
// output (or channel) and finite float weights:
//   rmse      |fast - double| <= (B/64 + 6) u rmse     + 8 u^2 Y
//   mae       |fast - double| <= (B/32 + 8) u mae      + 8 u^2 Y
//   mean_rel  |fast - double| <= (B/32 + 8) u mean_rel + 8 u^2 + 2^-148 Y / rel_floor
//   max_abs   |fast - double| <= 3 u max_abs           + 8 u^2 Y
// Per row the float difference has relative error 2u and absolute error 2u^2 |y|; rounding
// the weight and the weighted term adds 3u (squaring: 4u + u); a lane sums B/32 terms, the
// lane tree 5 more; the last term of mean_rel covers targets in float's subnormal range after
// scaling (|y| < 2^-126 Y). A block whose float sums overflow (a prediction some 2^60 times
// Y off) is summed in double instead. For B = 256: 1.4e-6 relative for MAE, 8e-7 for RMSE.
// This returns the bound.
double fastErrorBound(ErrorMetric m, double reference, double max_abs_target, int block_size,
                      double rel_floor = 1e-6);

namespace detail {
struct ErrorAcc {  // per-output sums over rows, combined in block order
  double sse = 0, sae = 0, srel = 0, maxabs = 0;
  float chk = 0;  // becomes NaN if any prediction is NaN or Inf
};
// What one output or channel is measured against: its target in float form (hi + lo), the
// double original (fallback) and MeanRel's per-row weights w / max(|y|, rel_floor), in float.
struct ErrorTarget {
  const SplitColumn* col = nullptr;
  const double* y = nullptr;
  std::vector<float, AlignedAllocator<float>> rel_w;
};
}  // namespace detail

// Scores programs against a Dataset with one Interpreter; one instance per thread.
// The Dataset holds the original targets; with a transform, output o of the model is
// invertTransform(T_o, program output o), and that is what the error compares.
class Scorer {
 public:
  Scorer(const Dataset& ds, ErrorConfig cfg, int block_size);
  // The error objective only (fast path used by the search and Nelder-Mead).
  double error(const Program& p);
  double error(const BoundProgram& bp);
  // Every metric per output, float32 path.
  std::vector<OutputMetrics> metrics(const Program& p);
  // Every metric per channel (per output when the config has no channels), float32 path.
  std::vector<OutputMetrics> channelMetrics(const Program& p);
  // The output layer fitted by the last error() call under linear scaling, one scale per raw
  // program output (o * genes + g), identity otherwise. Output o is its lead gene (the first
  // with a != 0, or gene 0) scaled, plus a_g f_g of each later gene with a_g != 0; only the
  // lead carries an offset (applyLinearScaling materialises exactly this).
  const std::vector<LinearScale>& scales() const { return scales_; }
  // From now on error() checks every finite result with `check` (fidelity.hpp) and returns
  // +inf for a program that fails it (the worst error, like a NaN output); nullptr = off. The
  // check must outlive the Scorer's use of it.
  void setFidelity(FidelityCheck* check) { fidelity_ = check; }
  // Programs error() refused for fidelity since construction.
  uint64_t fidelityRejects() const { return fidelity_rejects_; }
  // The program bound by the last error(Program), metrics() or channelMetrics() call; its
  // `effective` opcodes spare callers a second effectiveIndices().
  const BoundProgram& bound() const { return bound_; }

 private:
  template <int M>
  void run(const BoundProgram& bp, std::vector<detail::ErrorAcc>& accs);
  // Channel or scaled path: buffers every output of every row, then measures.
  template <int M>
  bool runBuffered(const BoundProgram& bp, bool scale, std::vector<detail::ErrorAcc>& accs);
  // A program whose outputs do not depend on the inputs: one row of the interpreter, then
  // closed forms (sse, max_abs) or a pass over the targets only (mae, mean_rel). `buffered`
  // follows runBuffered (channels, scaling), else run.
  template <int M>
  bool runConstant(const BoundProgram& bp, bool buffered, bool scale,
                   std::vector<detail::ErrorAcc>& accs);
  bool buffered() const { return !cfg_.channels.empty() || cfg_.linear_scaling; }
  // Fills acc_ for metric M by whichever path the config needs; false if an output is not
  // finite.
  template <int M>
  bool measure(const BoundProgram& bp);
  // Weighted least squares of T(y_o) on the raw output v (every padded row).
  LinearScale fitScale(const float* v, int o) const;
  // The output layer of output o over raw_[o * genes + g] (genes > 1) into scales_.
  void fitLayer(int o);

  const Dataset& ds_;
  ErrorConfig cfg_;
  Interpreter interp_;
  BoundProgram bound_;
  std::vector<detail::ErrorAcc> acc_;             // per-output accumulators, reused
  std::vector<float> pred_;                       // inverse-transformed predictions of one block
  std::vector<detail::ErrorTarget> targets_;      // per output
  std::vector<double> errors_;                    // per-output errors of the last error() call
  std::vector<std::vector<float>> raw_;           // buffered path: per output, every padded row
  std::vector<double> fit_mean_;                  // linear scaling: weighted mean of T(y_o)
  std::vector<std::vector<double>> fit_centred_;  // linear scaling: T(y_o) - fit_mean_[o]
  std::vector<std::vector<double>> chan_target_;  // per channel target (channels only)
  std::vector<SplitColumn> chan_cols_;            // the same in float form, with statistics
  std::vector<detail::ErrorTarget> chan_targets_;
  std::vector<float> chan_pred_;   // one channel's predictions
  std::vector<float> const_pred_;  // a constant program's prediction broadcast over a block
  std::vector<float> const_vals_;  // a constant program's final value per output
  std::vector<LinearScale> scales_;
  std::vector<std::vector<float>> layer_;  // genes > 1: per output, the layer's values
  std::vector<float*> model_;              // buffered path: per output, its values
  std::vector<double> gram_;               // fitLayer's normal equations
  int genes_ = 1;                          // cfg_.genes under linear scaling, else 1
  FidelityCheck* fidelity_ = nullptr;
  uint64_t fidelity_rejects_ = 0;
};

// Appends the output layer's opcodes to a copy of `p`, with new constant slots: per output,
// the lead gene's scale (mad, or mul/add where a = 1 or b = 0), then a mad per later gene with
// a != 0 (Scorer::scales()); the program's outputs become one per model output (designated).
// The result computes exactly what Scorer::error() measured. `genes` = scales per output.
Program applyLinearScaling(const Program& p, const std::vector<LinearScale>& scales, int genes = 1);

// The error a float32 evaluation of the exact formula reaches on `t` by rounding alone:
// 2^-24 times the targets' RMS (rmse), mean |y| (mae) or max |y| (max_abs), or 2^-24
// (mean_rel), per output, combined like the error (mean or max). Constant snapping
// (core/snap.hpp) treats error changes below it as none.
double float32ErrorFloor(const ErrorConfig& cfg, const Table& t);

// Whether the table, under this error config, stays within what the float32 evaluation and
// its double sums represent, so that some program can have a finite error. Checked before a
// search starts (lgp run, lgpd): every value within the float32 range (Table::validate), each
// error channel's target (its weighted sum of outputs) within it too, transformed targets
// finite, and the weighted sums of the targets and of their squares (what rmse, mae, r2 and
// linear scaling add up) finite in double. The message names the output or channel and row.
Status checkErrorNumerics(const Table& t, const ErrorConfig& cfg);

// Metrics in double precision via the reference evaluator (the "double check path").
std::vector<OutputMetrics> referenceMetrics(const Program& p, const Table& original,
                                            const ErrorConfig& cfg);
// The same per channel (per output when the config has no channels).
std::vector<OutputMetrics> referenceChannelMetrics(const Program& p, const Table& original,
                                                   const ErrorConfig& cfg);
// Combines per-channel metrics (per-output ones when there are no channels) into the error.
double combineError(const std::vector<OutputMetrics>& m, const ErrorConfig& cfg);
// Channel names: the configured ones, or the output names.
std::vector<std::string> channelNames(const ErrorConfig& cfg,
                                      const std::vector<std::string>& output_names);

}  // namespace lgp
