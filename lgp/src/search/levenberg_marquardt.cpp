// Levenberg-Marquardt constant fitting (see levenberg_marquardt.hpp): our residuals and
// Jacobian, Eigen's solver.
#include "lgp/search/levenberg_marquardt.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <type_traits>
#include <unsupported/Eigen/LevenbergMarquardt>
#include <utility>
#include <vector>

#include "lgp/eval/jacobian.hpp"
#include "lgp/eval/semantics.hpp"

namespace lgp {

Status LevenbergMarquardtConfig::validate() const {
  if (max_iterations < 1) return Status::error("max_iterations: must be >= 1");
  if (!(tolerance >= 0)) return Status::error("tolerance: must be >= 0");
  if (max_rounds < 1) return Status::error("max_rounds: must be >= 1");
  return Status::ok();
}

namespace {

// Residual norm reported for a point whose residuals or constants are not all finite: the
// solver never accepts such a step (it needs a decrease) and shrinks its trust region.
constexpr double kHugeResidual = 1e300;
// Relative step size below which the solver stops: constants are float32, so smaller steps
// round to the same program.
constexpr double kXtol = 1e-7;
// Sum-of-squares changes below kNoiseFloor * sum(w y^2) are float32 rounding noise (a few ulp
// of every prediction, squared): the solver stops there instead of chasing it.
constexpr double kNoiseFloor = 1e-12;
// Eigenvalues of J'J below this fraction of the largest are treated as zero: J is float32
// (relative error ~1e-7, squared 1e-14), so those directions are not resolved.
constexpr double kRankTolerance = 1e-13;
// Residual passes allowed per iteration on average (rejected trial steps cost one each).
constexpr int kEvaluationsPerIteration = 4;
// Solver iterations per reweighted round at most: the weights are only as good as the point
// they were taken at, so a round solves its least-squares problem roughly and hands over.
constexpr int kRoundIterations = 3;
// IRLS for the L1 norm: residuals below this fraction of the channel's mean error weigh as
// much as one at it (the weight 1/|e| is capped, the usual regularisation).
constexpr double kL1Eps = 1e-3;
// Lawson weights never drop below this fraction of the largest, so a row that leaves the
// extremal set can come back (the program is nonlinear in its constants).
constexpr double kLawsonFloor = 1e-6;
// Under OutputCombine::Mean a channel's factor 1/error_c is capped at 1/(this * the worst
// error): a channel at error 0 is at a kink of rmse, not at an infinite gradient.
constexpr double kChannelCap = 1e-3;
// A reweighted round's step is halved at most this many times until the Scorer takes it.
constexpr int kHalvings = 2;

// a * b + c, fused where the ISA has it (one rounding, twice the throughput).
inline double fmadd(double a, double b, double c) {
#if defined(__FMA__)
  return __builtin_fma(a, b, c);
#else
  return a * b + c;
#endif
}

// g = invertTransform(T, s) and dg/ds, with the protected inverses of objectives.cpp. exp is
// taken in float32 (the vectorised exp the Scorer uses); the rest in double.
template <TargetTransform T>
inline void inverse(double s, double& g, double& dg) {
  if constexpr (T == TargetTransform::None) {
    g = s;
    dg = 1.0;
  } else if constexpr (T == TargetTransform::Log) {
    const float t = static_cast<float>(s) * static_cast<float>(sem::kLog2E);
    g = sem::pexp2(t);
    dg = std::fabs(t) < kExpClamp ? g : 0.0;
  } else if constexpr (T == TargetTransform::Sqrt) {
    g = s > 0 ? s * s : 0.0;
    dg = s > 0 ? 2 * s : 0.0;
  } else {
    g = 1.0 / sem::guard(s);
    dg = std::fabs(s) < static_cast<double>(kDivGuard) ? 0.0 : -g * g;
  }
}

// The closed-form least-squares scale a f + b from the centred weighted sums, in double, with
// the Scorer's guards (objectives.cpp, scaleFromSums): a = 0 (offset only) for a flat or
// degenerate f.
struct Scale {
  double a, b;
};
Scale closedFormScale(double sw, double mf, double my, double sff, double sfy) {
  double a = sff > 1e-12 * sw * (1.0 + mf * mf) ? sfy / sff : 0.0;
  double b = my - a * mf;
  if (!std::isfinite(a) || !std::isfinite(b) || std::fabs(a) > 1e30 || std::fabs(b) > 1e30) {
    a = 0.0;
    b = std::isfinite(my) ? my : 0.0;
  }
  return {a, b};
}

// Calls fn(std::integral_constant<TargetTransform, t>{}).
template <class Fn>
void withTransform(TargetTransform t, Fn&& fn) {
  using TT = TargetTransform;
  switch (t) {
    case TT::None:
      return fn(std::integral_constant<TT, TT::None>{});
    case TT::Log:
      return fn(std::integral_constant<TT, TT::Log>{});
    case TT::Sqrt:
      return fn(std::integral_constant<TT, TT::Sqrt>{});
    case TT::Rcp:
      return fn(std::integral_constant<TT, TT::Rcp>{});
  }
}

}  // namespace

struct ConstantFitter::Impl {
  // Eigen's functor interface over the compressed problem (see pass()): n + 1 residuals.
  struct Functor {
    using Scalar = double;
    using InputType = Eigen::VectorXd;
    using ValueType = Eigen::VectorXd;
    using JacobianType = Eigen::MatrixXd;
    using QRSolver = Eigen::ColPivHouseholderQR<JacobianType>;
    enum { InputsAtCompileTime = Eigen::Dynamic, ValuesAtCompileTime = Eigen::Dynamic };
    Impl* self;
    int inputs() const { return static_cast<int>(self->num_vars); }
    int values() const { return static_cast<int>(self->num_vars + 1); }
    int operator()(const Eigen::VectorXd& x, Eigen::VectorXd& f) const {
      f.setZero(values());
      f[0] = self->evaluate(x, false);
      return 0;
    }
    int df(const Eigen::VectorXd& x, Eigen::MatrixXd& j) const {
      self->evaluate(x, true);
      self->compress(j, self->lm.fvec());
      if (self->projected) {
        // The solver's step scaling: Eigen takes the column norms of the Jacobian, but a
        // projected column can be 0 up to rounding (a constant the scales absorb: an offset,
        // a common factor), which would let the step run off along it. Each constant's column
        // before projection (its effect on the unscaled output) measures it instead; the
        // largest seen, as Eigen does.
        Eigen::VectorXd& d = self->lm.diag();
        for (Eigen::Index v = 0; v < d.size(); ++v)
          d[v] = std::max(d[v], self->ext_norm[v] > 0 ? self->ext_norm[v] : 1.0);
      }
      return 0;
    }
  };

