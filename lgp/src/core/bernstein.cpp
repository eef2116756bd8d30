// Bernstein bounds (bernstein.hpp): the polynomial is moved to the unit box (x = a + h t),
// then its power coefficients become Bernstein coefficients axis by axis:
// b_j = sum_{k <= j} C(j, k) / C(d, k) a_k (Farouki and Rajan 1988).
#include "lgp/core/bernstein.hpp"

#include <algorithm>
#include <cmath>

namespace lgp {

namespace {

double choose(int n, int k) {
  double c = 1;
  for (int i = 1; i <= k; ++i) c = c * (n - k + i) / i;
  return c;
}

}  // namespace

Interval bernsteinRange(const Polynomial& p, const std::vector<Interval>& box) {
  Interval out{0, 0, false};
  if (p.empty()) return out;
  const size_t n = box.size();
  std::vector<int> deg(n, 0);
  for (const auto& [e, c] : p)
    for (size_t i = 0; i < n && i < e.size(); ++i) deg[i] = std::max(deg[i], e[i]);
  std::vector<size_t> stride(n + 1, 1);
  for (size_t i = 0; i < n; ++i) {
    stride[i + 1] = stride[i] * static_cast<size_t>(deg[i] + 1);
    if (stride[i + 1] > kMaxBernsteinCoefficients) return {};  // no bound: the whole line
  }
  std::vector<double> t(stride[n], 0.0);
  // Power coefficients in t: prod_i (a_i + h_i t_i)^e_i, expanded term by term.
  for (const auto& [e, c] : p) {
    std::vector<double> term{c};
    std::vector<size_t> at{0};
    for (size_t i = 0; i < n; ++i) {
      const int ei = i < e.size() ? e[i] : 0;
      const double a = box[i].lo, h = box[i].hi - box[i].lo;
      std::vector<double> next;
      std::vector<size_t> next_at;
      for (size_t q = 0; q < term.size(); ++q)
        for (int k = 0; k <= ei; ++k) {
          next.push_back(term[q] * choose(ei, k) * std::pow(a, ei - k) * std::pow(h, k));
          next_at.push_back(at[q] + static_cast<size_t>(k) * stride[i]);
        }
      term.swap(next);
      at.swap(next_at);
    }
    for (size_t q = 0; q < term.size(); ++q) t[at[q]] += term[q];
  }
  // Power to Bernstein along each axis in turn (the basis is a tensor product).
  for (size_t i = 0; i < n; ++i) {
    const int d = deg[i];
    if (d == 0) continue;
    std::vector<double> fiber(d + 1);
    for (size_t base = 0; base < t.size(); ++base) {
      if ((base / stride[i]) % static_cast<size_t>(d + 1) != 0) continue;  // a fiber's start
      for (int j = 0; j <= d; ++j) fiber[j] = t[base + static_cast<size_t>(j) * stride[i]];
      for (int j = 0; j <= d; ++j) {
        double b = 0;
        for (int k = 0; k <= j; ++k) b += choose(j, k) / choose(d, k) * fiber[k];
        t[base + static_cast<size_t>(j) * stride[i]] = b;
      }
    }
  }
  const auto [lo, hi] = std::minmax_element(t.begin(), t.end());
  out.lo = *lo;
  out.hi = *hi;
  out.nan = !(std::isfinite(out.lo) && std::isfinite(out.hi));
  return out;
}

}  // namespace lgp
