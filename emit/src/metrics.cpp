// Row-by-row metrics of a DAG (see metrics.hpp).
#include "metrics.hpp"

#include <cmath>
#include <limits>
#include <string>

namespace lgp::emit::detail {

Expected<std::vector<OutputMetrics>> dagMetrics(const Dag& d, const Table& t,
                                                const std::vector<TargetTransform>& transforms,
                                                Precision p, double rel_floor) {
  const size_t k = d.outputs.size();
  if (t.numOutputs() != k)
    return Status::error("table: has " + std::to_string(t.numOutputs()) +
                         " outputs but the program has " + std::to_string(k));
  if (t.numInputs() < static_cast<size_t>(d.num_inputs))
    return Status::error("table: has " + std::to_string(t.numInputs()) +
                         " inputs but the program reads " + std::to_string(d.num_inputs));
  const size_t n = t.rows();
  std::vector<double> sw(k, 0), se2(k, 0), sae(k, 0), srel(k, 0), sy(k, 0), sy2(k, 0), mx(k, 0);
  std::vector<uint8_t> bad(k, 0);
  std::vector<double> x(t.numInputs());
  for (size_t r = 0; r < n; ++r) {
    for (size_t i = 0; i < x.size(); ++i) x[i] = t.inputs[i][r];
    const auto y = evaluateRow(d, x.data(), p);
    const double w = t.weights.empty() ? 1.0 : t.weights[r];
    for (size_t j = 0; j < k; ++j) {
      const TargetTransform tr = j < transforms.size() ? transforms[j] : TargetTransform::None;
      const double v = invertTransform(tr, y[j]);
      if (!std::isfinite(v)) {
        bad[j] = 1;
        continue;
      }
      const double yt = t.outputs[j][r], e = v - yt;
      sw[j] += w;
      se2[j] += w * e * e;
      sae[j] += w * std::fabs(e);
      srel[j] += w * std::fabs(e) / std::max(std::fabs(yt), rel_floor);
      sy[j] += w * yt;
      sy2[j] += w * yt * yt;
      if (w > 0) mx[j] = std::max(mx[j], std::fabs(e));
    }
  }
  std::vector<OutputMetrics> out(k);
  for (size_t j = 0; j < k; ++j) {
    if (bad[j] || sw[j] <= 0) continue;  // defaults are +inf / -inf
    OutputMetrics& m = out[j];
    m.rmse = std::sqrt(se2[j] / sw[j]);
    m.max_abs = mx[j];
    m.mae = sae[j] / sw[j];
    m.mean_rel = srel[j] / sw[j];
    const double mean = sy[j] / sw[j];
    const double sst = sy2[j] - sw[j] * mean * mean;
    m.r2 = sst > 0 ? 1.0 - se2[j] / sst
                   : (se2[j] == 0 ? 1.0 : -std::numeric_limits<double>::infinity());
  }
  return out;
}

}  // namespace lgp::emit::detail
