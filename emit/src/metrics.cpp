// Row-by-row metrics of a DAG (see metrics.hpp).
#include "metrics.hpp"

#include <cmath>
#include <limits>
#include <string>

namespace lgp::emit::detail {

std::vector<OutputMetrics> valueMetrics(const std::vector<std::vector<double>>& values,
                                        const Table& t, double rel_floor) {
  std::vector<OutputMetrics> out;
  for (size_t j = 0; j < values.size(); ++j)
    out.push_back(metricsOf(values[j].data(), t.outputs[j].data(),
                            t.weights.empty() ? nullptr : t.weights.data(), t.rows(), rel_floor));
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
