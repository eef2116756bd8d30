// Integrators for the ground-truth generators, in double precision.
//
// All three integrate a vector-valued integrand f: R^D -> R^K over a union of axis-aligned
// boxes, and return the integral with a per-component error estimate:
//   * gaussProduct: product Gauss-Legendre rule of order n on every box. The value is the
//     order-2n result; the error estimate is the sum over boxes of |Q_n - Q_2n| (conservative
//     for Q_2n; per box, so that differences of opposite sign cannot cancel).
//   * adaptive: globally adaptive subdivision. Every region carries Q (order-n product rule
//     on the region) and Q' (the same rule on its 2^D children); its estimate for component k
//     is |Q_k - Q'_k|, scaled up where the region is unresolved (detail::scaledError). A
//     max-heap pops the region with the largest estimate and replaces it by its children until
//     the summed estimate is <= max(abs_tol, rel_tol*|I|) for every component or the
//     evaluation budget is spent.
//   * qmc: randomly shifted (Cranley-Patterson) Hammersley/Halton points. The value is the
//     mean over `shifts` independent shifts; the error estimate is 3 standard errors.
// The deterministic estimates add a rounding floor, kRoundoff * integral |f|, and sum in
// compensated arithmetic. Gauss-Legendre nodes are computed by Newton iteration on the
// Legendre recurrence.
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

// Product rule on one box; adds into `acc` (and sum |w f| into `l1` when given). The box is
// summed on its own first, row by row, so that a long run of boxes does not lose the small
// terms to a large running total.
template <int D, int K, class F>
void productRule(const F& f, const Box<D>& b, const GaussRule& g, std::array<double, K>& acc,
                 uint64_t& evals, std::array<double, K>* l1 = nullptr) {
  const int n = static_cast<int>(g.x.size());
  std::array<double, D> p{};
  std::array<double, K> out{}, box{}, box_abs{};
  if constexpr (D == 1) {
    const double h = b.hi[0] - b.lo[0];
    for (int i = 0; i < n; ++i) {
      p[0] = b.lo[0] + h * g.x[i];
      out.fill(0.0);
      f(p, out);
      for (int k = 0; k < K; ++k) {
        box[k] += g.w[i] * out[k];
        box_abs[k] += g.w[i] * std::abs(out[k]);
      }
    }
    for (int k = 0; k < K; ++k) {
      box[k] *= h;
      box_abs[k] *= h;
    }
    evals += n;
  } else {
    static_assert(D == 2, "1-D and 2-D only");
    const double h0 = b.hi[0] - b.lo[0], h1 = b.hi[1] - b.lo[1];
    for (int i = 0; i < n; ++i) {
      p[0] = b.lo[0] + h0 * g.x[i];
      std::array<double, K> row{}, row_abs{};
      for (int j = 0; j < n; ++j) {
        p[1] = b.lo[1] + h1 * g.x[j];
        out.fill(0.0);
        f(p, out);
        for (int k = 0; k < K; ++k) {
          row[k] += g.w[j] * out[k];
          row_abs[k] += g.w[j] * std::abs(out[k]);
        }
      }
      for (int k = 0; k < K; ++k) {
        box[k] += g.w[i] * row[k];
        box_abs[k] += g.w[i] * row_abs[k];
      }
    }
    for (int k = 0; k < K; ++k) {
      box[k] *= h0 * h1;
      box_abs[k] *= h0 * h1;
    }
    evals += static_cast<uint64_t>(n) * n;
  }
  for (int k = 0; k < K; ++k) {
    acc[k] += box[k];
    if (l1) (*l1)[k] += box_abs[k];
  }
}

// Compensated (Neumaier) running sum.
struct CompensatedSum {
  double s = 0, c = 0;
  void add(double x) {
    const double t = s + x;
    c += std::abs(s) >= std::abs(x) ? (s - t) + x : (x - t) + s;
    s = t;
  }
  double value() const { return s + c; }
};

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

// Relative rounding floor added to every deterministic estimate: kRoundoff * integral |f|
// (integrand evaluation, the substitutions and the sums each lose a few ulps; 64 eps covers
// them with a margin, and no estimate claims more than double precision delivers).
inline constexpr double kRoundoff = 64 * 2.220446049250313e-16;

