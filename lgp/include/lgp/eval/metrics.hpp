// The error metrics, described once: their names (configs, fronts, reports), the field of
// OutputMetrics each fills, and their definition in double precision.
//
// With predictions p, targets y and row weights w (1 when the table has none), over the rows:
//   rmse     = sqrt(sum w (p - y)^2 / sum w)
//   max_abs  = max |p - y| over every row (a weight of 0 included: the search scores it so)
//   mae      = sum w |p - y| / sum w
//   mean_rel = sum w |p - y| / max(|y|, rel_floor) / sum w
//   r2       = 1 - sum w (p - y)^2 / sum w (y - mean_w(y))^2 (1 for an exact fit of a flat
//              target, 0 for another fit of it)
// A prediction that is not finite, or no row with weight, gives the worst values (OutputMetrics'
// defaults). metricsOf() is the definition every path is held to: the float32 scorer (its
// sums in float lanes, bounded by fastErrorBound), the double reference (referenceMetrics),
// the emitted code's re-measurement (emit) and lgpd's residuals use it or agree with it
// (tests/core/registry_coverage_test.cpp).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <string_view>

namespace lgp {

enum class ErrorMetric : uint8_t { Rmse, MaxAbs, Mae, MeanRel };

// Every metric of one output, measured on the original (untransformed) scale.
struct OutputMetrics {
  double rmse = std::numeric_limits<double>::infinity();
  double max_abs = std::numeric_limits<double>::infinity();
  double mae = std::numeric_limits<double>::infinity();
  double mean_rel = std::numeric_limits<double>::infinity();
  double r2 = -std::numeric_limits<double>::infinity();
};

struct MetricInfo {
  ErrorMetric metric;
  std::string_view name;        // objectives.error, the front's metrics keys
  double OutputMetrics::*field;  // where OutputMetrics holds it
};
inline constexpr std::array<MetricInfo, 4> kMetrics = {{
    {ErrorMetric::Rmse, "rmse", &OutputMetrics::rmse},
    {ErrorMetric::MaxAbs, "max_abs", &OutputMetrics::max_abs},
    {ErrorMetric::Mae, "mae", &OutputMetrics::mae},
    {ErrorMetric::MeanRel, "mean_rel", &OutputMetrics::mean_rel},
}};
constexpr bool metricTableInEnumOrder() {
  for (size_t i = 0; i < kMetrics.size(); ++i)
    if (static_cast<size_t>(kMetrics[i].metric) != i) return false;
  return true;
}
static_assert(metricTableInEnumOrder(), "kMetrics lists every ErrorMetric, in enum order");

constexpr const std::array<MetricInfo, 4>& allMetrics() {
  return kMetrics;
}
constexpr const MetricInfo& metricInfo(ErrorMetric m) {
  return kMetrics[static_cast<size_t>(m)];
}
// The metric's value in `m`.
constexpr double metricValue(const OutputMetrics& m, ErrorMetric metric) {
  return m.*(metricInfo(metric).field);
}

// The definition above, for n rows of predictions p against targets y (w: nullptr for 1).
OutputMetrics metricsOf(const double* p, const double* y, const double* w, size_t n,
                        double rel_floor);

}  // namespace lgp