  Impl(const Dataset& d, const ErrorConfig& c) : ds(d), cfg(c), functor{this}, lm(functor) {
    const int k = ds.numOutputs();
    transforms = c.transforms;
    transforms.resize(k, TargetTransform::None);
    scaling = c.linear_scaling;
    rows = ds.rows();
    bs = ds.blockSize();
    // Channels as sparse (output, weight) lists; without channels, one per output.
    if (c.channels.empty()) {
      for (int o = 0; o < k; ++o) channels.push_back({{o, 1.0}});
    } else {
      for (const ErrorChannel& ch : c.channels) {
        channels.emplace_back();
        for (int o = 0; o < k && o < static_cast<int>(ch.weights.size()); ++o)
          if (ch.weights[o] != 0) channels.back().push_back({o, ch.weights[o]});
      }
    }
    sqrt_w.resize(rows);
    for (size_t r = 0; r < rows; ++r) sqrt_w[r] = std::sqrt(ds.weight()[r]);
    swy.assign(channels.size() * rows, 0.0);
    chan_y.assign(channels.size() * rows, 0.0);
    double sy2 = 0;
    for (size_t ch = 0; ch < channels.size(); ++ch)
      for (size_t r = 0; r < rows; ++r) {
        double y = 0;
        for (const auto& [o, w] : channels[ch]) y += w * ds.target(o)[r];
        chan_y[ch * rows + r] = y;
        swy[ch * rows + r] = sqrt_w[r] * y;
        sy2 += swy[ch * rows + r] * swy[ch * rows + r];
      }
    plain_noise_floor = kNoiseFloor * sy2;
    noise_floor = plain_noise_floor;
    scale.assign(channels.size() * rows, 1.0);
    plain.assign(channels.size() * rows, 0.0);
    if (scaling) {
      raw.resize(static_cast<size_t>(k) * ds.paddedRows());
      fit_target.resize(static_cast<size_t>(k) * ds.paddedRows());
      fit_centred.resize(static_cast<size_t>(k) * ds.paddedRows());
      t_mean.assign(k, 0.0);
      const double* w = ds.weight();
      for (int o = 0; o < k; ++o) {
        double* t = fit_target.data() + o * ds.paddedRows();
        for (size_t r = 0; r < ds.paddedRows(); ++r) {
          t[r] = applyTransform(transforms[o], ds.target(o)[r]);
          t_mean[o] += w[r] * t[r];
        }
        t_mean[o] /= ds.weightSum();
        for (size_t r = 0; r < ds.paddedRows(); ++r)
          fit_centred[o * ds.paddedRows() + r] = t[r] - t_mean[o];
      }
    }
    q.resize(k);
    fv.resize(k);
    // Outputs alone in a single-output channel: their inverse transform fuses into the
    // residual loop.
    alone.assign(k, 0);
    std::vector<int> uses(k, 0);
    for (const auto& ch : channels)
      for (const auto& [o, w] : ch) uses[o] += ch.size() == 1 ? 1 : 2;
    for (int o = 0; o < k; ++o) alone[o] = uses[o] == 1;
    g.resize(static_cast<size_t>(k) * bs);
    gp.resize(static_cast<size_t>(k) * bs);
    res_block.resize(channels.size() * bs);
    num_res = static_cast<Eigen::Index>(channels.size() * rows);
  }

  // Closed-form weighted least squares of T(y) on the raw outputs (as Scorer::runBuffered):
  // the starting a_o, b_o of linear scaling.
  void initialScales(Eigen::VectorXd& x, int p0) {
    const size_t n = ds.paddedRows();
    for (size_t b = 0; b < ds.numBlocks(); ++b) {
      jac.evalBlock(b, false);
      for (int o = 0; o < jac.numOutputs(); ++o)
        std::copy_n(jac.value(o), bs, raw.data() + o * n + b * bs);
    }
    ++evaluations;
    const double* w = ds.weight();
    for (int o = 0; o < jac.numOutputs(); ++o) {
      const float* v = raw.data() + o * n;
      const double* y = fit_target.data() + o * n;
      double sw = 0, sf = 0, sy = 0;
      for (size_t r = 0; r < n; ++r) {
        sw += w[r];
        sf += w[r] * v[r];
        sy += w[r] * y[r];
      }
      const double mf = sf / sw, my = sy / sw;
      double sff = 0, sfy = 0;
      for (size_t r = 0; r < n; ++r) {
        const double df = v[r] - mf;
        sff += w[r] * df * df;
        sfy += w[r] * df * (y[r] - my);
      }
      const Scale sc = closedFormScale(sw, mf, my, sff, sfy);
      x[p0 + 2 * o] = sc.a;
      x[p0 + 2 * o + 1] = sc.b;
    }
    raw_valid = true;
  }

