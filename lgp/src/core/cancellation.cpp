// Cancellation estimate (see cancellation.hpp).
#include "lgp/core/cancellation.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include "lgp/eval/objectives.hpp"
#include "lgp/eval/semantics.hpp"

namespace lgp {

namespace {

// d invertTransform(t, v) / dv.
double inverseSlope(TargetTransform t, double v) {
  switch (t) {
    case TargetTransform::None:
      return 1;
    case TargetTransform::Log:
      return invertTransform(t, v);
    case TargetTransform::Sqrt:
      return v > 0 ? 2 * v : 0;
    case TargetTransform::Rcp: {
      const double r = invertTransform(t, v);
      return std::fabs(v) < kDivGuard ? 0 : -r * r;
    }
  }
  return 1;
}

}  // namespace

Cancellation cancellation(const Dag& d, const Table& t,
                          const std::vector<TargetTransform>& transforms,
                          const CancellationOptions& o) {
  const size_t k = d.outputs.size(), n = d.nodes.size(), rows = t.rows();
  Cancellation res;
  res.per_output.assign(k, 0.0);
  if (rows == 0 || k == 0) return res;
  const size_t stride =
      std::max<size_t>(1, (rows + o.max_rows - 1) / std::max<size_t>(1, o.max_rows));
  std::vector<double> val(n), adj(n);
  // Per output: E and |result| per sampled row.
  std::vector<std::vector<double>> err(k), mag(k);
  for (size_t r = 0; r < rows; r += stride) {
    for (size_t i = 0; i < n; ++i) {
      const Node& nd = d.nodes[i];
      if (nd.kind == Node::Kind::Var)
        val[i] = nd.index < static_cast<int>(t.numInputs()) ? t.inputs[nd.index][r] : 0.0;
      else if (nd.kind == Node::Kind::Const)
        val[i] = nd.value;
      else {
        double a[kMaxArity] = {0, 0, 0, 0};
        for (int q = 0; q < arity(nd.op) && q < kMaxArity; ++q) a[q] = val[nd.args[q]];
        val[i] = applyOp(Precision::Double, nd.op, a[0], a[1], a[2], a[3]);
      }
    }
    for (size_t j = 0; j < k; ++j) {
      const int out = d.outputs[j];
      std::fill(adj.begin(), adj.end(), 0.0);
      adj[out] = 1;
      double e = 0;
      for (int i = out; i >= 0; --i) {
        if (adj[i] == 0) continue;
        e += std::fabs(val[i] * adj[i]);
        const Node& nd = d.nodes[i];
        if (!nd.isOp()) continue;
        double a[kMaxArity] = {0, 0, 0, 0};
        for (int q = 0; q < arity(nd.op) && q < kMaxArity; ++q) a[q] = val[nd.args[q]];
        // The derivatives of eval/semantics.hpp, in double, and the rounding inside the op
        // (mad's product, lerp's (b - a) c).
        const auto p = sem::partialsDynamic(nd.op, val[i], a[0], a[1], a[2], a[3]);
        e += std::fabs(p.inner * adj[i]);
        for (int q = 0; q < arity(nd.op) && q < kMaxArity; ++q)
          if (p.on[q]) adj[nd.args[q]] += adj[i] * (p.p[q] / p.den);
      }
      const TargetTransform tr = j < transforms.size() ? transforms[j] : TargetTransform{};
      const double y = val[out], result = invertTransform(tr, y);
      const double er = std::fabs(inverseSlope(tr, y)) * e;
      if (!std::isfinite(result) || !std::isfinite(er)) continue;
      err[j].push_back(er);
      mag[j].push_back(std::fabs(result));
    }
  }
  for (size_t j = 0; j < k; ++j) {
    if (mag[j].empty()) continue;
    double ss = 0;
    for (double m : mag[j]) ss += m * m;
    const double rms = std::sqrt(ss / static_cast<double>(mag[j].size()));
    double worst = 0;
    for (size_t r = 0; r < mag[j].size(); ++r) {
      const double den = std::max(mag[j][r], rms);
      if (den > 0) worst = std::max(worst, err[j][r] / den);
    }
    res.per_output[j] = worst > 1 ? std::log2(worst) : 0.0;
    res.bits_lost = std::max(res.bits_lost, res.per_output[j]);
  }
  res.flagged = res.bits_lost > o.flag_bits;
  return res;
}

}  // namespace lgp
