// Constant snapping (see snap.hpp).
#include "lgp/core/snap.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>

namespace lgp {

namespace {

void fractions(float v, int q_lo, int q_hi, std::vector<float>& out) {
  for (int q = q_lo; q <= q_hi; ++q) {
    const double p = std::nearbyint(static_cast<double>(v) * q);
    if (std::fabs(p) > 1e6) continue;
    out.push_back(static_cast<float>(p) / static_cast<float>(q));
  }
}

void decimal(float v, int digits, std::vector<float>& out) {
  if (v == 0 || !std::isfinite(v)) return;
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*e", digits - 1, static_cast<double>(v));
  out.push_back(static_cast<float>(std::strtod(buf, nullptr)));
}

}  // namespace

std::vector<float> snapCandidates(float v) {
  std::vector<float> c = {0.0f};
  if (std::fabs(v) < 0x1p24f) c.push_back(std::nearbyint(v));
  fractions(v, 2, 2, c);
  decimal(v, 1, c);
  fractions(v, 3, 4, c);
  decimal(v, 2, c);
  fractions(v, 5, 8, c);
  decimal(v, 3, c);
  fractions(v, 9, 12, c);
  decimal(v, 4, c);
  std::vector<float> out;
  for (float x : c) {
    if (x == 0.0f) x = 0.0f;  // no -0
    if (std::isfinite(x) && std::find(out.begin(), out.end(), x) == out.end()) out.push_back(x);
  }
  return out;
}

SnapResult snapConstants(const Program& p, const std::function<double(const Program&)>& error,
                         const SnapOptions& o) {
  SnapResult r;
  r.program = p;
  r.error_before = r.error_after = error(p);
  if (!std::isfinite(r.error_before)) return r;
  const double limit = r.error_before + std::max(r.error_before * std::max(0.0, o.tolerance),
                                                 std::max(0.0, o.abs_floor));
  for (int slot : effectiveConstants(p)) {
    const float v = r.program.constants[slot];
    for (float cand : snapCandidates(v)) {
      if (cand == v) break;  // already this simple
      Program q = r.program;
      q.constants[slot] = cand;
      const double e = error(q);
      if (std::isfinite(e) && e <= limit) {
        r.program = std::move(q);
        r.error_after = e;
        ++r.snapped;
        break;
      }
    }
  }
  return r;
}

}  // namespace lgp
