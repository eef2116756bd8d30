#include "lgp/eval/objectives.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>

#include "lgp/eval/semantics.hpp"
#include "output_layer.hpp"

namespace lgp {

namespace {
constexpr std::string_view kTransformNames[] = {"none", "log", "sqrt", "rcp"};
constexpr std::string_view kCombineNames[] = {"mean", "max"};

template <class E, size_t N>
std::optional<E> fromNames(std::string_view s, const std::string_view (&names)[N]) {
  for (size_t i = 0; i < N; ++i)
    if (names[i] == s) return static_cast<E>(i);
  return std::nullopt;
}

}  // namespace

std::string_view toString(ErrorMetric m) {
  return metricInfo(m).name;
}
std::string_view toString(TargetTransform t) {
  return kTransformNames[static_cast<int>(t)];
}
std::string_view toString(OutputCombine c) {
  return kCombineNames[static_cast<int>(c)];
}
std::optional<ErrorMetric> errorMetricFromString(std::string_view s) {
  for (const auto& m : allMetrics())
    if (m.name == s) return m.metric;
  return std::nullopt;
}

OutputMetrics metricsOf(const double* p, const double* y, const double* w, size_t n,
                        double rel_floor) {
  OutputMetrics m;
  double sw = 0, swy = 0, sse = 0, sae = 0, srel = 0, mx = 0;
  for (size_t r = 0; r < n; ++r) {
    if (!std::isfinite(p[r])) return OutputMetrics{};
    const double wr = w ? w[r] : 1.0;
    const double d = p[r] - y[r];
    sw += wr;
    swy += wr * y[r];
    sse += wr * d * d;
    sae += wr * std::fabs(d);
    srel += wr * std::fabs(d) / std::max(std::fabs(y[r]), rel_floor);
    mx = std::max(mx, std::fabs(d));
  }
  if (sw <= 0) return m;
  const double mean = swy / sw;
  double ss = 0;
  for (size_t r = 0; r < n; ++r) ss += (w ? w[r] : 1.0) * (y[r] - mean) * (y[r] - mean);
  m.rmse = std::sqrt(sse / sw);
  m.max_abs = mx;
  m.mae = sae / sw;
  m.mean_rel = srel / sw;
  m.r2 = ss > 0 ? 1.0 - sse / ss : (sse == 0 ? 1.0 : 0.0);
  return m;
}
std::optional<TargetTransform> targetTransformFromString(std::string_view s) {
  return fromNames<TargetTransform>(s, kTransformNames);
}
std::optional<OutputCombine> outputCombineFromString(std::string_view s) {
  return fromNames<OutputCombine>(s, kCombineNames);
}

double applyTransform(TargetTransform t, double y) {
  switch (t) {
    case TargetTransform::None:
      return y;
    case TargetTransform::Log:
      return std::log(std::max(y, static_cast<double>(kMinPos)));
    case TargetTransform::Sqrt:
      return std::sqrt(std::max(y, 0.0));
    case TargetTransform::Rcp:
      return 1.0 / sem::guard(y);
  }
  return y;
}
double invertTransform(TargetTransform t, double v) {
  return detail::invertValue<double>(t, v);
}

Status checkErrorNumerics(const Table& t, const ErrorConfig& cfg) {
  if (auto s = t.validate(); !s) return s;
  const size_t n = t.rows();
  auto weight = [&](size_t r) { return t.weights.empty() ? 1.0 : t.weights[r]; };
  auto sums = [&](const std::string& what, const std::vector<double>& y) -> Status {
    double s1 = 0, s2 = 0;
    for (size_t r = 0; r < n; ++r) {
      s1 += weight(r) * std::fabs(y[r]);
      s2 += weight(r) * y[r] * y[r];
    }
    if (!std::isfinite(s1) || !std::isfinite(s2))
      return Status::error(what + ": the weighted sum of its " +
                           std::string(std::isfinite(s1) ? "squares" : "values") +
                           " overflows double: rescale the targets or the weights");
    return Status::ok();
  };
  // mean_rel weighs row r by w / max(|y|, rel_floor), in float32.
  auto relWeights = [&](const std::string& name, const std::vector<double>& y) -> Status {
    if (cfg.metric != ErrorMetric::MeanRel) return Status::ok();
    for (size_t r = 0; r < n; ++r) {
      const double rw = weight(r) / std::max(std::fabs(y[r]), cfg.rel_floor);
      if (!fitsFloat32(rw))
        return Status::error(name + ", row " + std::to_string(r + 1) +
                             ": the mean_rel weight w/max(|y|, rel_floor) = " + formatDouble(rw) +
                             " is beyond the float32 range: raise /objectives/rel_floor (" +
                             formatDouble(cfg.rel_floor) + ")");
    }
    return Status::ok();
  };
  for (size_t o = 0; o < t.numOutputs(); ++o) {
    const std::string name = "output '" + t.output_names[o] + "'";
    if (auto s = sums(name, t.outputs[o]); !s) return s;
    if (cfg.channels.empty())
      if (auto s = relWeights(name, t.outputs[o]); !s) return s;
    const TargetTransform tr =
        o < cfg.transforms.size() ? cfg.transforms[o] : TargetTransform::None;
    if (tr == TargetTransform::None) continue;
    std::vector<double> ty(n);
    for (size_t r = 0; r < n; ++r) {
      ty[r] = applyTransform(tr, t.outputs[o][r]);
      if (!std::isfinite(ty[r]))
        return Status::error(name + ", row " + std::to_string(r + 1) + ": its " +
                             std::string(toString(tr)) + " transform is not finite");
    }
    if (auto s = sums(name + " (" + std::string(toString(tr)) + ")", ty); !s) return s;
  }
  for (const auto& ch : cfg.channels) {
    const std::string name = "error channel '" + ch.name + "'";
    std::vector<double> y(n, 0.0);
    for (size_t r = 0; r < n; ++r) {
      for (size_t o = 0; o < t.numOutputs() && o < ch.weights.size(); ++o)
        if (ch.weights[o] != 0) y[r] += ch.weights[o] * t.outputs[o][r];
      if (!fitsFloat32(y[r]))
        return Status::error(name + ", row " + std::to_string(r + 1) + ": its target " +
                             formatDouble(y[r]) + " is beyond the float32 range (|v| <= " +
                             formatDouble(kTableValueMax) + "): rescale the channel weights");
    }
    if (auto s = sums(name, y); !s) return s;
    if (auto s = relWeights(name, y); !s) return s;
  }
  return Status::ok();
}

double float32ErrorFloor(const ErrorConfig& cfg, const Table& t) {
  constexpr double u = 0x1p-24;
  double total = 0, worst = 0;
  for (const auto& y : t.outputs) {
    double ss = 0, sa = 0, mx = 0;
    for (double v : y) {
      ss += v * v;
      sa += std::fabs(v);
      mx = std::max(mx, std::fabs(v));
    }
    const double n = std::max<double>(1, static_cast<double>(y.size()));
    double f = u;
    switch (cfg.metric) {
      case ErrorMetric::Rmse:
        f = u * std::sqrt(ss / n);
        break;
      case ErrorMetric::Mae:
        f = u * sa / n;
        break;
      case ErrorMetric::MaxAbs:
        f = u * mx;
        break;
      case ErrorMetric::MeanRel:
        break;
    }
    total += f;
    worst = std::max(worst, f);
  }
  if (t.outputs.empty()) return 0;
  return cfg.combine == OutputCombine::Max ? worst : total / static_cast<double>(t.outputs.size());
}

double fastErrorBound(ErrorMetric m, double reference, double max_abs_target, int block_size,
                      double rel_floor) {
  constexpr double u = 0x1p-24;
  const double tail = 8 * u * u * max_abs_target;
  switch (m) {
    case ErrorMetric::Rmse:
      return (block_size / 64.0 + 6) * u * reference + tail;
    case ErrorMetric::Mae:
      return (block_size / 32.0 + 8) * u * reference + tail;
    case ErrorMetric::MeanRel:
      return (block_size / 32.0 + 8) * u * reference + 8 * u * u +
             0x1p-148 * max_abs_target / rel_floor;
    case ErrorMetric::MaxAbs:
      return 3 * u * reference + tail;
  }
  return 0;
}

namespace {
using Acc = detail::ErrorAcc;
using Target = detail::ErrorTarget;

// MeanRel's row weights w / max(|y|, rel_floor) of a target column.
void fillRelWeights(Target& t, const double* w, size_t n, double rel_floor) {
  t.rel_w.resize(n);
  for (size_t r = 0; r < n; ++r)
    t.rel_w[r] = static_cast<float>(w[r] / std::max(std::fabs(t.y[r]), rel_floor));
}
}  // namespace

Scorer::Scorer(const Dataset& ds, ErrorConfig cfg, int block_size)
    : ds_(ds), cfg_(std::move(cfg)), interp_(block_size) {
  cfg_.transforms.resize(ds.numOutputs(), TargetTransform::None);
  pred_.resize(block_size);
  const_pred_.resize(block_size);
  const size_t n = ds.paddedRows();
  targets_.resize(ds.numOutputs());
  for (int o = 0; o < ds.numOutputs(); ++o) {
    targets_[o].col = &ds.split(o);
    targets_[o].y = ds.target(o);
    fillRelWeights(targets_[o], ds.weight(), n, cfg_.rel_floor);
  }
  genes_ = cfg_.linear_scaling ? std::max(1, cfg_.genes) : 1;
  if (buffered()) {
    raw_.assign(static_cast<size_t>(ds.numOutputs()) * genes_, std::vector<float>(n));
    model_.assign(ds.numOutputs(), nullptr);
    if (genes_ > 1) layer_.assign(ds.numOutputs(), std::vector<float>(n));
    chan_pred_.resize(block_size);
    if (cfg_.linear_scaling) {
      // T(y) is fixed: its weighted mean and centred values are computed once, not per fit.
      fit_mean_.assign(ds.numOutputs(), 0.0);
      fit_centred_.assign(ds.numOutputs(), std::vector<double>(n));
      const double* w = ds.weight();
      for (int o = 0; o < ds.numOutputs(); ++o) {
        auto& yc = fit_centred_[o];
        double sy = 0;
        for (size_t r = 0; r < n; ++r) {
          yc[r] = applyTransform(cfg_.transforms[o], ds.target(o)[r]);
          sy += w[r] * yc[r];
        }
        fit_mean_[o] = sy / ds.weightSum();
        for (size_t r = 0; r < n; ++r) yc[r] -= fit_mean_[o];
      }
    }
    for (auto& ch : cfg_.channels) {
      ch.weights.resize(ds.numOutputs(), 0.0);
      std::vector<double> t(n, 0.0);
      for (int o = 0; o < ds.numOutputs(); ++o)
        if (ch.weights[o] != 0)
          for (size_t r = 0; r < n; ++r) t[r] += ch.weights[o] * ds.target(o)[r];
      chan_cols_.emplace_back(t.data(), ds.weight(), ds.rows(), n);
      chan_target_.push_back(std::move(t));
    }
    chan_targets_.resize(cfg_.channels.size());
    for (size_t c = 0; c < cfg_.channels.size(); ++c) {
      chan_targets_[c].col = &chan_cols_[c];
      chan_targets_[c].y = chan_target_[c].data();
      fillRelWeights(chan_targets_[c], ds.weight(), n, cfg_.rel_floor);
    }
  }
  scales_.assign(static_cast<size_t>(ds.numOutputs()) * genes_, LinearScale{});
}

namespace {
// Every metric of one output from its sums over rows (r2 is left to the caller: it needs the
// total sum of squares).
OutputMetrics metricsFromAcc(const Acc& a, double weight_sum) {
  OutputMetrics m;
  m.rmse = std::sqrt(a.sse / weight_sum);
  m.max_abs = a.maxabs;
  m.mae = a.sae / weight_sum;
  m.mean_rel = a.srel / weight_sum;
  return m;
}

double pickMetric(const OutputMetrics& m, ErrorMetric metric) {
  return metricValue(m, metric);
}

// Combines per-output errors; a non-finite one makes the whole error +inf.
double combineValues(const std::vector<double>& errors, OutputCombine combine) {
  double combined = 0;
  for (double e : errors) {
    if (!std::isfinite(e)) return std::numeric_limits<double>::infinity();
    combined = combine == OutputCombine::Max ? std::max(combined, e) : combined + e;
  }
  if (combine == OutputCombine::Mean && !errors.empty()) combined /= errors.size();
  return combined;
}

// Which sums metric M needs (M < 0: all of them).
template <int M>
constexpr bool kNeedSse = M < 0 || M == static_cast<int>(ErrorMetric::Rmse);
template <int M>
constexpr bool kNeedSae = M < 0 || M == static_cast<int>(ErrorMetric::Mae);
template <int M>
constexpr bool kNeedRel = M < 0 || M == static_cast<int>(ErrorMetric::MeanRel);
template <int M>
constexpr bool kNeedMax = M < 0 || M == static_cast<int>(ErrorMetric::MaxAbs);

// One block in double: the fallback when a float partial sum is not finite.
template <int M>
void accumulateDouble(Acc& acc, const float* pred, const double* y, const double* w, int n,
                      double rel_floor) {
  double sse = 0, sae = 0, srel = 0, mx = 0;
  for (int i = 0; i < n; ++i) {
    const double d = static_cast<double>(pred[i]) - y[i];
    const double ad = std::fabs(d);
    if constexpr (kNeedSse<M>) sse += w[i] * d * d;
    if constexpr (kNeedSae<M>) sae += w[i] * ad;
    if constexpr (kNeedRel<M>) srel += w[i] * ad / std::max(std::fabs(y[i]), rel_floor);
    if constexpr (kNeedMax<M>) mx = std::max(mx, ad);
  }
  acc.sse += sse;
  acc.sae += sae;
  acc.srel += srel;
  acc.maxabs = std::max(acc.maxabs, mx);
}

// Eight float lanes as one value (GCC/Clang vector extension: an AVX register here, lowered to
// narrower registers on other targets), so that the lane layout and the summation order are
// fixed by the code, not left to the vectoriser. Four of them make the 32 lanes of a sum:
// enough independent chains to hide the add latency.
using V8 = float __attribute__((vector_size(32)));
using V8i = int32_t __attribute__((vector_size(32)));
constexpr int kVecs = 4;
constexpr int kLanes = 8 * kVecs;

inline V8 load8(const float* p) {
  V8 v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
inline V8 abs8(V8 v) {
  return reinterpret_cast<V8>(reinterpret_cast<V8i>(v) & 0x7fffffff);
}

// Folds the 32 lanes in a fixed tree: (v0 + v2) + (v1 + v3), then halves of the eight lanes.
inline float sumLanes(const V8* v) {
  const V8 a = (v[0] + v[2]) + (v[1] + v[3]);
  float b[4];
  for (int j = 0; j < 4; ++j) b[j] = a[j] + a[j + 4];
  return (b[0] + b[2]) + (b[1] + b[3]);
}
// The largest lane, NaN if any lane is NaN.
inline float maxLanes(const V8* v) {
  float m = v[0][0];
  bool nan = false;
  for (int k = 0; k < kVecs; ++k)
    for (int j = 0; j < 8; ++j) {
      nan |= v[k][j] != v[k][j];
      m = v[k][j] > m ? v[k][j] : m;
    }
  return nan ? std::numeric_limits<float>::quiet_NaN() : m;
}

// Accumulates the metrics selected by M over rows [off, off + n) of one block (n a multiple
// of 16). Differences are taken in float against the split target, d = (pred * s - hi) - lo:
// pred * s is exact, and pred * s - hi is exact whenever pred is within a factor 2 of y
// (Sterbenz), so the tiny error of a recovered formula survives. Weighted terms are summed in
// 32 float lanes (row r goes to lane r mod 32) in a fixed order, the same for every M
// (metrics() and error() agree to the last bit), and the block's sums go to the double
// totals. kUnit: every row of the block has weight 1 (no weight loads). A NaN or Inf
// prediction makes a sum non-finite (max is NaN-sticky), and only then is the block looked at
// again: non-finite predictions flag chk, otherwise float overflowed and the block is summed
// in double. Accuracy: fastErrorBound.
template <int M, bool kUnit>
[[gnu::always_inline]] inline void accumulate(Acc& acc, const float* pred, const Target& t,
                                              const float* wf, const double* wd, size_t off, int n,
                                              double rel_floor) {
  const float* hi = t.col->hi.data() + off;
  const float* lo = t.col->lo.data() + off;
  const float* rw = t.rel_w.data() + off;
  const float* w = wf + off;
  const float s = t.col->scale;
  V8 sse[kVecs] = {}, sae[kVecs] = {}, srel[kVecs] = {}, mx[kVecs] = {};
  auto rows8 = [&](int r, int k) {
    const V8 d = (load8(pred + r) * s - load8(hi + r)) - load8(lo + r);
    const V8 ad = abs8(d);
    if constexpr (kNeedSse<M>) sse[k] += kUnit ? d * d : load8(w + r) * (d * d);
    if constexpr (kNeedSae<M>) sae[k] += kUnit ? ad : load8(w + r) * ad;
    if constexpr (kNeedRel<M>) srel[k] += load8(rw + r) * ad;
    if constexpr (kNeedMax<M>) mx[k] = ((ad > mx[k]) | (ad != ad)) ? ad : mx[k];
  };
  int i = 0;
  for (; i + kLanes <= n; i += kLanes)
    for (int k = 0; k < kVecs; ++k) rows8(i + 8 * k, k);
  if (i < n) {  // a block of 16 * odd rows: 16 left (constant indices keep sums in registers)
    rows8(i, 0);
    rows8(i + 8, 1);
  }
  const float fsse = kNeedSse<M> ? sumLanes(sse) : 0.0f;
  const float fsae = kNeedSae<M> ? sumLanes(sae) : 0.0f;
  const float fsrel = kNeedRel<M> ? sumLanes(srel) : 0.0f;
  const float fmx = kNeedMax<M> ? maxLanes(mx) : 0.0f;
  const double inv = t.col->inv_scale;  // a power of two: exact
  Acc block{static_cast<double>(fsse) * (inv * inv), static_cast<double>(fsae) * inv,
            static_cast<double>(fsrel) * inv, static_cast<double>(fmx) * inv, 0.0f};
  if (!std::isfinite(fsse + fsae + fsrel + fmx)) {
    float chk = 0;
    for (int r = 0; r < n; ++r) chk += pred[r] * 0.0f;
    acc.chk += chk;
    if (!(chk == 0.0f)) return;
    // Only the sums that overflowed are replaced, so each sum is the same for every M.
    Acc d;
    accumulateDouble<M>(d, pred, t.y + off, wd + off, n, rel_floor);
    if (!std::isfinite(block.sse)) block.sse = d.sse;
    if (!std::isfinite(block.sae)) block.sae = d.sae;
    if (!std::isfinite(block.srel)) block.srel = d.srel;
    if (!std::isfinite(block.maxabs)) block.maxabs = d.maxabs;
  }
  acc.sse += block.sse;
  acc.sae += block.sae;
  acc.srel += block.srel;
  acc.maxabs = std::max(acc.maxabs, block.maxabs);
}

// Block `b` of an output or channel: the unit-weight loop where it applies.
template <int M>
[[gnu::always_inline]] inline void accumulateBlock(Acc& acc, const float* pred, const Target& t,
                                                   const Dataset& ds, size_t b, double rel_floor) {
  const int bs = ds.blockSize();
  const size_t off = b * bs;
  if (ds.unitWeights() && off + bs <= ds.rows())
    accumulate<M, true>(acc, pred, t, ds.weightF(), ds.weight(), off, bs, rel_floor);
  else
    accumulate<M, false>(acc, pred, t, ds.weightF(), ds.weight(), off, bs, rel_floor);
}

// The scale applied as the materialised opcode computes it (see applyLinearScaling).
void applyScale(const LinearScale& ls, float* v, size_t n) {
  switch (ls.op()) {
    case Op::Mul:
#pragma omp simd
      for (size_t r = 0; r < n; ++r) v[r] = v[r] * ls.a;
      break;
    case Op::Add:
#pragma omp simd
      for (size_t r = 0; r < n; ++r) v[r] = v[r] + ls.b;
      break;
    default:
#pragma omp simd
      for (size_t r = 0; r < n; ++r) v[r] = sem::apply<Op::Mad, float>(v[r], ls.a, ls.b, 0.0f);
      break;
  }
}

void invertInPlace(TargetTransform t, float* v, size_t n) {
  if (t == TargetTransform::None) return;
#pragma omp simd
  for (size_t r = 0; r < n; ++r) v[r] = detail::invertValue<float>(t, v[r]);
}

// a and b from the centred weighted sums; a = 0 (offset only) for a flat or degenerate f.
LinearScale scaleFromSums(double sw, double mf, double my, double sff, double sfy) {
  double a = sff > 1e-12 * sw * (1.0 + mf * mf) ? sfy / sff : 0.0;
  double b0 = my - a * mf;
  if (!std::isfinite(a) || !std::isfinite(b0) || std::fabs(a) > 1e30 || std::fabs(b0) > 1e30) {
    a = 0.0;
    b0 = std::isfinite(my) ? my : 0.0;
  }
  return LinearScale{static_cast<float>(a), static_cast<float>(b0)};
}
}  // namespace

template <int M>
void Scorer::run(const BoundProgram& bp, std::vector<detail::ErrorAcc>& accs) {
  const int bs = interp_.blockSize();
  const size_t nb = ds_.numBlocks();
  accs.assign(bp.output_slots.size(), Acc{});
  for (size_t b = 0; b < nb; ++b) {
    const auto& outs = interp_.evalBlock(bp, ds_, b);
    for (size_t o = 0; o < outs.size(); ++o) {
      const float* pred = outs[o];
      const TargetTransform t = cfg_.transforms[o];
      if (t != TargetTransform::None) {
        float* buf = pred_.data();
#pragma omp simd
        for (int i = 0; i < bs; ++i) buf[i] = detail::invertValue<float>(t, pred[i]);
        pred = buf;
      }
      accumulateBlock<M>(accs[o], pred, targets_[o], ds_, b, cfg_.rel_floor);
    }
  }
}

LinearScale Scorer::fitScale(const float* v, int o) const {
  // Centred two-pass least squares for accuracy, in double; fixed lanes so that it vectorises
  // and stays deterministic.
  constexpr int L = 8;
  const size_t n = ds_.paddedRows();  // a multiple of 16
  const double* w = ds_.weight();
  const double* yc = fit_centred_[o].data();
  const double sw = ds_.weightSum();
  double sf[L] = {};
  for (size_t r = 0; r < n; r += L)
#pragma omp simd
    for (int j = 0; j < L; ++j) sf[j] += w[r + j] * v[r + j];
  double tf = 0;
  for (int j = 0; j < L; ++j) tf += sf[j];
  const double mf = tf / sw;
  double sff[L] = {}, sfy[L] = {};
  for (size_t r = 0; r < n; r += L)
#pragma omp simd
    for (int j = 0; j < L; ++j) {
      const double df = v[r + j] - mf;
      sff[j] += w[r + j] * df * df;
      sfy[j] += w[r + j] * df * yc[r + j];
    }
  double tff = 0, tfy = 0;
  for (int j = 0; j < L; ++j) {
    tff += sff[j];
    tfy += sfy[j];
  }
  return scaleFromSums(sw, mf, fit_mean_[o], tff, tfy);
}

namespace {
// sum_r w_r (f_r - mf) (g_r - mg) over n rows (a multiple of 8), in fixed lanes (vectorised,
// deterministic).
template <class G>
double centredDot(const double* w, const float* f, double mf, const G* g, double mg, size_t n) {
  constexpr int L = 8;
  double acc[L] = {};
  for (size_t r = 0; r < n; r += L)
#pragma omp simd
    for (int j = 0; j < L; ++j)
      acc[j] += w[r + j] * (f[r + j] - mf) * (static_cast<double>(g[r + j]) - mg);
  double t = 0;
  for (int j = 0; j < L; ++j) t += acc[j];
  return t;
}
// A gene is dropped when what it adds beyond the genes before it has less than this share of
// its own variance: its coefficient would be large and cancel against theirs, which float32
// cannot carry (fidelity.hpp).
constexpr double kCollinear = 1e-8;
}  // namespace

void Scorer::fitLayer(int o) {
  const int G = genes_;
  const size_t n = ds_.paddedRows();
  const double* w = ds_.weight();
  const double sw = ds_.weightSum();
  const double my = fit_mean_[o];
  // Weighted means, then the centred normal equations C a = c.
  std::vector<double>& gm = gram_;
  gm.assign(static_cast<size_t>(G) * (G + 3), 0.0);
  double* mean = gm.data();
  double* c = mean + G;
  double* C = c + G;  // G x G, lower triangle used; becomes the Cholesky factor
  for (int g = 0; g < G; ++g) {
    const float* f = raw_[o * G + g].data();
    double acc[8] = {};
    for (size_t r = 0; r < n; r += 8)
#pragma omp simd
      for (int j = 0; j < 8; ++j) acc[j] += w[r + j] * f[r + j];
    double t = 0;
    for (double v : acc) t += v;
    mean[g] = t / sw;
  }
  for (int g = 0; g < G; ++g) {
    const float* fg = raw_[o * G + g].data();
    c[g] = centredDot(w, fg, mean[g], fit_centred_[o].data(), 0.0, n);
    for (int h = 0; h <= g; ++h)
      C[g * G + h] = centredDot(w, fg, mean[g], raw_[o * G + h].data(), mean[h], n);
  }
  // Cholesky in gene order, keeping only genes that are neither flat (scaleFromSums's guard)
  // nor collinear with the kept ones; dropped genes get a = 0.
  std::vector<int> kept;
  kept.reserve(G);
  for (int g = 0; g < G; ++g) {
    const double var = C[g * G + g];
    if (!(var > 1e-12 * sw * (1.0 + mean[g] * mean[g]))) continue;
    double d = var;
    for (size_t i = 0; i < kept.size(); ++i) {
      const int j = kept[i];
      double v = C[g * G + j];
      for (size_t q = 0; q < i; ++q) v -= C[g * G + kept[q]] * C[j * G + kept[q]];
      v /= C[j * G + j];
      C[g * G + j] = v;
      d -= v * v;
    }
    if (!(d > kCollinear * var)) continue;
    C[g * G + g] = std::sqrt(d);
    kept.push_back(g);
  }
  // L L' a = c on the kept genes.
  const size_t m = kept.size();
  std::vector<double> a(G, 0.0), z(m);
  for (size_t i = 0; i < m; ++i) {
    const int g = kept[i];
    double v = c[g];
    for (size_t q = 0; q < i; ++q) v -= C[g * G + kept[q]] * z[q];
    z[i] = v / C[g * G + g];
  }
  for (size_t i = m; i-- > 0;) {
    const int g = kept[i];
    double v = z[i];
    for (size_t q = i + 1; q < m; ++q) v -= C[kept[q] * G + g] * a[kept[q]];
    a[g] = v / C[g * G + g];
  }
  // The offset with the coefficients as float32 carries them; the guards of scaleFromSums.
  bool ok = true;
  double b = my;
  for (int g = 0; g < G; ++g) {
    const float af = static_cast<float>(a[g]);
    ok = ok && std::isfinite(a[g]) && std::fabs(a[g]) <= 1e30 && std::isfinite(af);
    b -= static_cast<double>(af) * mean[g];
  }
  ok = ok && std::isfinite(b) && std::fabs(b) <= 1e30;
  LinearScale* s = &scales_[static_cast<size_t>(o) * G];
  for (int g = 0; g < G; ++g) s[g] = LinearScale{ok ? static_cast<float>(a[g]) : 0.0f, 0.0f};
  if (!ok) b = std::isfinite(my) ? my : 0.0;
  s[detail::leadGene(s, G)].b = static_cast<float>(b);
}

template <int M>
bool Scorer::runBuffered(const BoundProgram& bp, bool scale, std::vector<detail::ErrorAcc>& accs) {
  const int bs = interp_.blockSize();
  const size_t nb = ds_.numBlocks();
  const size_t n = ds_.paddedRows();
  const int raw = static_cast<int>(bp.output_slots.size());
  const int G = scale ? genes_ : 1;  // metrics of a final program: its outputs as they are
  const int k = raw / G;
  for (size_t b = 0; b < nb; ++b) {
    const auto& outs = interp_.evalBlock(bp, ds_, b);
    for (int o = 0; o < raw; ++o) std::memcpy(raw_[o].data() + b * bs, outs[o], bs * sizeof(float));
  }
  // Reset first: a program that fails below must not leave the scales (and so the cost) of
  // whatever this Scorer measured before.
  std::fill(scales_.begin(), scales_.end(), LinearScale{});
  for (int o = 0; o < raw; ++o) {
    const float* v = raw_[o].data();
    float chk = 0;
#pragma omp simd reduction(+ : chk)
    for (size_t r = 0; r < n; ++r) chk += v[r] * 0.0f;
    if (!(chk == 0.0f)) return false;
  }
  for (int o = 0; o < k; ++o) {
    float* v = raw_[o].data();
    if (scale && G > 1) {
      fitLayer(o);
      const float* genes[kMaxGenes];
      for (int g = 0; g < G; ++g) genes[g] = raw_[o * G + g].data();
      v = layer_[o].data();
      detail::applyLayer<float>(&scales_[static_cast<size_t>(o) * G], G, genes, v, n);
    } else if (scale) {
      scales_[o] = fitScale(v, o);
      applyScale(scales_[o], v, n);
    }
    invertInPlace(cfg_.transforms[o], v, n);
    model_[o] = v;
  }
  if (cfg_.channels.empty()) {
    accs.assign(k, Acc{});
    for (int o = 0; o < k; ++o)
      for (size_t b = 0; b < nb; ++b)
        accumulateBlock<M>(accs[o], model_[o] + b * bs, targets_[o], ds_, b, cfg_.rel_floor);
    return true;
  }
  accs.assign(cfg_.channels.size(), Acc{});
  for (size_t c = 0; c < cfg_.channels.size(); ++c) {
    const auto& wt = cfg_.channels[c].weights;
    for (size_t b = 0; b < nb; ++b) {
      const size_t off = b * bs;
      float* cp = chan_pred_.data();
      std::fill(cp, cp + bs, 0.0f);
      for (int o = 0; o < k; ++o) {
        if (wt[o] == 0) continue;
        const float wo = static_cast<float>(wt[o]);
        const float* v = model_[o] + off;
#pragma omp simd
        for (int i = 0; i < bs; ++i) cp[i] += wo * v[i];
      }
      accumulateBlock<M>(accs[c], cp, chan_targets_[c], ds_, b, cfg_.rel_floor);
    }
  }
  return true;
}

template <int M>
bool Scorer::runConstant(const BoundProgram& bp, bool buffered, bool scale,
                         std::vector<detail::ErrorAcc>& accs) {
  // Every row computes the same value (the kernels are bit-identical row by row), so one
  // 16-row slice gives it; the steps below repeat the full path's on that one value.
  const auto& outs = interp_.evalBlock(bp, ds_, 0, 16);
  const int G = scale ? genes_ : 1;
  const int k = static_cast<int>(outs.size()) / G;
  const_vals_.resize(k);
  if (buffered) std::fill(scales_.begin(), scales_.end(), LinearScale{});
  if (buffered)
    for (const float* v : outs)
      if (!(v[0] * 0.0f == 0.0f)) return false;
  for (int o = 0; o < k; ++o) {
    float v = outs[o * G][0];
    if (buffered && scale) {
      // The fit of constant genes: sff = 0, so a = 0 and b = the weighted mean of T(y), exactly
      // what fitScale and fitLayer compute for flat columns; later genes weigh nothing.
      LinearScale* sc = &scales_[static_cast<size_t>(o) * G];
      sc[0] = scaleFromSums(ds_.weightSum(), v, fit_mean_[o], 0.0, 0.0);
      for (int g = 1; g < G; ++g) sc[g] = LinearScale{0.0f, 0.0f};
      applyScale(sc[0], &v, 1);
    }
    invertInPlace(cfg_.transforms[o], &v, 1);
    const_vals_[o] = v;
  }
  const bool channels = buffered && !cfg_.channels.empty();
  const size_t nt = channels ? cfg_.channels.size() : static_cast<size_t>(k);
  accs.assign(nt, Acc{});
  const double ws = ds_.weightSum();
  for (size_t c = 0; c < nt; ++c) {
    float p = const_vals_[c];
    const Target* t = &targets_[c];
    if (channels) {
      const auto& wt = cfg_.channels[c].weights;
      p = 0.0f;
      for (int o = 0; o < k; ++o)
        if (wt[o] != 0) p += static_cast<float>(wt[o]) * const_vals_[o];
      t = &chan_targets_[c];
    }
    Acc& a = accs[c];
    a.chk = p * 0.0f;
    if (!(a.chk == 0.0f)) continue;
    if constexpr (kNeedSae<M> || kNeedRel<M>) {
      // No closed form: the full path's accumulation over a broadcast column (same result).
      std::fill(const_pred_.begin(), const_pred_.end(), p);
      for (size_t b = 0; b < ds_.numBlocks(); ++b)
        accumulateBlock<M>(a, const_pred_.data(), *t, ds_, b, cfg_.rel_floor);
    }
    // sum w (p - y)^2 = W (p - mean)^2 + SS_tot; max |p - y| is at the target's min or max.
    const SplitColumn& col = *t->col;
    const double pd = p;
    if constexpr (kNeedSse<M>) a.sse = ws * (pd - col.mean) * (pd - col.mean) + col.ss_tot;
    if constexpr (kNeedMax<M>)
      a.maxabs = std::max(std::fabs(pd - col.min), std::fabs(pd - col.max));
  }
  return true;
}

template <int M>
bool Scorer::measure(const BoundProgram& bp) {
  if (bp.constant) return runConstant<M>(bp, buffered(), cfg_.linear_scaling, acc_);
  if (buffered()) return runBuffered<M>(bp, cfg_.linear_scaling, acc_);
  run<M>(bp, acc_);
  return true;
}

double Scorer::error(const Program& p) {
  bound_.bind(p, ds_.numInputs());
  return error(bound_);
}

double Scorer::error(const BoundProgram& bp) {
  // A program of another shape (one gene where the layer wants several) would leave outputs
  // unscored: its error would read as 0.
  if (bp.output_slots.size() != static_cast<size_t>(ds_.numOutputs()) * genes_)
    return std::numeric_limits<double>::infinity();
  bool ok = false;
  switch (cfg_.metric) {
    case ErrorMetric::Rmse:
      ok = measure<static_cast<int>(ErrorMetric::Rmse)>(bp);
      break;
    case ErrorMetric::MaxAbs:
      ok = measure<static_cast<int>(ErrorMetric::MaxAbs)>(bp);
      break;
    case ErrorMetric::Mae:
      ok = measure<static_cast<int>(ErrorMetric::Mae)>(bp);
      break;
    case ErrorMetric::MeanRel:
      ok = measure<static_cast<int>(ErrorMetric::MeanRel)>(bp);
      break;
  }
  if (!ok) return std::numeric_limits<double>::infinity();
  errors_.clear();
  for (const detail::ErrorAcc& a : acc_) {
    if (!(a.chk == 0.0f)) return std::numeric_limits<double>::infinity();
    errors_.push_back(pickMetric(metricsFromAcc(a, ds_.weightSum()), cfg_.metric));
  }
  const double e = combineValues(errors_, cfg_.combine);
  if (fidelity_ && e < std::numeric_limits<double>::infinity() &&
      !fidelity_->passes(bp, cfg_.linear_scaling ? scales_ : std::vector<LinearScale>{})) {
    ++fidelity_rejects_;
    return std::numeric_limits<double>::infinity();
  }
  return e;
}

std::vector<OutputMetrics> Scorer::metrics(const Program& p) {
  bound_.bind(p, ds_.numInputs());
  if (bound_.constant)
    runConstant<-1>(bound_, false, false, acc_);
  else
    run<-1>(bound_, acc_);
  std::vector<OutputMetrics> out(acc_.size());
  const double ws = ds_.weightSum();
  for (size_t o = 0; o < acc_.size(); ++o) {
    const detail::ErrorAcc& a = acc_[o];
    if (!(a.chk == 0.0f)) continue;  // stays at the worst values
    out[o] = metricsFromAcc(a, ws);
    const double ss = targets_[o].col->ss_tot;
    out[o].r2 = ss > 0 ? 1.0 - a.sse / ss : (a.sse == 0 ? 1.0 : 0.0);
  }
  return out;
}

std::vector<OutputMetrics> Scorer::channelMetrics(const Program& p) {
  if (cfg_.channels.empty()) return metrics(p);
  bound_.bind(p, ds_.numInputs());
  std::vector<OutputMetrics> out(cfg_.channels.size());
  const bool ok = bound_.constant ? runConstant<-1>(bound_, true, false, acc_)
                                  : runBuffered<-1>(bound_, false, acc_);
  if (!ok) return out;
  for (size_t c = 0; c < acc_.size(); ++c) {
    if (!(acc_[c].chk == 0.0f)) continue;
    out[c] = metricsFromAcc(acc_[c], ds_.weightSum());
    const double ss = chan_cols_[c].ss_tot;
    out[c].r2 = ss > 0 ? 1.0 - acc_[c].sse / ss : (acc_[c].sse == 0 ? 1.0 : 0.0);
  }
  return out;
}

Program applyLinearScaling(const Program& p, const std::vector<LinearScale>& scales, int genes) {
  Program q = p;
  const int G = std::max(1, genes);
  const size_t k = p.outputs.size() / G;
  auto append = [&](Op op, Operand x, std::initializer_list<float> ks, Operand tail) {
    Instr in;
    in.op = op;
    in.args[0] = x;
    int a = 1;
    for (float v : ks) {
      in.args[a++] = constOperand(static_cast<int>(q.constants.size()));
      q.constants.push_back(v);
    }
    if (tail.kind == OperandKind::Reg) in.args[a] = tail;
    q.code.push_back(in);
    return regOperand(static_cast<int>(q.code.size() - 1));
  };
  std::vector<uint8_t> outs(k);
  for (size_t o = 0; o < k; ++o) {
    const size_t first = o * G;
    if (first + G > scales.size()) {
      outs[o] = p.outputs[first];
      continue;
    }
    const LinearScale* s = &scales[first];
    const int lead = detail::leadGene(s, G);
    Operand cur = regOperand(p.outputs[first + lead]);
    const Operand none{OperandKind::Var, 0};
    // mul(f, a), add(f, b) or mad(f, a, b): the constants in operand order.
    const LinearScale ls = s[lead];
    if (!ls.identity())
      cur = ls.op() == Op::Mul   ? append(Op::Mul, cur, {ls.a}, none)
            : ls.op() == Op::Add ? append(Op::Add, cur, {ls.b}, none)
                                 : append(Op::Mad, cur, {ls.a, ls.b}, none);
    for (int g = lead + 1; g < G; ++g)
      if (s[g].a != 0.0f) cur = append(Op::Mad, regOperand(p.outputs[first + g]), {s[g].a}, cur);
    outs[o] = cur.index;
  }
  q.outputs = std::move(outs);
  return q;
}

namespace {
// Every metric of one series of double predictions against y (the reference path).
OutputMetrics seriesMetrics(const std::vector<double>& v, const std::vector<double>& y,
                            const std::vector<double>& weights, double rel_floor) {
  return metricsOf(v.data(), y.data(), weights.empty() ? nullptr : weights.data(), v.size(),
                   rel_floor);
}

// The reference evaluator's outputs, mapped back through the inverse transforms.
std::vector<std::vector<double>> referencePredictions(const Program& p, const Table& t,
                                                      const ErrorConfig& cfg) {
  auto pred = evaluateReference(p, t);
  for (size_t o = 0; o < pred.size(); ++o) {
    const TargetTransform tr =
        o < cfg.transforms.size() ? cfg.transforms[o] : TargetTransform::None;
    for (double& v : pred[o]) v = detail::invertValue<double>(tr, v);
  }
  return pred;
}
}  // namespace

std::vector<OutputMetrics> referenceChannelMetrics(const Program& p, const Table& t,
                                                   const ErrorConfig& cfg) {
  if (cfg.channels.empty()) return referenceMetrics(p, t, cfg);
  const auto v = referencePredictions(p, t, cfg);
  const size_t n = t.rows();
  std::vector<OutputMetrics> out;
  for (const auto& ch : cfg.channels) {
    std::vector<double> pv(n, 0.0), y(n, 0.0);
    for (size_t r = 0; r < n; ++r)
      for (size_t o = 0; o < v.size() && o < ch.weights.size(); ++o) {
        if (ch.weights[o] == 0) continue;
        pv[r] += ch.weights[o] * v[o][r];
        y[r] += ch.weights[o] * t.outputs[o][r];
      }
    out.push_back(seriesMetrics(pv, y, t.weights, cfg.rel_floor));
  }
  return out;
}

std::vector<std::string> channelNames(const ErrorConfig& cfg,
                                      const std::vector<std::string>& output_names) {
  if (cfg.channels.empty()) return output_names;
  std::vector<std::string> names;
  for (const auto& c : cfg.channels) names.push_back(c.name);
  return names;
}

std::vector<OutputMetrics> referenceMetrics(const Program& p, const Table& t,
                                            const ErrorConfig& cfg) {
  const auto v = referencePredictions(p, t, cfg);
  std::vector<OutputMetrics> out;
  for (size_t o = 0; o < v.size(); ++o)
    out.push_back(seriesMetrics(v[o], t.outputs[o], t.weights, cfg.rel_floor));
  return out;
}

double combineError(const std::vector<OutputMetrics>& m, const ErrorConfig& cfg) {
  std::vector<double> errors;
  for (const auto& om : m) errors.push_back(pickMetric(om, cfg.metric));
  return combineValues(errors, cfg.combine);
}

}  // namespace lgp