  // A residual or Jacobian pass at the solver's point x. Plain mode: pass(x). Projected mode
  // (reweighted rounds under linear scaling): the scales are not parameters but the Scorer's
  // closed-form least-squares fit at x (variable projection, Golub & Pereyra 1973), so LM
  // minimises the surrogate of exactly the error the Scorer measures.
  double evaluate(const Eigen::VectorXd& x, bool jacobian) {
    // A residual pass at the point whose plain residuals are at hand (a round's first pass,
    // after reweighting there) costs no evaluation.
    if (!jacobian && plain_valid && plain_theta.size() == x.size() && plain_theta == x) {
      raw_valid = false;
      double sse = 0;
      for (size_t i = 0; i < plain.size(); ++i)
        sse += (plain[i] * scale[i]) * (plain[i] * scale[i]);
      return std::isfinite(sse) ? std::sqrt(sse) : kHugeResidual;
    }
    plain_valid = false;
    double norm;
    if (!projected) {
      norm = pass(x, jacobian);
    } else {
      if (!projectScales(x)) {
        ++non_finite;
        if (jacobian) gram.setZero(x.size() + 1, x.size() + 1);
        return kHugeResidual;
      }
      raw_valid = !jacobian;  // a residual pass reads the values projectScales computed
      norm = pass(xe, jacobian);
      if (jacobian) projectGram();
    }
    if (plain_valid) plain_theta = x;
    return norm;
  }

  // Projected mode: the program's values at x (one evaluation, skipped when `raw` holds x's
  // already: the solver asks for the Jacobian where it has just evaluated the residuals) and
  // from them the Scorer's scales, into xe = [x | a_0 b_0 ...]. False if a constant or a
  // value is not finite (the Scorer fails such a program).
  bool projectScales(const Eigen::VectorXd& x) {
    const int np = static_cast<int>(x.size());
    const int k = jac.numOutputs();
    const size_t n = ds.paddedRows();
    if (!(values_valid && values_x == x)) {
      values_valid = false;
      for (int p = 0; p < np; ++p)
        if (!std::isfinite(static_cast<float>(x[p]))) return false;
      jac.setParameters(x.data());
      for (size_t b = 0; b < ds.numBlocks(); ++b) {
        jac.evalBlock(b, false);
        for (int o = 0; o < k; ++o) std::copy_n(jac.value(o), bs, raw.data() + o * n + b * bs);
      }
      ++evaluations;
      values_x = x;
      values_valid = true;
    }
    xe.resize(np + 2 * k);
    xe.head(np) = x;
    const double* w = ds.weight();
    const double sw = ds.weightSum();
    f_mean.assign(k, 0.0);
    f_ss.assign(k, 0.0);
    for (int o = 0; o < k; ++o) {
      const float* v = raw.data() + o * n;
      const double* yc = fit_centred.data() + o * n;
      double sf = 0;
      float chk = 0;  // not 0 if a value is not finite
#pragma omp simd reduction(+ : sf, chk)
      for (size_t r = 0; r < n; ++r) {
        sf += w[r] * v[r];
        chk += v[r] * 0.0f;
      }
      if (!(chk == 0.0f)) return false;
      const double mf = sf / sw;
      double sff = 0, sfy = 0;
#pragma omp simd reduction(+ : sff, sfy)
      for (size_t r = 0; r < n; ++r) {
        const double df = v[r] - mf;
        sff += w[r] * df * df;
        sfy += w[r] * df * yc[r];
      }
      const Scale sc = closedFormScale(sw, mf, t_mean[o], sff, sfy);
      xe[np + 2 * o] = sc.a;
      xe[np + 2 * o + 1] = sc.b;
      f_mean[o] = mf;
      f_ss[o] = sc.a != 0.0 ? sff : 0.0;  // 0: the scales do not move with x here
    }
    sums.assign(static_cast<size_t>(k) * np * 3, 0.0);
    return true;
  }

  // Projected mode, after pass(xe, true): folds the scale columns of the Gram matrix into the
  // constants' columns. With s = a f + b and (a, b) the weighted least-squares fit of the
  // centred T(y) on f, differentiating the normal equations gives, per constant k,
  //   da = (sum w J (t - tm) - 2 a sum w J (f - fm)) / sum w (f - fm)^2,  db = -da fm - a Jm,
  // so ds/dc_k = a J + da f + db: the pass's column for c_k plus da times the column for a
  // plus db times the column for b. [J_proj | r] = [J_ext | r] T, hence gram <- T' gram T.
  void projectGram() {
    const int k = jac.numOutputs();
    const Eigen::Index np = num_vars, ne = xe.size();
    const double sw = ds.weightSum();
    Eigen::MatrixXd t = Eigen::MatrixXd::Zero(ne + 1, np + 1);
    for (Eigen::Index v = 0; v < np; ++v) t(v, v) = 1.0;
    t(ne, np) = 1.0;
    for (int o = 0; o < k; ++o) {
      if (!(f_ss[o] > 0)) continue;
      const double a = xe[np + 2 * o];
      for (Eigen::Index v = 0; v < np; ++v) {
        const double* sv = sums.data() + (static_cast<size_t>(o) * np + v) * 3;
        const double da = (sv[1] - 2.0 * a * sv[2]) / f_ss[o];
        t(np + 2 * o, v) = da;
        t(np + 2 * o + 1, v) = -da * f_mean[o] - a * sv[0] / sw;
      }
    }
    ext_norm.resize(np);
    for (Eigen::Index v = 0; v < np; ++v) ext_norm[v] = std::sqrt(std::max(gram(v, v), 0.0));
    const Eigen::MatrixXd full = gram.selfadjointView<Eigen::Upper>();
    gram = t.transpose() * full * t;
  }

  // Projected mode, inside a Jacobian pass: per output and constant, the block's share of
  // sum w J, sum w J (t - tm) and sum w J (f - fm) (projectGram's sums).
  void accumulateSums(size_t r0, int nr) {
    const int np = static_cast<int>(num_vars);
    const size_t n = ds.paddedRows();
    const double* w = ds.weight() + r0;
    for (int o = 0; o < jac.numOutputs(); ++o) {
      const float* f = jac.value(o);
      const double* yc = fit_centred.data() + o * n + r0;
      const double mf = f_mean[o];
      for (int v = 0; v < np; ++v) {
        if (!jac.hasDerivative(o, v)) continue;
        const float* d = jac.derivative(o, v);
        double s0 = 0, s1 = 0, s2 = 0;
#pragma omp simd reduction(+ : s0, s1, s2)
        for (int i = 0; i < nr; ++i) {
          const double wj = w[i] * static_cast<double>(d[i]);
          s0 += wj;
          s1 += wj * yc[i];
          s2 += wj * (static_cast<double>(f[i]) - mf);
        }
        double* sv = sums.data() + (static_cast<size_t>(o) * np + v) * 3;
        sv[0] += s0;
        sv[1] += s1;
        sv[2] += s2;
      }
    }
  }