template <int D, int K, class F>
Estimate<K> gaussProduct(const F& f, std::span<const Box<D>> boxes, int n) {
  Estimate<K> e;
  std::array<detail::CompensatedSum, K> hi{};
  std::array<double, K> l1{}, diff{};
  const GaussRule& g1 = gaussLegendre(n);
  const GaussRule& g2 = gaussLegendre(2 * n);
  for (const auto& b : boxes) {
    if (detail::boxVolume(b) <= 0) continue;
    std::array<double, K> ql{}, qh{};
    detail::productRule<D, K>(f, b, g1, ql, e.evals);
    detail::productRule<D, K>(f, b, g2, qh, e.evals, &l1);
    for (int k = 0; k < K; ++k) {
      hi[k].add(qh[k]);
      diff[k] += std::abs(qh[k] - ql[k]);  // per box: differences of opposite sign add up
    }
  }
  for (int k = 0; k < K; ++k) {
    e.value[k] = hi[k].value();
    e.error[k] = diff[k] + kRoundoff * l1[k];
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

namespace detail {
// A region's error estimate from the difference `raw` of its two rules (the rule on the region
// and on its children), scaled up the way QUADPACK scales |K - G| (Piessens et al. 1983):
//   err = max(raw, resasc * min(1, (c raw / resasc)^1.5)),   resasc = int |f - mean| over it.
// It is never scaled down, and grows only where the two rules still differ by more than
// 1 / c^3 of the integrand's variation, i.e. where the region is not yet resolved and the
// difference can understate the error of the finer rule. QUADPACK's c = 200 belongs to a
// 10-point Gauss rule against its 21-point Kronrod extension; here c = 20, measured on a
// 41 x 41 dfg table against an independent reference: with the raw difference the truth came
// within 1/2.5 of the estimate, with c = 20 within 1/9, at a third more integrand evaluations.
inline constexpr double kScaleC = 20.0;
inline double scaledError(double raw, double resasc) {
  if (!(resasc > 0) || raw <= 0) return raw;
  return std::max(raw, resasc * std::min(1.0, std::pow(kScaleC * raw / resasc, 1.5)));
}
}  // namespace detail

template <int D, int K, class F>
Estimate<K> adaptive(const F& f, std::span<const Box<D>> boxes, const AdaptiveOptions& o) {
  constexpr int C = 1 << D;
  struct Region {
    Box<D> box;
    std::array<double, K> coarse{}, fine{}, fine_abs{}, errk{};
    std::array<std::array<double, K>, C> child{};
    double err = 0;  // max over components: the heap's key
  };
  const GaussRule& g = gaussLegendre(o.order);
  const int n = static_cast<int>(g.x.size());
  const int per_child = D == 1 ? n : n * n;
  Estimate<K> e;
  std::vector<std::array<double, K>> vals(static_cast<size_t>(C) * per_child);
  std::vector<double> wts(static_cast<size_t>(C) * per_child);
  // Applies the rule to the 2^D children of r.box (r.coarse already set), keeping the values,
  // then sets fine, fine_abs and the per-component scaled estimates.
  auto refine = [&](Region& r) {
    auto cb = detail::children<D>(r.box);
    r.fine.fill(0.0);
    r.fine_abs.fill(0.0);
    size_t idx = 0;
    for (int c = 0; c < C; ++c) {
      const Box<D>& b = cb[c];
      std::array<double, D> p{};
      std::array<double, K> sum{};
      if constexpr (D == 1) {
        const double h = b.hi[0] - b.lo[0];
        for (int i = 0; i < n; ++i, ++idx) {
          p[0] = b.lo[0] + h * g.x[i];
          vals[idx].fill(0.0);
          f(p, vals[idx]);
          wts[idx] = h * g.w[i];
          for (int k = 0; k < K; ++k) sum[k] += wts[idx] * vals[idx][k];
        }
      } else {
        static_assert(D == 2, "1-D and 2-D only");
        const double h0 = b.hi[0] - b.lo[0], h1 = b.hi[1] - b.lo[1];
        for (int i = 0; i < n; ++i) {
          p[0] = b.lo[0] + h0 * g.x[i];
          for (int j = 0; j < n; ++j, ++idx) {
            p[1] = b.lo[1] + h1 * g.x[j];
            vals[idx].fill(0.0);
            f(p, vals[idx]);
            wts[idx] = h0 * h1 * g.w[i] * g.w[j];
            for (int k = 0; k < K; ++k) sum[k] += wts[idx] * vals[idx][k];
          }
        }
      }
      r.child[c] = sum;
      for (int k = 0; k < K; ++k) r.fine[k] += sum[k];
    }
    e.evals += static_cast<uint64_t>(C) * per_child;
    const double vol = detail::boxVolume(r.box);
    r.err = 0;
    for (int k = 0; k < K; ++k) {
      const double mean = r.fine[k] / vol;
      double resasc = 0, resabs = 0;
      for (size_t i = 0; i < idx; ++i) {
        resasc += wts[i] * std::abs(vals[i][k] - mean);
        resabs += wts[i] * std::abs(vals[i][k]);
      }
      r.fine_abs[k] = resabs;
      r.errk[k] = detail::scaledError(std::abs(r.fine[k] - r.coarse[k]), resasc);
      r.err = std::max(r.err, r.errk[k]);
    }
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
  std::array<double, K> l1{};
  auto totals = [&](std::array<double, K>& val, std::array<double, K>& err) {
    std::array<detail::CompensatedSum, K> v{};
    err.fill(0.0);
    l1.fill(0.0);
    for (const auto& r : heap)
      for (int k = 0; k < K; ++k) {
        v[k].add(r.fine[k]);
        err[k] += r.errk[k];
        l1[k] += r.fine_abs[k];
      }
    for (int k = 0; k < K; ++k) val[k] = v[k].value();
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
      err[k] -= parent.errk[k];
    }
    auto cb = detail::children<D>(parent.box);
    for (int c = 0; c < C; ++c) {
      Region r;
      r.box = cb[c];
      r.coarse = parent.child[c];
      refine(r);
      for (int k = 0; k < K; ++k) {
        val[k] += r.fine[k];
        err[k] += r.errk[k];
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
  for (int k = 0; k < K; ++k) e.error[k] = err[k] + kRoundoff * l1[k];
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
