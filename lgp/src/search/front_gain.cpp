#include "lgp/search/front_gain.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace lgp {
namespace {

// Errors below 1e-12 count as 1e-12: an exact fit gains a bounded area.
double logError(double e) {
  return std::log10(std::max(e, 1e-12));
}

int band(double cost, int bands) {
  if (!(cost >= 0)) return 0;
  return static_cast<int>(std::min<double>(std::floor(cost), bands));
}

}  // namespace

FrontGain::FrontGain(int max_cost)
    : best_(static_cast<size_t>(std::max(1, max_cost)), std::numeric_limits<double>::infinity()) {}

void FrontGain::reset(const std::vector<Objectives>& members) {
  const int bands = static_cast<int>(best_.size());
  std::fill(best_.begin(), best_.end(), std::numeric_limits<double>::infinity());
  ceiling_ = -std::numeric_limits<double>::infinity();
  for (const auto& o : members) {
    if (!o.finite()) continue;
    const double e = logError(o.error);
    ceiling_ = std::max(ceiling_, e);
    const int b = band(o.cost, bands);
    if (b < bands) best_[static_cast<size_t>(b)] = std::min(best_[static_cast<size_t>(b)], e);
  }
  for (int b = 1; b < bands; ++b)
    best_[static_cast<size_t>(b)] =
        std::min(best_[static_cast<size_t>(b)], best_[static_cast<size_t>(b - 1)]);
  if (!std::isfinite(ceiling_)) ceiling_ = 0;
}

double FrontGain::add(const Objectives& o) {
  if (!o.finite()) return 0;
  const int bands = static_cast<int>(best_.size());
  const double e = logError(o.error);
  double gain = 0;
  for (int b = band(o.cost, bands); b < bands; ++b) {
    double& s = best_[static_cast<size_t>(b)];
    if (e >= s) break;  // the staircase falls with cost: no band above gains either
    gain += std::min(s, ceiling_) > e ? std::min(s, ceiling_) - e : 0;
    s = e;
  }
  return gain;
}

}  // namespace lgp