  // pass()'s Jacobian part for the block of rows r0..r0+nr: once it has written the block's
  // residual column and q, the derivative columns into block_a and their products into gram.
  void jacobianBlock(const Eigen::VectorXd& x, size_t r0, int nr) {
    const int np = jac.numParameters();
    const size_t n = rows;
    const size_t nc = channels.size();
    const int na = static_cast<int>(nc) * nr;
    // d r / d c_k = sum_o W q_o a_o df_o/dc_k, d r / d a_o = W q_o f_o, d r / d b_o = W q_o.
    for (size_t c = 0; c < nc; ++c) {
      const std::vector<int>& act = active[c];
      for (size_t j = 0; j + 1 < act.size(); ++j) {  // the last one is the residual
        const int v = act[j];
        double* out = block_a.data() + static_cast<size_t>(v) * na + c * nr;
        bool first = true;  // the first contribution assigns, later ones add
        for (const auto& [o, w] : channels[c]) {
          const double* qo = q[o];
          const float* d;  // the factor beside q: df_o/dc_v, f_o, or none (1)
          double sc = w;
          if (v < np) {
            if (!jac.hasDerivative(o, v)) continue;
            d = jac.derivative(o, v);
            if (scaling) sc *= x[np + 2 * o];
          } else if (v == np + 2 * o) {
            d = jac.value(o);
          } else if (v == np + 2 * o + 1) {
            d = nullptr;
          } else {
            continue;
          }
          if (d == nullptr && first) {
#pragma omp simd
            for (int i = 0; i < nr; ++i) out[i] = sc * qo[i];
          } else if (d == nullptr) {
#pragma omp simd
            for (int i = 0; i < nr; ++i) out[i] += sc * qo[i];
          } else if (first) {
#pragma omp simd
            for (int i = 0; i < nr; ++i) out[i] = sc * qo[i] * d[i];
          } else {
#pragma omp simd
            for (int i = 0; i < nr; ++i) out[i] += sc * qo[i] * d[i];
          }
          first = false;
        }
      }
      if (weighted) {  // the residual column is scaled already
        const double* sc = scale.data() + c * n + r0;
        for (size_t j = 0; j + 1 < act.size(); ++j) {
          double* out = block_a.data() + static_cast<size_t>(act[j]) * na + c * nr;
#pragma omp simd
          for (int i = 0; i < nr; ++i) out[i] *= sc[i];
        }
      }
      accumulateGram(act, block_a.data() + c * nr, na, nr);
    }
  }

  // One pass over the rows at x. Returns the residual norm (kHugeResidual if a residual or a
  // constant is not finite). With `jacobian`, also accumulates the Gram matrix gram = A'A of
  // A = [J | r] (rows x (n + 1)), block by block, without storing A.
  double pass(const Eigen::VectorXd& x, bool jacobian) {
    const int np = jac.numParameters();
    const int k = jac.numOutputs();
    const Eigen::Index nv = x.size();
    const size_t n = rows;
    const size_t nc = channels.size();
    plain_valid = false;
    bool ok = true;
    for (int p = 0; p < np; ++p) ok = ok && std::isfinite(static_cast<float>(x[p]));
    for (Eigen::Index v = np; v < nv; ++v) ok = ok && std::isfinite(x[v]);
    // The first residual pass of a fit with linear scaling reuses initialScales' values.
    const bool from_raw = raw_valid && !jacobian;
    raw_valid = false;
    if (jacobian) {
      gram.setZero(nv + 1, nv + 1);
      block_a.resize(nc * bs * (nv + 1));
    }
    if (!ok) {
      ++non_finite;
      return kHugeResidual;
    }
    if (!from_raw) {
      jac.setParameters(x.data());
      // A Jacobian pass computes, beside the values, one derivative column per constant for
      // every opcode that depends on it: up to the work of 1 + np forward passes, what a
      // finite-difference Jacobian would cost. The budget counts it so.
      evaluations += jacobian ? 1 + np : 1;
    }
    double sse = 0;
    for (size_t blk = 0; blk * bs < n; ++blk) {
      const size_t r0 = blk * bs;
      const int nr = static_cast<int>(std::min<size_t>(bs, n - r0));
      const int na = static_cast<int>(nc) * nr;  // rows of this block in A: channel-major
      if (!from_raw) jac.evalBlock(blk, jacobian);
      if (jacobian && projected) accumulateSums(r0, nr);
      const double* sw = sqrt_w.data() + r0;
      // Per output: g_o and q_o = sqrt(w) dg_o/ds_o (q_o = sqrt(w) without a transform).
      // Outputs alone in their channel get them fused into the residual loop below.
      for (int o = 0; o < k; ++o) {
        fv[o] = from_raw ? raw.data() + o * ds.paddedRows() + r0 : jac.value(o);
        q[o] = transforms[o] == TargetTransform::None ? sw : gp.data() + o * bs;
        if (alone[o]) continue;
        const double a = scaling ? x[np + 2 * o] : 1.0, b = scaling ? x[np + 2 * o + 1] : 0.0;
        withTransform(transforms[o], [&](auto tt) {
          const float* fo = fv[o];
          double* __restrict go = g.data() + o * bs;
          double* __restrict qo = gp.data() + o * bs;
#pragma omp simd
          for (int i = 0; i < nr; ++i) {
            double dg;
            inverse<decltype(tt)::value>(a * static_cast<double>(fo[i]) + b, go[i], dg);
            qo[i] = sw[i] * dg;
          }
        });
      }
      for (size_t c = 0; c < nc; ++c) {
        double* out = jacobian ? block_a.data() + nv * na + c * nr : res_block.data() + c * bs;
        const double* t = swy.data() + c * n + r0;
        const double* sc = scale.data() + c * n + r0;
        double* __restrict pl = plain.data() + c * n + r0;
        const auto& terms = channels[c];
        if (terms.size() == 1 && alone[terms[0].first]) {  // the common case: one loop
          const int o = terms[0].first;
          const double w = terms[0].second;
          const double a = scaling ? x[np + 2 * o] : 1.0, b = scaling ? x[np + 2 * o + 1] : 0.0;
          withTransform(transforms[o], [&](auto tt) {
            const float* fo = fv[o];
            double* __restrict qo = gp.data() + o * bs;
            double acc = 0;
#pragma omp simd reduction(+ : acc)
            for (int i = 0; i < nr; ++i) {
              double go, dg;
              inverse<decltype(tt)::value>(a * static_cast<double>(fo[i]) + b, go, dg);
              pl[i] = sw[i] * (w * go) - t[i];
              out[i] = pl[i] * sc[i];
              acc += out[i] * out[i];
              if constexpr (decltype(tt)::value != TargetTransform::None) qo[i] = sw[i] * dg;
            }
            sse += acc;
          });
          continue;
        }
        std::fill_n(out, nr, 0.0);
        for (const auto& [o, w] : terms) {
          const double* go = g.data() + o * bs;
#pragma omp simd
          for (int i = 0; i < nr; ++i) out[i] += w * go[i];
        }
#pragma omp simd reduction(+ : sse)
        for (int i = 0; i < nr; ++i) {
          pl[i] = sw[i] * out[i] - t[i];
          out[i] = pl[i] * sc[i];
          sse += out[i] * out[i];
        }
      }
      if (jacobian) jacobianBlock(x, r0, nr);
    }
    if (!std::isfinite(sse)) {
      ++non_finite;
      return kHugeResidual;
    }
    plain_valid = true;
    return std::sqrt(sse);
  }

