// Integrators for the ground-truth generators , in double precision.
//
// All three integrate a vector-valued integrand f: R^D -> R^K over a union of axis-aligned
// boxes, and return the integral with a per-component error estimate:
//   * gaussProduct: product Gauss-Legendre rule of order n on every box. The value is the
//     order-2n result; the error estimate is |Q_n - Q_2n| (conservative for Q_2n).
//   * adaptive: globally adaptive subdivision. Every region carries Q (order-n product rule
//     on the region) and Q' (the same rule on its 2^D children); the error estimate is
//     max_k |Q_k - Q'_k|. A max-heap pops the region with the largest estimate and replaces it
//     by its children until the summed estimate is <= max(abs_tol, rel_tol*|I|) for every
//     component or the evaluation budget is spent.
//   * qmc: randomly shifted (Cranley-Patterson) Hammersley/Halton points. The value is the
//     mean over `shifts` independent shifts; the error estimate is 3 standard errors.
// Gauss-Legendre nodes are computed by Newton iteration on the Legendre recurrence.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <queue>
#include <span>
#include <vector>

namespace lgp::datasets {

// Nodes and weights of the n-point Gauss-Legendre rule on [0, 1].
struct GaussRule {
  std::vector<double> x;
  std::vector<double> w;
};
const GaussRule& gaussLegendre(int n);  // cached per n; thread-safe; 1 <= n <= 256

template <int D>
struct Box {
  std::array<double, D> lo{};
  std::array<double, D> hi{};
};

template <int K>
struct Estimate {
  std::array<double, K> value{};
  std::array<double, K> error{};
  uint64_t evals = 0;  // integrand evaluations
  int regions = 0;     // adaptive: regions in the final partition
  bool converged = true;
};

namespace detail {
template <int D>
double boxVolume(const Box<D>& b) {
  double v = 1;
  for (int d = 0; d < D; ++d) v *= b.hi[d] - b.lo[d];
  return v;
}

// Product rule on one box; adds into `acc`.
template <int D, int K, class F>
void productRule(const F& f, const Box<D>& b, const GaussRule& g, std::array<double, K>& acc,
                 uint64_t& evals) {
  const int n = static_cast<int>(g.x.size());
  std::array<double, D> p{};
  std::array<double, K> out{};
  if constexpr (D == 1) {
    const double h = b.hi[0] - b.lo[0];
    for (int i = 0; i < n; ++i) {
      p[0] = b.lo[0] + h * g.x[i];
      out.fill(0.0);
      f(p, out);
      for (int k = 0; k < K; ++k) acc[k] += h * g.w[i] * out[k];
    }
    evals += n;
  } else {
    static_assert(D == 2, "1-D and 2-D only");
    const double h0 = b.hi[0] - b.lo[0], h1 = b.hi[1] - b.lo[1];
    for (int i = 0; i < n; ++i) {
      p[0] = b.lo[0] + h0 * g.x[i];
      for (int j = 0; j < n; ++j) {
        p[1] = b.lo[1] + h1 * g.x[j];
        out.fill(0.0);
        f(p, out);
        const double w = h0 * h1 * g.w[i] * g.w[j];
        for (int k = 0; k < K; ++k) acc[k] += w * out[k];
      }
    }
    evals += static_cast<uint64_t>(n) * n;
  }
}

template <int D>
std::array<Box<D>, (1 << D)> children(const Box<D>& b) {
  std::array<Box<D>, (1 << D)> c;
  for (int m = 0; m < (1 << D); ++m) {
    for (int d = 0; d < D; ++d) {
      const double mid = 0.5 * (b.lo[d] + b.hi[d]);
      c[m].lo[d] = (m >> d) & 1 ? mid : b.lo[d];
      c[m].hi[d] = (m >> d) & 1 ? b.hi[d] : mid;
    }
  }
  return c;
}

inline uint64_t splitmix64(uint64_t& s) {
  uint64_t z = (s += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

inline double radicalInverse(uint32_t base, uint64_t i) {
  if (base == 2) {
    uint64_t b = i;
    b = (b << 32) | (b >> 32);
    b = ((b & 0x0000FFFF0000FFFFull) << 16) | ((b & 0xFFFF0000FFFF0000ull) >> 16);
    b = ((b & 0x00FF00FF00FF00FFull) << 8) | ((b & 0xFF00FF00FF00FF00ull) >> 8);
    b = ((b & 0x0F0F0F0F0F0F0F0Full) << 4) | ((b & 0xF0F0F0F0F0F0F0F0ull) >> 4);
    b = ((b & 0x3333333333333333ull) << 2) | ((b & 0xCCCCCCCCCCCCCCCCull) >> 2);
    b = ((b & 0x5555555555555555ull) << 1) | ((b & 0xAAAAAAAAAAAAAAAAull) >> 1);
    return static_cast<double>(b >> 11) * 0x1.0p-53;
  }
  double inv = 1.0 / base, f = inv, r = 0;
  while (i > 0) {
    r += f * static_cast<double>(i % base);
    i /= base;
    f *= inv;
  }
  return r;
}
}  // namespace detail

template <int D, int K, class F>
Estimate<K> gaussProduct(const F& f, std::span<const Box<D>> boxes, int n) {
  Estimate<K> e;
  std::array<double, K> lo{}, hi{};
  const GaussRule& g1 = gaussLegendre(n);
  const GaussRule& g2 = gaussLegendre(2 * n);
  for (const auto& b : boxes) {
    if (detail::boxVolume(b) <= 0) continue;
    detail::productRule<D, K>(f, b, g1, lo, e.evals);
    detail::productRule<D, K>(f, b, g2, hi, e.evals);
  }
  for (int k = 0; k < K; ++k) {
    e.value[k] = hi[k];
    e.error[k] = std::abs(hi[k] - lo[k]);
  }
  e.regions = static_cast<int>(boxes.size());
  return e;
}

struct AdaptiveOptions {
  double abs_tol = 1e-7;         // target for the summed error estimate, per component
  double rel_tol = 0;            // or relative to |I|, whichever is larger
  int order = 5;                 // Gauss-Legendre points per dimension per region
  uint64_t max_evals = 2000000;  // budget; `converged` is false when it is spent
};

template <int D, int K, class F>
Estimate<K> adaptive(const F& f, std::span<const Box<D>> boxes, const AdaptiveOptions& o) {
  constexpr int C = 1 << D;
  struct Region {
    Box<D> box;
    std::array<double, K> coarse{}, fine{};
    std::array<std::array<double, K>, C> child{};
    double err = 0;
  };
  const GaussRule& g = gaussLegendre(o.order);
  Estimate<K> e;
  auto refine = [&](Region& r) {  // r.coarse already set; computes children
    auto cb = detail::children<D>(r.box);
    r.fine.fill(0.0);
    for (int c = 0; c < C; ++c) {
      r.child[c].fill(0.0);
      detail::productRule<D, K>(f, cb[c], g, r.child[c], e.evals);
      for (int k = 0; k < K; ++k) r.fine[k] += r.child[c][k];
    }
    r.err = 0;
    for (int k = 0; k < K; ++k) r.err = std::max(r.err, std::abs(r.fine[k] - r.coarse[k]));
  };
  auto cmp = [](const Region& a, const Region& b) { return a.err < b.err; };
  std::vector<Region> heap;
  for (const auto& b : boxes) {
    if (detail::boxVolume(b) <= 0) continue;
    Region r;
    r.box = b;
    detail::productRule<D, K>(f, b, g, r.coarse, e.evals);
    refine(r);
    heap.push_back(r);
  }
  std::make_heap(heap.begin(), heap.end(), cmp);
  auto totals = [&](std::array<double, K>& val, std::array<double, K>& err) {
    val.fill(0.0);
    err.fill(0.0);
    for (const auto& r : heap)
      for (int k = 0; k < K; ++k) {
        val[k] += r.fine[k];
        err[k] += std::abs(r.fine[k] - r.coarse[k]);
      }
  };
  std::array<double, K> val{}, err{};
  totals(val, err);
  auto done = [&]() {
    for (int k = 0; k < K; ++k)
      if (err[k] > std::max(o.abs_tol, o.rel_tol * std::abs(val[k]))) return false;
    return true;
  };
  int since_total = 0;
  while (!heap.empty() && !done()) {
    if (e.evals >= o.max_evals) {
      e.converged = false;
      break;
    }
    std::pop_heap(heap.begin(), heap.end(), cmp);
    Region parent = heap.back();
    heap.pop_back();
    for (int k = 0; k < K; ++k) {  // incremental update of the totals
      val[k] -= parent.fine[k];
      err[k] -= std::abs(parent.fine[k] - parent.coarse[k]);
    }
    auto cb = detail::children<D>(parent.box);
    for (int c = 0; c < C; ++c) {
      Region r;
      r.box = cb[c];
      r.coarse = parent.child[c];
      refine(r);
      for (int k = 0; k < K; ++k) {
        val[k] += r.fine[k];
        err[k] += std::abs(r.fine[k] - r.coarse[k]);
      }
      heap.push_back(r);
      std::push_heap(heap.begin(), heap.end(), cmp);
    }
    if (++since_total == 64) {  // re-sum now and then: no drift from the incremental update
      totals(val, err);
      since_total = 0;
    }
  }
  totals(val, err);
  e.value = val;
  e.error = err;
  e.regions = static_cast<int>(heap.size());
  if (!done()) e.converged = false;
  return e;
}

struct QmcOptions {
  int points = 4096;  // points per shift
  int shifts = 8;     // independent Cranley-Patterson shifts (>= 2)
  uint64_t seed = 0x5eed;
};

// Integrates over the unit cube [0,1]^D (D <= 4) with Hammersley points (i/N, radical inverses
// in bases 2, 3, 5), randomly shifted modulo 1. Deterministic for a given seed.
template <int D, int K, class F>
Estimate<K> qmc(const F& f, const QmcOptions& o) {
  static_assert(D >= 1 && D <= 4, "QMC supports 1..4 dimensions");
  constexpr uint32_t kBases[3] = {2, 3, 5};
  Estimate<K> e;
  uint64_t s = o.seed;
  std::vector<std::array<double, K>> means(o.shifts);
  std::array<double, D> p{};
  std::array<double, K> out{};
  for (int r = 0; r < o.shifts; ++r) {
    std::array<double, D> shift{};
    for (int d = 0; d < D; ++d)
      shift[d] = static_cast<double>(detail::splitmix64(s) >> 11) * 0x1.0p-53;
    std::array<double, K> sum{};
    for (int i = 0; i < o.points; ++i) {
      p[0] = (i + 0.5) / o.points;
      for (int d = 1; d < D; ++d) p[d] = detail::radicalInverse(kBases[d - 1], i);
      for (int d = 0; d < D; ++d) {
        p[d] += shift[d];
        if (p[d] >= 1) p[d] -= 1;
      }
      out.fill(0.0);
      f(p, out);
      for (int k = 0; k < K; ++k) sum[k] += out[k];
    }
    for (int k = 0; k < K; ++k) means[r][k] = sum[k] / o.points;
  }
  e.evals = static_cast<uint64_t>(o.points) * o.shifts;
  for (int k = 0; k < K; ++k) {
    double m = 0;
    for (int r = 0; r < o.shifts; ++r) m += means[r][k];
    m /= o.shifts;
    double v = 0;
    for (int r = 0; r < o.shifts; ++r) v += (means[r][k] - m) * (means[r][k] - m);
    v /= (o.shifts - 1);
    e.value[k] = m;
    e.error[k] = 3.0 * std::sqrt(v / o.shifts);
  }
  return e;
}

}  // namespace lgp::datasets
