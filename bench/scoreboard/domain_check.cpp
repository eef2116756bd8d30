// Whether a member holds on its table's declared domain (board.hpp checkOnDomain): a program
// that is finite and bounded at the grid points may still explode between them or beyond them
// (an r/mu term at n.v = 1e-4 makes fireflies at every silhouette).
#include <algorithm>
#include <cmath>

#include "board.hpp"
#include "lgp/core/interval.hpp"
#include "lgp/eval/interpreter.hpp"

namespace lgp::board {

namespace {
// `n` points over [lo, hi]: geometric from a lower end above 0 (where a formula blows up as an
// input goes to 0), evenly spread otherwise, both ends included.
std::vector<double> sweepAxis(double lo, double hi, int n) {
  std::vector<double> v;
  for (int i = 0; i < n; ++i) {
    const double f = n > 1 ? static_cast<double>(i) / (n - 1) : 0.0;
    v.push_back(lo > 0 ? lo * std::pow(hi / lo, f) : lo + (hi - lo) * f);
    if (lo > 0) v.push_back(lo + (hi - lo) * f);  // and evenly, for the upper part
  }
  std::sort(v.begin(), v.end());
  v.erase(std::unique(v.begin(), v.end()), v.end());
  return v;
}
}  // namespace

DomainCheck checkOnDomain(const Program& p, const std::vector<Interval>& domain,
                          const std::vector<std::pair<double, double>>& allowed,
                          const std::vector<TargetTransform>& transforms, int sweep_points) {
  DomainCheck c;
  const size_t k = p.outputs.size();
  auto none = [&] {
    return std::all_of(transforms.begin(), transforms.end(),
                       [](TargetTransform t) { return t == TargetTransform::None; });
  };
  // The proof: the program's intervals over the domain box, every output inside its bound.
  if (none()) {
    std::vector<Interval> iv;
    programIntervals(p, domain, effectiveIndices(p), iv);
    bool proven = true;
    double lo = INFINITY, hi = -INFINITY;
    for (size_t o = 0; o < k; ++o) {
      const Interval& v = iv[p.outputs[o]];
      lo = std::min(lo, v.lo), hi = std::max(hi, v.hi);
      proven =
          proven && !v.nan && v.finite() && v.lo >= allowed[o].first && v.hi <= allowed[o].second;
    }
    if (proven) {
      c.safe = true;
      c.method = "interval analysis";
      c.lo = lo, c.hi = hi;
      return c;
    }
  }
  // The sweep: a dense product grid over the domain, evaluated as scored (float32).
  const int n = std::max(2, domain.size() > 2 ? sweep_points / 5 : sweep_points);
  std::vector<std::vector<double>> axes;
  for (const auto& d : domain) axes.push_back(sweepAxis(d.lo, d.hi, n));
  Table t;
  t.inputs.assign(domain.size(), {});
  for (size_t i = 0; i < domain.size(); ++i) t.input_names.push_back("x" + std::to_string(i));
  std::vector<size_t> idx(domain.size(), 0);
  for (bool more = !axes.empty(); more;) {
    for (size_t a = 0; a < axes.size(); ++a) t.inputs[a].push_back(axes[a][idx[a]]);
    more = false;
    for (size_t a = 0; a < axes.size() && !more; ++a) {
      if (++idx[a] < axes[a].size())
        more = true;
      else
        idx[a] = 0;
    }
  }
  for (size_t o = 0; o < k; ++o) {
    t.output_names.push_back("y" + std::to_string(o));
    t.outputs.push_back(std::vector<double>(t.inputs[0].size(), 0.0));
  }
  const Dataset ds(t, 256);
  Interpreter interp(256);
  const auto out = interp.evaluate(p, ds);
  c.lo = INFINITY, c.hi = -INFINITY;
  c.safe = true;
  for (size_t o = 0; o < k; ++o)
    for (size_t r = 0; r < t.rows(); ++r) {
      const double v =
          invertTransform(o < transforms.size() ? transforms[o] : TargetTransform::None,
                          static_cast<double>(out[o][r]));
      if (std::isfinite(v)) c.lo = std::min(c.lo, v), c.hi = std::max(c.hi, v);
      if (c.safe && !(std::isfinite(v) && v >= allowed[o].first && v <= allowed[o].second)) {
        c.safe = false;
        std::string at;
        for (size_t a = 0; a < domain.size(); ++a)
          at += (a ? ", " : "") + formatDouble(t.inputs[a][r]);
        c.why = "output " + std::to_string(o) + " is " + formatDouble(v) + " at (" + at +
                "), outside [" + formatDouble(allowed[o].first) + ", " +
                formatDouble(allowed[o].second) + "]";
      }
    }
  c.method = "sweep of " + std::to_string(t.rows()) + " points";
  return c;
}

}  // namespace lgp::board