  // Plain least squares: every residual at scale 1.
  void unweight() {
    if (weighted) std::fill(scale.begin(), scale.end(), 1.0);
    weighted = false;
    noise_floor = plain_noise_floor;
  }

  // The plain residuals (before reweighting) at `point`: at hand if the last pass was there,
  // else one residual pass. False if one is not finite.
  bool plainAtPoint() {
    if (plain_valid && plain_theta == point) return true;
    return evaluate(point, false) < kHugeResidual;
  }

  double plainSse() const {
    double sse = 0;
    for (double r : plain) sse += r * r;
    return sse;
  }

  // Sets `scale` (sqrt(u v), see levenberg_marquardt.hpp) from the plain residuals at the
  // current point, for round `round` (0: Lawson's weights start from 1).
  void reweight(int round) {
    const size_t n = rows, nc = channels.size();
    const double* w = ds.weight();
    if (round == 0) lawson.assign(nc * n, 1.0);
    err.resize(n);
    chan_err.assign(nc, 0.0);
    double wsum = 0;
#pragma omp simd reduction(+ : wsum)
    for (size_t r = 0; r < n; ++r) wsum += w[r];
    for (size_t c = 0; c < nc; ++c) {
      double* u = scale.data() + c * n;  // u first, sqrt(u v) below
      const double* y = chan_y.data() + c * n;
      double* __restrict e = err.data();
      const double* pl = plain.data() + c * n;
#pragma omp simd
      for (size_t r = 0; r < n; ++r) e[r] = sqrt_w[r] > 0 ? std::fabs(pl[r]) / sqrt_w[r] : 0.0;
      switch (cfg.metric) {
        case ErrorMetric::Rmse: {
          double sse = 0;
#pragma omp simd reduction(+ : sse)
          for (size_t r = 0; r < n; ++r) sse += w[r] * e[r] * e[r];
          chan_err[c] = std::sqrt(sse / wsum);
          std::fill_n(u, n, 1.0);
          break;
        }
        case ErrorMetric::Mae:
        case ErrorMetric::MeanRel: {
          const bool rel = cfg.metric == ErrorMetric::MeanRel;
          double sum = 0, bsum = 0;
#pragma omp simd reduction(+ : sum, bsum)
          for (size_t r = 0; r < n; ++r) {
            const double beta = rel ? 1.0 / std::max(std::fabs(y[r]), cfg.rel_floor) : 1.0;
            sum += w[r] * beta * e[r];
            bsum += w[r] * beta;
          }
          chan_err[c] = sum / wsum;
          // An exact fit (every error 0) keeps the rows' base weights.
          const double eps = sum > 0 ? kL1Eps * sum / bsum : 1.0;
#pragma omp simd
          for (size_t r = 0; r < n; ++r) {
            const double beta = rel ? 1.0 / std::max(std::fabs(y[r]), cfg.rel_floor) : 1.0;
            u[r] = beta / std::max(e[r], eps);
          }
          break;
        }
        case ErrorMetric::MaxAbs: {
          double* l = lawson.data() + c * n;
          double mx = 0, top = 0, sum = 0;
#pragma omp simd reduction(max : mx)
          for (size_t r = 0; r < n; ++r) mx = w[r] > 0 ? std::max(mx, e[r]) : mx;
          chan_err[c] = mx;
          const double inv = mx > 0 ? 1.0 / mx : 0.0;
#pragma omp simd reduction(max : top)
          for (size_t r = 0; r < n; ++r) {
            if (mx > 0) l[r] *= e[r] * inv;
            top = std::max(top, l[r]);
          }
#pragma omp simd reduction(+ : sum)
          for (size_t r = 0; r < n; ++r) {
            l[r] = std::max(l[r], kLawsonFloor * top);
            sum += w[r] * l[r];
          }
          const double norm = sum > 0 ? 1.0 / sum : 0.0;
#pragma omp simd
          for (size_t r = 0; r < n; ++r) {
            l[r] = sum > 0 ? l[r] * norm : 1.0;  // a probability over the rows
            u[r] = l[r];
          }
          break;
        }
      }
    }
    // Channel factors. The gradient of error_c is that of its surrogate times 1/error_c (rmse,
    // max_abs: the surrogate is error_c^2) or 1 (mae, mean_rel), so under Mean that factor,
    // capped. Under Max, the gradient of sum_c error_c^p, with p = 2, 4, 8, ... over the
    // rounds: a continuation from the sum of squares toward the worst channel alone, from
    // factors at the current point (Lawson's multiplicative update over a handful of channels
    // swings from one to the other).
    const bool squared = cfg.metric == ErrorMetric::Rmse || cfg.metric == ErrorMetric::MaxAbs;
    double worst = 0;
    for (double e : chan_err) worst = std::max(worst, e);
    for (size_t c = 0; c < nc; ++c) {
      double v = 1.0;
      if (nc > 1 && worst > 0) {
        const double rel = chan_err[c] / worst;
        if (cfg.combine == OutputCombine::Max) {
          const double p = std::ldexp(2.0, std::min(round, 5));
          v = std::max(std::pow(rel, p - (squared ? 2 : 1)), kLawsonFloor);
        } else if (squared) {
          v = 1.0 / std::max(rel, kChannelCap);
        }
      }
      double* u = scale.data() + c * n;
#pragma omp simd
      for (size_t r = 0; r < n; ++r) u[r] = std::sqrt(v * u[r]);
    }
    double sy2 = 0;
#pragma omp simd reduction(+ : sy2)
    for (size_t i = 0; i < nc * n; ++i) sy2 += (swy[i] * scale[i]) * (swy[i] * scale[i]);
    noise_floor = kNoiseFloor * sy2;
    weighted = true;
  }

