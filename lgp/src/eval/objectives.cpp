#include "lgp/eval/objectives.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>

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

namespace {
// Weighted total sum of squares of y about its weighted mean (the denominator of R^2).
double totalSumOfSquares(const double* y, const double* w, size_t n) {
  double sw = 0, swy = 0;
  for (size_t r = 0; r < n; ++r) {
    sw += w[r];
    swy += w[r] * y[r];
  }
  const double mean = sw > 0 ? swy / sw : 0;
  double ss = 0;
  for (size_t r = 0; r < n; ++r) {
    const double d = y[r] - mean;
    ss += w[r] * d * d;
  }
  return ss;
}
}  // namespace

Scorer::Scorer(const Dataset& ds, ErrorConfig cfg, int block_size)
    : ds_(ds), cfg_(std::move(cfg)), interp_(block_size) {
  cfg_.transforms.resize(ds.numOutputs(), TargetTransform::None);
  pred_.resize(block_size);
  ss_tot_.resize(ds.numOutputs());
  for (int o = 0; o < ds.numOutputs(); ++o)
    ss_tot_[o] = totalSumOfSquares(ds.target(o), ds.weight(), ds.rows());
  if (buffered()) {
    const size_t n = ds.paddedRows();
    raw_.assign(ds.numOutputs(), std::vector<float>(n));
    chan_pred_.resize(block_size);
    if (cfg_.linear_scaling) {
      fit_target_.assign(ds.numOutputs(), std::vector<double>(n));
      for (int o = 0; o < ds.numOutputs(); ++o)
        for (size_t r = 0; r < n; ++r)
          fit_target_[o][r] = applyTransform(cfg_.transforms[o], ds.target(o)[r]);
    }
    for (auto& ch : cfg_.channels) {
      ch.weights.resize(ds.numOutputs(), 0.0);
      std::vector<double> t(n, 0.0);
      for (int o = 0; o < ds.numOutputs(); ++o)
        if (ch.weights[o] != 0)
          for (size_t r = 0; r < n; ++r) t[r] += ch.weights[o] * ds.target(o)[r];
      chan_ss_tot_.push_back(totalSumOfSquares(t.data(), ds.weight(), ds.rows()));
      chan_target_.push_back(std::move(t));
    }
  }
  scales_.assign(ds.numOutputs(), LinearScale{});
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

template <int M>
bool Scorer::runBuffered(const BoundProgram& bp, bool scale, std::vector<detail::ErrorAcc>& accs) {
  const int bs = interp_.blockSize();
  const size_t nb = ds_.numBlocks();
  const size_t n = ds_.paddedRows();
  const int k = static_cast<int>(bp.output_slots.size());
  for (size_t b = 0; b < nb; ++b) {
    const auto& outs = interp_.evalBlock(bp, ds_, b);
    for (int o = 0; o < k; ++o) std::memcpy(raw_[o].data() + b * bs, outs[o], bs * sizeof(float));
  }
  const double* w = ds_.weight();
  for (int o = 0; o < k; ++o) {
    float* v = raw_[o].data();
    float chk = 0;
#pragma omp simd reduction(+ : chk)
    for (size_t r = 0; r < n; ++r) chk += v[r] * 0.0f;
    if (!(chk == 0.0f)) return false;
    scales_[o] = LinearScale{};
    if (scale) {
      // Weighted least squares of T(y) on f, centred (two passes) for accuracy.
      const double* y = fit_target_[o].data();
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
      double a = sff > 1e-12 * sw * (1.0 + mf * mf) ? sfy / sff : 0.0;
      double b0 = my - a * mf;
      if (!std::isfinite(a) || !std::isfinite(b0) || std::fabs(a) > 1e30 || std::fabs(b0) > 1e30) {
        a = 0.0;
        b0 = std::isfinite(my) ? my : 0.0;
      }
      LinearScale ls{static_cast<float>(a), static_cast<float>(b0)};
      scales_[o] = ls;
      // What the materialised opcode computes (see applyLinearScaling).
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
    const TargetTransform t = cfg_.transforms[o];
    if (t != TargetTransform::None) {
#pragma omp simd
      for (size_t r = 0; r < n; ++r) v[r] = invert<float>(t, v[r]);
    }
  }
  if (cfg_.channels.empty()) {
    accs.assign(k, Acc{});
    for (int o = 0; o < k; ++o)
      for (size_t b = 0; b < nb; ++b)
        accumulate<M>(accs[o], raw_[o].data() + b * bs, ds_.target(o) + b * bs, w + b * bs, bs,
                      cfg_.rel_floor);
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
        const float* v = raw_[o].data() + off;
#pragma omp simd
        for (int i = 0; i < bs; ++i) cp[i] += wo * v[i];
      }
      accumulate<M>(accs[c], cp, chan_target_[c].data() + off, w + off, bs, cfg_.rel_floor);
    }
  }
  return true;
}

