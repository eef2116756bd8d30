// Constant optimisation with exact derivatives: Levenberg-Marquardt (Levenberg 1944,
// Marquardt 1963; the trust-region variant of More 1978, as implemented by Eigen's unsupported
// LevenbergMarquardt module) over a program's effective constants, with the Jacobian from the
// forward-mode pass of eval/jacobian.hpp. Gradient-based constant fitting of GP programs
// follows Kommenda et al. 2020 ("Parameter identification for symbolic regression using
// nonlinear least squares").
//
// Residuals. The error is measured on the original scale, so the residuals are too. For each
// error channel c (ErrorConfig::channels; without channels each output o is its own channel
// with weight 1) and each real row r (padded rows are skipped):
//   residual_{c,r} = sqrt(w_r) * (sum_o W_{c,o} g_o(x_r) - sum_o W_{c,o} y_{o,r})
// where w_r is the row weight, W_{c,o} the channel weights, y the original targets and
// g_o = invertTransform(T_o, s_o) with the protected inverses of objectives.cpp (log: exp(s),
// sqrt: s > 0 ? s^2 : 0, rcp: 1/guard(s)). Without linear scaling s_o = f_o, the program's
// output o. With it, s_o = a_o f_o + b_o. For plain least squares a_o and b_o are extra LM
// parameters started at the closed-form weighted least-squares fit of T_o(y_o) on f_o (what
// Scorer does) and discarded afterwards (the Scorer refits them in closed form). For reweighted
// rounds they are that closed-form fit at every point (variable projection, Golub & Pereyra
// 1973): LM moves the constants only, with the Jacobian of the projected residual, so every
// round minimises its surrogate of exactly the error the Scorer measures.
//
// Objective. LmObjective::LeastSquares minimises the sum of squares above, whatever the metric.
// LmObjective::Configured fits the configured error: plain least squares for rmse on one
// channel (but for a transformed output under linear scaling, whose scale the Scorer fits on
// the transformed scale: rounds of weight 1 there), else rounds of iteratively reweighted least
// squares, residual_{c,r} scaled by sqrt(u_{c,r} v_c) from the residuals e at the round's
// starting point:
//   mae       u = 1 / max(|e|, eps)                          (IRLS for the L1 norm)
//   mean_rel  u = 1 / (max(|y|, rel_floor) max(|e|, eps))    (mae of the relative error,
//                                                             the Scorer's row weights)
//   max_abs   u <- u |e| / sum(w u |e|), kept above a floor    (Lawson 1961: weights toward
//                                                             the minimax fit)
//   rmse      u = 1
// with eps a small fraction of the channel's mean error. Several channels: v_c makes the
// channel's share of the gradient that of its error in the combination: under Mean 1/error_c
// for rmse and max_abs (whose surrogates are squares), 1 for mae and mean_rel; under Max the
// gradient of sum_c error_c^p with p = 2, 4, 8, ... over the rounds, toward the worst channel. The
// Scorer's error, not the surrogate, judges every round's end point: the result is the best of them
// on the configured error, never worse than the start, and the fit stops at the first round that
// does not improve it.
//
// Program values and derivatives are float32 (so residuals are what the interpreter computes);
// sums and the solver work in double. A trial step whose residuals are not all finite counts
// as a huge residual, so the solver rejects it and shrinks its trust region.
#pragma once

#include <cstdint>
#include <limits>
#include <memory>

#include "lgp/core/program.hpp"
#include "lgp/core/status.hpp"
#include "lgp/eval/interpreter.hpp"
#include "lgp/eval/objectives.hpp"

namespace lgp {

enum class LmObjective : uint8_t {
  LeastSquares,  // the weighted sum of squares, whatever the metric
  Configured,    // the configured error (see above): reweighted rounds where it differs
  // Configured, but LeastSquares under linear scaling: on the DFG runs of
  // docs/constant-fitting.md the projected rounds did not beat least squares with the
  // Nelder-Mead polish there.
  Auto
};

struct LevenbergMarquardtConfig {
  int max_iterations = 10;   // solver iterations (each = 1 Jacobian pass + >= 1 residual pass),
                             // all rounds together
  double tolerance = 1e-10;  // relative reduction of the sum of squares at which to stop
  LmObjective objective = LmObjective::Auto;
  int max_rounds = 8;  // reweighting rounds at most (Configured, where it differs)
  Status validate() const;
};

// What LM with objective `o` does for an error configuration with `channels` error channels
// (ErrorConfig::channels, or one per output without them): reweighted rounds judged by the
// Scorer (`rounds`), and whether what it minimises is the error the Scorer measures
// (`fits_error`: rounds, or plain least squares where that is the error: rmse on one channel,
// but not for a transformed output under linear scaling, whose scale the Scorer fits on the
// transformed scale).
struct LmPlan {
  bool rounds = false;
  bool fits_error = false;
};
LmPlan lmPlan(LmObjective o, const ErrorConfig& cfg, size_t channels);

struct ConstantFitResult {
  double sse_before = std::numeric_limits<double>::infinity();  // weighted sum of squared
  double sse_after = std::numeric_limits<double>::infinity();   // residuals (see above)
  int iterations = 0;                                           // solver iterations run
  // Program evaluations spent: a residual pass counts 1, a Jacobian pass 1 + the number of
  // constants fitted (a forward-mode pass computes a derivative column per constant beside
  // the values: the work of that many forward passes, as for finite differences).
  int evaluations = 0;
  int non_finite = 0;  // trial points rejected because a residual was not finite
  // The constants were replaced: sse_after < sse_before, or on reweighted rounds
  // error_after < error_before.
  bool improved = false;
  // The solver stopped because the sum of squares stopped decreasing (a local minimum within
  // float32 resolution), not for want of iterations or evaluations. On reweighted rounds: the
  // last round's solver converged and that round did not lower the error (a fixed point of
  // the reweighting as far as the Scorer can tell).
  bool converged = false;
  // Reweighted rounds only: rounds run, and the Scorer's error at the start and at the result
  // (each Scorer call counts one evaluation). NaN where the fit was plain least squares.
  int rounds = 0;
  double error_before = std::numeric_limits<double>::quiet_NaN();
  double error_after = std::numeric_limits<double>::quiet_NaN();
};

// Fits the effective constants of programs to a Dataset (which must outlive it). One instance
// per thread: it owns the evaluator and the solver's buffers, reused from one fit to the next.
class ConstantFitter {
 public:
  ConstantFitter(const Dataset& ds, const ErrorConfig& cfg);
  ~ConstantFitter();
  ConstantFitter(ConstantFitter&&) noexcept;
  ConstantFitter& operator=(ConstantFitter&&) = delete;

  // Fits p's effective constants to c.objective (see above). p's constants change only if
  // the objective decreased (the sum of squares, or the Scorer's error on reweighted rounds)
  // and every residual stayed finite. A program without effective constants returns at once
  // (improved = false, evaluations = 0).
  ConstantFitResult fit(Program& p, const LevenbergMarquardtConfig& c);
  // Whether c.objective fits the configured error in reweighted rounds (judged by the Scorer)
  // rather than as a plain sum of squares.
  bool reweights(const LevenbergMarquardtConfig& c) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace lgp