  // One solver run from `point` on the current weights, at most `iterations` iterations.
  struct Run {
    bool started = false;
    double before = 0, after = 0;  // sum of squares (on the current weights)
    int iterations = 0;
    bool converged = false;
  };
  Run solve(int iterations, double tolerance) {
    Run run;
    lm.setXtol(kXtol);
    lm.setGtol(0.0);
    lm.setMaxfev(1 + kEvaluationsPerIteration * iterations);
    lm.setExternalScaling(projected);
    if (projected) lm.diag().setConstant(point.size(), std::numeric_limits<double>::min());
    auto status = lm.minimizeInit(point);
    if (status != Eigen::LevenbergMarquardtSpace::NotStarted || !(lm.fnorm() < kHugeResidual))
      return run;
    run.started = true;
    non_finite = 0;
    run.before = lm.fnorm() * lm.fnorm();
    double sse = run.before;
    while (run.iterations < iterations) {
      // Eigen's ftol is relative to the current sum of squares; raise it to the noise floor.
      lm.setFtol(std::max(tolerance, sse > 0 ? noise_floor / sse : 0.0));
      status = lm.minimizeOneStep(point);
      ++run.iterations;
      const double prev = sse;
      sse = lm.fnorm() * lm.fnorm();
      if (status != Eigen::LevenbergMarquardtSpace::Running) {
        using namespace Eigen::LevenbergMarquardtSpace;
        run.converged = status != TooManyFunctionEvaluation && status != ImproperInputParameters &&
                        status != UserAsked;
        break;
      }
      if (prev - sse <= std::max(tolerance * prev, noise_floor)) {
        run.converged = true;
        break;
      }
    }
    // Accepted steps always lower the norm, so fnorm() is the sum at `point`, evaluated with
    // its float constants, and finite.
    run.after = sse;
    return run;
  }

  Scorer& judge() {
    if (!scorer) scorer = std::make_unique<Scorer>(ds, cfg, ds.blockSize());
    return *scorer;
  }

  // Columns of A = [J | r] that can be nonzero in channel c's rows (ascending; the residual
  // last): a channel sees only the constants and scales of its outputs.
  void findActiveColumns(Eigen::Index nvars) {
    const int np = jac.numParameters();
    active.assign(channels.size(), {});
    for (size_t c = 0; c < channels.size(); ++c) {
      for (Eigen::Index v = 0; v < nvars; ++v) {
        bool on = false;
        for (const auto& [o, w] : channels[c])
          on = on || (v < np ? jac.hasDerivative(o, static_cast<int>(v)) : (v - np) / 2 == o);
        if (on) active[c].push_back(static_cast<int>(v));
      }
      active[c].push_back(static_cast<int>(nvars));
    }
  }