template <int M>
bool Scorer::measure(const BoundProgram& bp) {
  if (buffered()) return runBuffered<M>(bp, cfg_.linear_scaling, acc_);
  run<M>(bp, acc_);
  return true;
}

double Scorer::error(const Program& p) {
  bound_.bind(p, ds_.numInputs());
  return error(bound_);
}

double Scorer::error(const BoundProgram& bp) {
  bool ok = false;
  switch (cfg_.metric) {
    case ErrorMetric::Rmse:
      ok = measure<0>(bp);
      break;
    case ErrorMetric::MaxAbs:
      ok = measure<1>(bp);
      break;
    case ErrorMetric::Mae:
      ok = measure<2>(bp);
      break;
    case ErrorMetric::MeanRel:
      ok = measure<3>(bp);
      break;
  }
  if (!ok) return std::numeric_limits<double>::infinity();
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

std::vector<OutputMetrics> Scorer::channelMetrics(const Program& p) {
  if (cfg_.channels.empty()) return metrics(p);
  bound_.bind(p, ds_.numInputs());
  std::vector<OutputMetrics> out(cfg_.channels.size());
  if (!runBuffered<-1>(bound_, false, acc_)) return out;
  for (size_t c = 0; c < acc_.size(); ++c) {
    if (!(acc_[c].chk == 0.0f)) continue;
    out[c] = metricsFromAcc(acc_[c], ds_.weightSum());
    const double ss = chan_ss_tot_[c];
    out[c].r2 = ss > 0 ? 1.0 - acc_[c].sse / ss : (acc_[c].sse == 0 ? 1.0 : 0.0);
  }
  return out;
}

Program applyLinearScaling(const Program& p, const std::vector<LinearScale>& scales) {
  Program q = p;
  for (size_t o = 0; o < q.outputs.size() && o < scales.size(); ++o) {
    const LinearScale s = scales[o];
    if (s.identity()) continue;
    Instr in;
    in.op = s.op();
    in.args[0] = regOperand(q.outputs[o]);
    // mul(f, a), add(f, b) or mad(f, a, b): the constants in operand order.
    const std::vector<float> ks = in.op == Op::Mul   ? std::vector<float>{s.a}
                                  : in.op == Op::Add ? std::vector<float>{s.b}
                                                     : std::vector<float>{s.a, s.b};
    for (size_t k = 0; k < ks.size(); ++k) {
      in.args[1 + k] = constOperand(static_cast<int>(q.constants.size()));
      q.constants.push_back(ks[k]);
    }
    q.code.push_back(in);
    q.outputs[o] = static_cast<uint8_t>(q.code.size() - 1);
  }
  return q;
}

double scalingCost(const CostModel& m, const std::vector<LinearScale>& scales) {
  double c = 0;
  for (const LinearScale& s : scales) {
    if (!s.identity()) c += m.cost[static_cast<int>(s.op())];
  }
  return c;
}

namespace {
// Every metric of one series of double predictions against y (the reference path); the worst
// values when a prediction is not finite or no row has weight.
OutputMetrics seriesMetrics(const std::vector<double>& v, const std::vector<double>& y,
                            const std::vector<double>& weights, double rel_floor) {
  OutputMetrics m;
  double sw = 0, sse = 0, sae = 0, srel = 0, mx = 0, swy = 0;
  for (size_t r = 0; r < v.size(); ++r) {
    if (!std::isfinite(v[r])) return OutputMetrics{};
    const double w = weights.empty() ? 1.0 : weights[r];
    const double d = v[r] - y[r];
    sw += w;
    swy += w * y[r];
    sse += w * d * d;
    sae += w * std::fabs(d);
    srel += w * std::fabs(d) / std::max(std::fabs(y[r]), rel_floor);
    mx = std::max(mx, std::fabs(d));
  }
  if (sw <= 0) return m;
  const double mean = swy / sw;
  double ss = 0;
  for (size_t r = 0; r < v.size(); ++r) {
    const double w = weights.empty() ? 1.0 : weights[r];
    ss += w * (y[r] - mean) * (y[r] - mean);
  }
  m.rmse = std::sqrt(sse / sw);
  m.max_abs = mx;
  m.mae = sae / sw;
  m.mean_rel = srel / sw;
  m.r2 = ss > 0 ? 1.0 - sse / ss : (sse == 0 ? 1.0 : 0.0);
  return m;
}

// The reference evaluator's outputs, mapped back through the inverse transforms.
std::vector<std::vector<double>> referencePredictions(const Program& p, const Table& t,
                                                      const ErrorConfig& cfg) {
  auto pred = evaluateReference(p, t);
  for (size_t o = 0; o < pred.size(); ++o) {
    const TargetTransform tr =
        o < cfg.transforms.size() ? cfg.transforms[o] : TargetTransform::None;
    for (double& v : pred[o]) v = invert<double>(tr, v);
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
