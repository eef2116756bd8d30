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
// output o. With it, s_o = a_o f_o + b_o, where a_o and b_o are extra LM parameters started
// at the closed-form weighted least-squares fit of T_o(y_o) on f_o (what Scorer does) and
// discarded afterwards (the Scorer refits them in closed form). The fitter minimises the sum
// of squared residuals, whatever ErrorConfig::metric says; callers rescore.
//
// Program values and derivatives are float32 (so residuals are what the interpreter computes);
// sums and the solver work in double. A trial step whose residuals are not all finite counts
// as a huge residual, so the solver rejects it and shrinks its trust region.
#pragma once

#include <limits>
#include <memory>

#include "lgp/core/program.hpp"
#include "lgp/core/status.hpp"
#include "lgp/eval/interpreter.hpp"
#include "lgp/eval/objectives.hpp"

namespace lgp {

struct LevenbergMarquardtConfig {
  int max_iterations = 10;   // solver iterations (each = 1 Jacobian pass + >= 1 residual pass)
  double tolerance = 1e-10;  // relative reduction of the sum of squares at which to stop
  Status validate() const;
};

struct ConstantFitResult {
  double sse_before = std::numeric_limits<double>::infinity();  // weighted sum of squared
  double sse_after = std::numeric_limits<double>::infinity();   // residuals (see above)
  int iterations = 0;                                           // solver iterations run
  // Program evaluations spent: a residual pass counts 1, a Jacobian pass 1 + the number of
  // constants fitted (a forward-mode pass computes a derivative column per constant beside
  // the values: the work of that many forward passes, as for finite differences).
  int evaluations = 0;
  int non_finite = 0;     // trial points rejected because a residual was not finite
  bool improved = false;  // the constants were replaced (sse_after < sse_before)
  // The solver stopped because the sum of squares stopped decreasing (a local minimum within
  // float32 resolution), not for want of iterations or evaluations.
  bool converged = false;
};

// Fits the effective constants of programs to a Dataset (which must outlive it). One instance
// per thread: it owns the evaluator and the solver's buffers, reused from one fit to the next.
class ConstantFitter {
 public:
  ConstantFitter(const Dataset& ds, const ErrorConfig& cfg);
  ~ConstantFitter();
  ConstantFitter(ConstantFitter&&) noexcept;
  ConstantFitter& operator=(ConstantFitter&&) = delete;

  // Minimises the weighted sum of squared residuals above over p's effective constants. p's
  // constants change only if the sum decreased and every residual stayed finite. A program
  // without effective constants returns at once (improved = false, evaluations = 0).
  ConstantFitResult fit(Program& p, const LevenbergMarquardtConfig& c);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace lgp