  // gram += S'S for one channel's rows of a block, S = the active columns of A there (column
  // v starts at a0 + v * na and has nr rows). A column whose squared norm is not finite (a
  // derivative overflowed float: rsqrt near kMinPos, say) counts as flat.
  void accumulateGram(const std::vector<int>& act, const double* a0, int na, int nr) {
    const int m = static_cast<int>(act.size());
    col_ptr.resize(m);
    for (int p = 0; p < m; ++p) col_ptr[p] = a0 + static_cast<size_t>(act[p]) * na;
    seg_gram.resize(m, m);
    for (int p = 0; p < m; ++p) {
      const double* cu = col_ptr[p];
      int t = p;
      for (; t + 3 < m; t += 4) {  // four products per load of cu, four independent sums
        const double *c0 = col_ptr[t], *c1 = col_ptr[t + 1], *c2 = col_ptr[t + 2],
                     *c3 = col_ptr[t + 3];
        double s0 = 0, s1 = 0, s2 = 0, s3 = 0;
#pragma omp simd reduction(+ : s0, s1, s2, s3)
        for (int i = 0; i < nr; ++i) {
          s0 = fmadd(cu[i], c0[i], s0);
          s1 = fmadd(cu[i], c1[i], s1);
          s2 = fmadd(cu[i], c2[i], s2);
          s3 = fmadd(cu[i], c3[i], s3);
        }
        seg_gram(p, t) = s0;
        seg_gram(p, t + 1) = s1;
        seg_gram(p, t + 2) = s2;
        seg_gram(p, t + 3) = s3;
      }
      for (; t + 1 < m; t += 2) {
        const double *c0 = col_ptr[t], *c1 = col_ptr[t + 1];
        double s0 = 0, s1 = 0;
#pragma omp simd reduction(+ : s0, s1)
        for (int i = 0; i < nr; ++i) {
          s0 = fmadd(cu[i], c0[i], s0);
          s1 = fmadd(cu[i], c1[i], s1);
        }
        seg_gram(p, t) = s0;
        seg_gram(p, t + 1) = s1;
      }
      if (t < m) {
        const double* c0 = col_ptr[t];
        double s0 = 0;
#pragma omp simd reduction(+ : s0)
        for (int i = 0; i < nr; ++i) s0 = fmadd(cu[i], c0[i], s0);
        seg_gram(p, t) = s0;
      }
    }
    for (int p = 0; p < m; ++p) {
      if (std::isfinite(seg_gram(p, p))) continue;
      for (int t = 0; t < m; ++t) seg_gram(std::min(p, t), std::max(p, t)) = 0.0;
    }
    for (int p = 0; p < m; ++p)
      for (int t = p; t < m; ++t)
        gram(act[p], act[t]) += std::isfinite(seg_gram(p, t)) ? seg_gram(p, t) : 0.0;
  }

  // Hands the solver an (n + 1) x n Jacobian and residual with the same linear least-squares
  // model as [J | r] (the same J'J, J'r and |r|), so the same steps, at O(n^2) cost per solver
  // step instead of O(rows n^2) (as MINPACK's lmstr keeps only an n x n factor; More, Garbow &
  // Hillstrom 1980). With J'J = V D V': Jc = [D^1/2 V'; 0], rc = [D^-1/2 V' J'r; d]. Eigenvalues
  // below kRankTolerance * max are null directions (J is float32: those are noise). d, beside
  // the zero last row of Jc, only completes the norm: the solver's QR never mixes it in.
  void compress(Eigen::MatrixXd& jc, Eigen::VectorXd& rc) {
    const Eigen::Index nv = gram.rows() - 1;
    const Eigen::MatrixXd jtj = gram.topLeftCorner(nv, nv).selfadjointView<Eigen::Upper>();
    eig.compute(jtj);
    const Eigen::VectorXd& lambda = eig.eigenvalues();
    const Eigen::MatrixXd& vecs = eig.eigenvectors();
    const double floor = kRankTolerance * std::max(lambda.maxCoeff(), 0.0);
    const Eigen::VectorXd vtg = vecs.transpose() * gram.col(nv).head(nv);
    jc.setZero(nv + 1, nv);
    rc.setZero(nv + 1);
    double head2 = 0;
    for (Eigen::Index i = 0; i < nv; ++i) {
      if (!(lambda[i] > floor) || lambda[i] <= 0) continue;
      const double s = std::sqrt(lambda[i]);
      jc.row(i) = s * vecs.col(i).transpose();
      rc[i] = vtg[i] / s;
      head2 += rc[i] * rc[i];
    }
    rc[nv] = std::sqrt(std::max(gram(nv, nv) - head2, 0.0));
  }

