// Row-by-row metrics of a DAG (see metrics.hpp).
#include "metrics.hpp"

#include <cmath>
#include <limits>
#include <string>

namespace lgp::emit::detail {

std::vector<OutputMetrics> valueMetrics(const std::vector<std::vector<double>>& values,
                                        const Table& t, double rel_floor) {
  const size_t k = values.size(), n = t.rows();
  std::vector<OutputMetrics> out(k);
  for (size_t j = 0; j < k; ++j) {
    double sw = 0, se2 = 0, sae = 0, srel = 0, sy = 0, sy2 = 0, mx = 0;
    bool bad = false;
    for (size_t r = 0; r < n && !bad; ++r) {
      const double v = values[j][r];
      if (!std::isfinite(v)) {
        bad = true;
        break;
      }
      const double w = t.weights.empty() ? 1.0 : t.weights[r];
      const double yt = t.outputs[j][r], e = v - yt;
      sw += w;
      se2 += w * e * e;
      sae += w * std::fabs(e);
      srel += w * std::fabs(e) / std::max(std::fabs(yt), rel_floor);
      sy += w * yt;
      sy2 += w * yt * yt;
      if (w > 0) mx = std::max(mx, std::fabs(e));
    }
    if (bad || sw <= 0) continue;  // defaults are +inf / -inf
    OutputMetrics& m = out[j];
    m.rmse = std::sqrt(se2 / sw);
    m.max_abs = mx;
    m.mae = sae / sw;
    m.mean_rel = srel / sw;
    const double mean = sy / sw;
    const double sst = sy2 - sw * mean * mean;
    m.r2 = sst > 0 ? 1.0 - se2 / sst : (se2 == 0 ? 1.0 : -std::numeric_limits<double>::infinity());
  }
  return out;
}

Expected<std::vector<std::vector<double>>> dagValues(const Dag& d, const Table& t,
                                                     const std::vector<TargetTransform>& transforms,
                                                     Precision p) {
  const size_t k = d.outputs.size();
  if (t.numOutputs() != k)
    return Status::error("table: has " + std::to_string(t.numOutputs()) +
                         " outputs but the program has " + std::to_string(k));
  if (t.numInputs() < static_cast<size_t>(d.num_inputs))
    return Status::error("table: has " + std::to_string(t.numInputs()) +
                         " inputs but the program reads " + std::to_string(d.num_inputs));
  const size_t n = t.rows();
  std::vector<std::vector<double>> values(k, std::vector<double>(n));
  std::vector<double> x(t.numInputs());
  for (size_t r = 0; r < n; ++r) {
    for (size_t i = 0; i < x.size(); ++i) x[i] = t.inputs[i][r];
    const auto y = evaluateRow(d, x.data(), p);
    for (size_t j = 0; j < k; ++j)
      values[j][r] =
          invertTransform(j < transforms.size() ? transforms[j] : TargetTransform::None, y[j]);
  }
  return values;
}

Expected<std::vector<OutputMetrics>> dagMetrics(const Dag& d, const Table& t,
                                                const std::vector<TargetTransform>& transforms,
                                                Precision p, double rel_floor) {
  auto v = dagValues(d, t, transforms, p);
  if (!v) return v.status();
  return valueMetrics(*v, t, rel_floor);
}

}  // namespace lgp::emit::detail
