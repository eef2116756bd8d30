#include "lgp/eval/objectives.hpp"

#include <algorithm>
#include <cmath>

#include "lgp/eval/semantics.hpp"

namespace lgp {

namespace {
constexpr std::string_view kMetricNames[] = {"rmse", "max_abs", "mae", "mean_rel"};
constexpr std::string_view kTransformNames[] = {"none", "log", "sqrt", "rcp"};
constexpr std::string_view kCombineNames[] = {"mean", "max"};

template <class E, size_t N>
std::optional<E> fromNames(std::string_view s, const std::string_view (&names)[N]) {
  for (size_t i = 0; i < N; ++i)
    if (names[i] == s) return static_cast<E>(i);
  return std::nullopt;
}

// Inverse transform with the operators' protected semantics, in T precision.
template <class T>
inline T invert(TargetTransform t, T v) {
  switch (t) {
    case TargetTransform::None:
      return v;
    case TargetTransform::Log:
      return sem::apply<Op::Exp, T>(v, v, v, v);
    case TargetTransform::Sqrt:
      return v > T(0) ? v * v : T(0);
    case TargetTransform::Rcp:
      return sem::apply<Op::Rcp, T>(v, v, v, v);
  }
  return v;
}
}  // namespace

std::string_view toString(ErrorMetric m) {
  return kMetricNames[static_cast<int>(m)];
}
std::string_view toString(TargetTransform t) {
  return kTransformNames[static_cast<int>(t)];
}
std::string_view toString(OutputCombine c) {
  return kCombineNames[static_cast<int>(c)];
}
std::optional<ErrorMetric> errorMetricFromString(std::string_view s) {
  return fromNames<ErrorMetric>(s, kMetricNames);
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
  return invert<double>(t, v);
}

CostModel CostModel::preset(CostTarget t) {
  CostModel m;
  m.target = t;
  for (const auto& i : allOps()) m.cost[static_cast<int>(i.op)] = i.cost[static_cast<int>(t)];
  return m;
}

double CostModel::programCost(const Program& p) const {
  return programCost(p, effectiveIndices(p));
}

double CostModel::programCost(const Program& p, const std::vector<int>& effective) const {
  double c = 0;
  for (int i : effective) c += cost[static_cast<int>(p.code[i].op)];
  return c;
}

double CostModel::transformCost(const std::vector<TargetTransform>& ts) const {
  double c = 0;
  for (auto t : ts) {
    switch (t) {
      case TargetTransform::None:
        break;
      case TargetTransform::Log:
        c += cost[static_cast<int>(Op::Exp)];
        break;
      case TargetTransform::Sqrt:
        c += cost[static_cast<int>(Op::Square)];
        break;
      case TargetTransform::Rcp:
        c += cost[static_cast<int>(Op::Rcp)];
        break;
    }
  }
  return c;
}

DiscontinuityModel DiscontinuityModel::defaults() {
  DiscontinuityModel m;
  for (const auto& i : allOps()) m.weight[static_cast<int>(i.op)] = i.piecewise ? 1.0 : 0.0;
  return m;
}

double DiscontinuityModel::programDiscontinuity(const Program& p) const {
  return programDiscontinuity(p, effectiveIndices(p));
}

double DiscontinuityModel::programDiscontinuity(const Program& p,
                                                const std::vector<int>& effective) const {
  double d = 0;
  for (int i : effective) d += weight[static_cast<int>(p.code[i].op)];
  return d;
}

Scorer::Scorer(const Dataset& ds, ErrorConfig cfg, int block_size)
    : ds_(ds), cfg_(std::move(cfg)), interp_(block_size) {
  cfg_.transforms.resize(ds.numOutputs(), TargetTransform::None);
  pred_.resize(block_size);
  ss_tot_.resize(ds.numOutputs());
  for (int o = 0; o < ds.numOutputs(); ++o) {
    double sw = 0, swy = 0;
    for (size_t r = 0; r < ds.rows(); ++r) {
      sw += ds.weight()[r];
      swy += ds.weight()[r] * ds.target(o)[r];
    }
    const double mean = sw > 0 ? swy / sw : 0;
    double ss = 0;
    for (size_t r = 0; r < ds.rows(); ++r) {
      const double d = ds.target(o)[r] - mean;
      ss += ds.weight()[r] * d * d;
    }
    ss_tot_[o] = ss;
  }
}

namespace {
using Acc = detail::ErrorAcc;

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
  switch (metric) {
    case ErrorMetric::Rmse:
      return m.rmse;
    case ErrorMetric::MaxAbs:
      return m.max_abs;
    case ErrorMetric::Mae:
      return m.mae;
    case ErrorMetric::MeanRel:
      return m.mean_rel;
  }
  return m.rmse;
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

// Accumulates the metrics selected by M over one block. M < 0 computes all of them.
template <int M>
inline void accumulate(Acc& acc, const float* __restrict pred, const double* __restrict y,
                       const double* __restrict w, int n, double rel_floor) {
  double sse = 0, sae = 0, srel = 0, mx = 0;
  float chk = 0;
#pragma omp simd reduction(+ : sse, sae, srel, chk) reduction(max : mx)
  for (int i = 0; i < n; ++i) {
    chk += pred[i] * 0.0f;
    const double d = static_cast<double>(pred[i]) - y[i];
    const double ad = std::fabs(d);
    if constexpr (M < 0 || M == static_cast<int>(ErrorMetric::Rmse)) sse += w[i] * d * d;
    if constexpr (M < 0 || M == static_cast<int>(ErrorMetric::Mae)) sae += w[i] * ad;
    if constexpr (M < 0 || M == static_cast<int>(ErrorMetric::MeanRel)) {
      const double ay = std::fabs(y[i]);
      srel += w[i] * ad / (ay > rel_floor ? ay : rel_floor);
    }
    if constexpr (M < 0 || M == static_cast<int>(ErrorMetric::MaxAbs)) mx = ad > mx ? ad : mx;
  }
  acc.sse += sse;
  acc.sae += sae;
  acc.srel += srel;
  acc.maxabs = std::max(acc.maxabs, mx);
  acc.chk += chk;
}
}  // namespace

template <int M>
void Scorer::run(const BoundProgram& bp, std::vector<detail::ErrorAcc>& accs) {
  const int bs = interp_.blockSize();
  const size_t nb = ds_.numBlocks();
  accs.assign(bp.output_slots.size(), Acc{});
  for (size_t b = 0; b < nb; ++b) {
    const auto& outs = interp_.evalBlock(bp, ds_, b);
    const size_t off = b * bs;
    for (size_t o = 0; o < outs.size(); ++o) {
      const float* pred = outs[o];
      const TargetTransform t = cfg_.transforms[o];
      if (t != TargetTransform::None) {
        float* buf = pred_.data();
#pragma omp simd
        for (int i = 0; i < bs; ++i) buf[i] = invert<float>(t, pred[i]);
        pred = buf;
      }
      accumulate<M>(accs[o], pred, ds_.target(static_cast<int>(o)) + off, ds_.weight() + off, bs,
                    cfg_.rel_floor);
    }
  }
}

double Scorer::error(const Program& p) {
  bound_.bind(p, ds_.numInputs());
  return error(bound_);
}

double Scorer::error(const BoundProgram& bp) {
  switch (cfg_.metric) {
    case ErrorMetric::Rmse:
      run<0>(bp, acc_);
      break;
    case ErrorMetric::MaxAbs:
      run<1>(bp, acc_);
      break;
    case ErrorMetric::Mae:
      run<2>(bp, acc_);
      break;
    case ErrorMetric::MeanRel:
      run<3>(bp, acc_);
      break;
  }
  errors_.clear();
  for (const detail::ErrorAcc& a : acc_) {
    if (!(a.chk == 0.0f)) return std::numeric_limits<double>::infinity();
    errors_.push_back(pickMetric(metricsFromAcc(a, ds_.weightSum()), cfg_.metric));
  }
  return combineValues(errors_, cfg_.combine);
}

std::vector<OutputMetrics> Scorer::metrics(const Program& p) {
  bound_.bind(p, ds_.numInputs());
  run<-1>(bound_, acc_);
  std::vector<OutputMetrics> out(acc_.size());
  const double ws = ds_.weightSum();
  for (size_t o = 0; o < acc_.size(); ++o) {
    const detail::ErrorAcc& a = acc_[o];
    if (!(a.chk == 0.0f)) continue;  // stays at the worst values
    out[o] = metricsFromAcc(a, ws);
    out[o].r2 = ss_tot_[o] > 0 ? 1.0 - a.sse / ss_tot_[o] : (a.sse == 0 ? 1.0 : 0.0);
  }
  return out;
}

std::vector<OutputMetrics> referenceMetrics(const Program& p, const Table& t,
                                            const ErrorConfig& cfg) {
  const auto pred = evaluateReference(p, t);
  std::vector<OutputMetrics> out(pred.size());
  const size_t n = t.rows();
  for (size_t o = 0; o < pred.size(); ++o) {
    const TargetTransform tr =
        o < cfg.transforms.size() ? cfg.transforms[o] : TargetTransform::None;
    double sw = 0, sse = 0, sae = 0, srel = 0, mx = 0, swy = 0;
    bool finite = true;
    for (size_t r = 0; r < n; ++r) {
      const double w = t.weights.empty() ? 1.0 : t.weights[r];
      const double v = invert<double>(tr, pred[o][r]);
      if (!std::isfinite(v)) finite = false;
      const double y = t.outputs[o][r];
      const double d = v - y;
      sw += w;
      swy += w * y;
      sse += w * d * d;
      sae += w * std::fabs(d);
      srel += w * std::fabs(d) / std::max(std::fabs(y), cfg.rel_floor);
      mx = std::max(mx, std::fabs(d));
    }
    if (!finite || sw <= 0) continue;
    const double mean = swy / sw;
    double ss = 0;
    for (size_t r = 0; r < n; ++r) {
      const double w = t.weights.empty() ? 1.0 : t.weights[r];
      ss += w * (t.outputs[o][r] - mean) * (t.outputs[o][r] - mean);
    }
    out[o].rmse = std::sqrt(sse / sw);
    out[o].max_abs = mx;
    out[o].mae = sae / sw;
    out[o].mean_rel = srel / sw;
    out[o].r2 = ss > 0 ? 1.0 - sse / ss : (sse == 0 ? 1.0 : 0.0);
  }
  return out;
}

double combineError(const std::vector<OutputMetrics>& m, const ErrorConfig& cfg) {
  std::vector<double> errors;
  for (const auto& om : m) errors.push_back(pickMetric(om, cfg.metric));
  return combineValues(errors, cfg.combine);
}

}  // namespace lgp