  const Dataset& ds;
  ErrorConfig cfg;
  JacobianEvaluator jac;
  std::vector<TargetTransform> transforms;
  bool scaling = false;
  size_t rows = 0;
  int bs = 0;
  std::vector<std::vector<std::pair<int, double>>> channels;  // (output, weight), nonzero
  std::vector<double> sqrt_w;                                 // per real row
  std::vector<double> swy;          // [channel * rows + r]: sqrt(w) * channel target
  std::vector<double> fit_target;   // linear scaling: T_o(y) per output, padded rows
  std::vector<double> fit_centred;  // linear scaling: T_o(y) - t_mean[o], padded rows
  std::vector<double> t_mean;       // linear scaling: weighted mean of T_o(y)
  bool projected = false;           // the scales are projected out (see evaluate())
  Eigen::VectorXd xe;               // projected: [x | a_0 b_0 ...] of the last pass
  Eigen::VectorXd values_x;         // projected: the point whose values `raw` holds
  bool values_valid = false;
  std::vector<double> f_mean, f_ss;  // projected: per output, weighted mean and centred sum of
                                     // squares of f (0 where the scales do not move)
  std::vector<double> sums;          // projected: accumulateSums' [output][constant][3]
  Eigen::VectorXd ext_norm;          // projected: per constant, its Jacobian column's norm
                                     // before projection (the solver's step scaling)
  std::vector<float> raw;            // linear scaling: raw outputs of the starting constants
  bool raw_valid = false;            // raw holds the outputs at the point being evaluated
  std::vector<double> g, gp;         // per output, one block: g_o and q_o
  std::vector<double> res_block;     // per channel, one block: residuals of a trial pass
  std::vector<double> block_a;       // one block of A = [J | r], column-major, channel-major rows
  std::vector<std::vector<int>> active;  // per channel: columns of A that can be nonzero
  std::vector<const double*> q;          // per output: q_o of the current block
  std::vector<const float*> fv;          // per output: f_o of the current block
  std::vector<uint8_t> alone;            // per output: its channel's only output, used once
  std::vector<const double*> col_ptr;    // accumulateGram's columns
  Eigen::MatrixXd gram;                  // A'A (upper triangle), (n + 1) x (n + 1)
  Eigen::MatrixXd seg_gram;              // one channel segment's share of gram
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig;
  Eigen::Index num_vars = 0, num_res = 0;
  double noise_floor = 0;  // kNoiseFloor * sum(w y^2) over channels, reweighted
  double plain_noise_floor = 0;
  std::vector<double> chan_y;         // [channel * rows + r]: channel target
  std::vector<double> scale;          // [channel * rows + r]: reweighting of the residual (1: none)
  bool weighted = false;              // scale is not all 1
  std::vector<double> plain;          // [channel * rows + r]: residuals of the last pass, unscaled
  Eigen::VectorXd plain_theta;        // the solver's point of `plain`
  bool plain_valid = false;           // plain holds a finite pass at plain_theta
  std::vector<double> lawson;         // max_abs: Lawson's row weights, per channel a probability
  std::vector<double> err, chan_err;  // reweight's |e| of one channel, error per channel
  std::unique_ptr<Scorer> scorer;     // judges reweighted rounds
  int evaluations = 0, non_finite = 0;
  Eigen::VectorXd point;  // the solver's current point
  Functor functor;
  Eigen::LevenbergMarquardt<Functor> lm;
};

ConstantFitter::ConstantFitter(const Dataset& ds, const ErrorConfig& cfg)
    : impl_(std::make_unique<Impl>(ds, cfg)) {}
ConstantFitter::~ConstantFitter() = default;
ConstantFitter::ConstantFitter(ConstantFitter&&) noexcept = default;

LmPlan lmPlan(LmObjective o, const ErrorConfig& cfg, size_t channels) {
  bool transformed = false;
  for (TargetTransform t : cfg.transforms) transformed |= t != TargetTransform::None;
  const bool plain_is_error =
      cfg.metric == ErrorMetric::Rmse && channels == 1 && !(cfg.linear_scaling && transformed);
  LmPlan plan;
  // Auto is Configured without linear scaling and LeastSquares with it. Configured reweights
  // wherever plain least squares is not the error; under linear scaling of a transformed
  // output that is rounds of weight 1 with the scale projected out as the Scorer fits it.
  plan.rounds = o == LmObjective::Configured || (o == LmObjective::Auto && !cfg.linear_scaling);
  plan.rounds = plan.rounds && !plain_is_error;
  plan.fits_error = plan.rounds || plain_is_error;
  return plan;
}

bool ConstantFitter::reweights(const LevenbergMarquardtConfig& c) const {
  return lmPlan(c.objective, impl_->cfg, impl_->channels.size()).rounds;
}

ConstantFitResult ConstantFitter::fit(Program& p, const LevenbergMarquardtConfig& c) {
  Impl& m = *impl_;
  ConstantFitResult res;
  m.jac.bind(p, m.ds);
  const int np = m.jac.numParameters();
  if (np == 0) return res;
  const int k = m.jac.numOutputs();
  const bool rounds = reweights(c);
  m.projected = m.scaling && rounds;
  const Eigen::Index num_ext = np + (m.scaling ? 2 * k : 0);
  m.num_vars = m.projected ? np : num_ext;
  if (m.num_res <= num_ext || k != m.ds.numOutputs()) return res;
  m.evaluations = 0;
  m.non_finite = 0;
  m.plain_valid = false;
  m.values_valid = false;
  m.point.resize(m.num_vars);
  for (int i = 0; i < np; ++i) m.point[i] = p.constants[m.jac.parameters()[i]];
  m.findActiveColumns(num_ext);
  if (m.scaling && !m.projected) m.initialScales(m.point, np);
  auto adopt = [&](const Eigen::VectorXd& x) {
    for (int i = 0; i < np; ++i) p.constants[m.jac.parameters()[i]] = static_cast<float>(x[i]);
  };

  if (!rounds) {
    m.unweight();
    const Impl::Run run = m.solve(c.max_iterations, c.tolerance);
    res.evaluations = m.evaluations;
    if (!run.started) return res;
    res.iterations = run.iterations;
    res.converged = run.converged;
    res.non_finite = m.non_finite;
    res.sse_before = run.before;
    res.sse_after = run.before;
    if (run.after < run.before) {
      res.sse_after = run.after;
      res.improved = true;
      adopt(m.point);
    }
    return res;
  }

  // Reweighted rounds, each end point judged by the Scorer; the best one is kept.
  Scorer& judge = m.judge();
  Program work = p;
  res.error_before = judge.error(work);
  ++m.evaluations;
  double best_err = res.error_before;
  Eigen::VectorXd best = m.point;
  int non_finite = 0;
  if (!m.plainAtPoint()) {
    res.evaluations = m.evaluations;
    return res;
  }
  res.sse_before = m.plainSse();
  double best_sse = res.sse_before;
  int left = c.max_iterations;
  for (int round = 0; round < c.max_rounds && left > 0; ++round) {
    m.reweight(round);
    const Eigen::VectorXd from = m.point;
    const Impl::Run run = m.solve(std::min(left, kRoundIterations), c.tolerance);
    non_finite += m.non_finite;
    ++res.rounds;
    left -= run.iterations;
    res.iterations += run.iterations;
    bool better = false;
    // The round's step, halved while the Scorer does not take it: frozen weights overshoot
    // (they are the gradient at the round's start only).
    for (int h = 0; h <= kHalvings && run.started && run.after < run.before && !better; ++h) {
      if (h > 0) m.point = 0.5 * (from + m.point);
      adopt(m.point);
      work.constants = p.constants;
      const double e = judge.error(work);
      ++m.evaluations;
      better = e < best_err;
      if (better) {
        best_err = e;
        best = m.point;
      }
    }
    if (!better) {
      // No step, or one the Scorer does not take: the reweighting has reached what it can.
      res.converged = run.started && run.converged;
      break;
    }
    if (!m.plainAtPoint()) break;  // the next round's weights, and the sum of squares here
    best_sse = m.plainSse();
  }
  res.evaluations = m.evaluations;
  res.non_finite = non_finite;
  res.error_after = best_err;
  if (best_err < res.error_before) {
    res.improved = true;
    res.sse_after = best_sse;
    adopt(best);
  } else {
    res.error_after = res.error_before;
    res.sse_after = res.sse_before;
    adopt(best);  // the starting constants (a rejected round moved p's)
  }
  return res;
}

}  // namespace lgp
