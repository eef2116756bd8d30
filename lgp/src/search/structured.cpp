// The structured accurate end (structured.hpp): polynomial, rational and exp2-of-polynomial
// least-squares fits, written as programs in Horner form.
#include "lgp/search/structured.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <functional>
#include <map>

#include "lgp/core/rng.hpp"
#include "lgp/eval/objectives.hpp"

namespace lgp {

namespace {

using Exponents = std::vector<int>;  // per feature

// Every exponent vector of `n` features with total degree <= d, in a fixed order.
std::vector<Exponents> monomials(int n, int d) {
  std::vector<Exponents> out;
  Exponents e(n, 0);
  std::function<void(int, int)> rec = [&](int v, int left) {
    if (v == n) {
      out.push_back(e);
      return;
    }
    for (int k = 0; k <= left; ++k) {
      e[v] = k;
      rec(v + 1, left - k);
    }
    e[v] = 0;
  };
  rec(0, d);
  return out;
}

// How many monomials `monomials(n, d)` lists, C(n + d, d), without listing them (in double:
// 30 inputs at degree 8 are 4.9e7, far past any constant budget).
double monomialCount(int n, int d) {
  double c = 1;
  for (int k = 1; k <= d; ++k) c = c * (n + k) / k;
  return c;
}

// Builds programs opcode by opcode; operands are inputs, constant slots or earlier opcodes.
struct Builder {
  Program p;
  Operand op(Op o, Operand a, Operand b = {}, Operand c = {}) {
    Instr in;
    in.op = o;
    in.args[0] = a;
    in.args[1] = b;
    in.args[2] = c;
    p.code.push_back(in);
    return regOperand(static_cast<int>(p.code.size()) - 1);
  }
  Operand constant(double v) {
    p.constants.push_back(static_cast<float>(v));
    return constOperand(static_cast<int>(p.constants.size()) - 1);
  }
};

// A polynomial over `feat` (operands) with coefficients by exponent vector, in Horner form
// nested over the features: P = sum_i f0^i P_i(f1, ...), P_i by the same rule. Returns the
// operand holding its value (a constant slot for a constant polynomial).
Operand horner(Builder& b, const std::vector<Operand>& feat,
               const std::map<Exponents, double>& coef, Exponents& prefix, int v, int degree) {
  const int n = static_cast<int>(feat.size());
  if (v == n - 1) {
    auto c = [&](int k) {
      prefix[v] = k;
      auto it = coef.find(prefix);
      prefix[v] = 0;
      return it == coef.end() ? 0.0 : it->second;
    };
    Operand acc = b.constant(c(degree));
    for (int k = degree - 1; k >= 0; --k) acc = b.op(Op::Mad, acc, feat[v], b.constant(c(k)));
    return acc;
  }
  auto part = [&](int k) {
    prefix[v] = k;
    Operand o = horner(b, feat, coef, prefix, v + 1, degree - k);
    prefix[v] = 0;
    return o;
  };
  Operand acc = part(degree);
  for (int k = degree - 1; k >= 0; --k) acc = b.op(Op::Mad, acc, feat[v], part(k));
  return acc;
}

struct Features {
  std::vector<int> sqrt_of;  // per input: 1 = the feature is sqrt(input)
  std::string label;
};

// The fit's rows: an even stride over a large table.
std::vector<size_t> fitRows(size_t rows, int max_rows) {
  std::vector<size_t> r;
  const size_t step = max_rows > 0 && rows > static_cast<size_t>(max_rows)
                          ? (rows + static_cast<size_t>(max_rows) - 1) / max_rows
                          : 1;
  for (size_t i = 0; i < rows; i += step) r.push_back(i);
  return r;
}

// Weighted least squares min |W (A x - y)|; empty when it is not finite.
Eigen::VectorXd solve(const Eigen::MatrixXd& a, const Eigen::VectorXd& y,
                      const Eigen::VectorXd& w) {
  const Eigen::MatrixXd aw = w.asDiagonal() * a;
  const Eigen::VectorXd yw = w.cwiseProduct(y);
  Eigen::VectorXd x = aw.colPivHouseholderQr().solve(yw);
  if (!x.allFinite()) return {};
  return x;
}

class Fitter {
 public:
  Fitter(const RunConfig& cfg, const Table& t, const ProgramShape& shape,
         const std::vector<Interval>& domain)
      : cfg_(cfg), t_(t), shape_(shape), domain_(domain) {
    rows_ = fitRows(t.rows(), cfg.search.structured.max_rows);
    const auto err = cfg.errorConfig(t.output_names);
    for (size_t o = 0; o < t.numOutputs(); ++o) {
      const TargetTransform tr =
          o < err.transforms.size() ? err.transforms[o] : TargetTransform::None;
      Eigen::VectorXd y(rows_.size());
      bool finite = true;
      for (size_t k = 0; k < rows_.size(); ++k) {
        y[k] = applyTransform(tr, t.outputs[o][rows_[k]]);
        finite = finite && std::isfinite(y[k]);
      }
      targets_.push_back(y);
      finite_.push_back(finite);
    }
    w_ = Eigen::VectorXd::Ones(static_cast<Eigen::Index>(rows_.size()));
    if (!t.weights.empty())
      for (size_t k = 0; k < rows_.size(); ++k)
        w_[k] = std::sqrt(std::max(0.0, t.weights[rows_[k]]));
    // The domain box where a denominator must keep its sign: a grid over the table's ranges.
    const int n = static_cast<int>(t.numInputs());
    const int per_axis = n == 1 ? 512 : n == 2 ? 64 : n == 3 ? 16 : 6;
    if (std::pow(per_axis, n) > kMaxBoxPoints) {
      // Many inputs: a grid would be astronomically large; points drawn over the box.
      Rng rng(0x5eed5eedULL);
      for (int k = 0; k < kMaxBoxPoints; ++k) {
        std::vector<double> pt(n);
        for (int a = 0; a < n; ++a) pt[a] = rng.uniform(domain[a].lo, domain[a].hi);
        box_.push_back(pt);
      }
      return;
    }
    std::vector<int> idx(n, 0);
    for (bool more = n > 0; more;) {
      std::vector<double> pt(n);
      for (int a = 0; a < n; ++a) {
        const double lo = domain[a].lo, hi = domain[a].hi;
        pt[a] = lo + (hi - lo) * idx[a] / (per_axis - 1);
      }
      box_.push_back(pt);
      more = false;
      for (int a = 0; a < n && !more; ++a) {
        if (++idx[a] < per_axis)
          more = true;
        else
          idx[a] = 0;
      }
    }
  }

  static constexpr int kMaxBoxPoints = 8192;

  std::vector<StructuredFit> run() {
    std::vector<StructuredFit> out;
    const auto& sc = cfg_.search.structured;
    if (sc.max_degree <= 0 || t_.numInputs() == 0 || t_.numOutputs() == 0) return out;
    for (const auto& f : featureSets()) {
      for (int d = 1; d <= sc.max_degree; ++d) {
        // Past the constant budget at degree d, every larger degree is too.
        if (monomialCount(static_cast<int>(t_.numInputs()), d) * t_.numOutputs() >
            shape_.num_constants)
          break;
        fitPoly(f, d, false, out);
        if (sc.exp2 && shape_.ops.contains(Op::Exp2)) fitPoly(f, d, true, out);
        if (sc.rational && shape_.ops.contains(Op::Div))
          for (int e = 1; e <= std::min(d, 3); ++e) fitRational(f, d, e, out);
      }
    }
    return out;
  }

 private:
  // Raw inputs, and where sc.sqrt_inputs and the input is >= 0 on the table, each subset of
  // inputs under a square root.
  std::vector<Features> featureSets() const {
    const int n = static_cast<int>(t_.numInputs());
    std::vector<int> can;
    for (int i = 0; i < n; ++i)
      if (cfg_.search.structured.sqrt_inputs && domain_[i].lo >= 0 && n <= 3) can.push_back(i);
    std::vector<Features> out;
    for (unsigned mask = 0; mask < (1u << can.size()); ++mask) {
      Features f;
      f.sqrt_of.assign(n, 0);
      for (size_t k = 0; k < can.size(); ++k)
        if (mask & (1u << k)) f.sqrt_of[can[k]] = 1;
      for (int i = 0; i < n; ++i)
        f.label +=
            (i ? ", " : "") + (f.sqrt_of[i] ? "sqrt " + t_.input_names[i] : t_.input_names[i]);
      out.push_back(f);
    }
    return out;
  }

  double feature(const Features& f, int i, double x) const {
    return f.sqrt_of[i] ? std::sqrt(std::max(0.0, x)) : x;
  }

  Eigen::MatrixXd design(const Features& f, const std::vector<Exponents>& ms,
                         const std::vector<std::vector<double>>& pts) const {
    Eigen::MatrixXd a(static_cast<Eigen::Index>(pts.size()), static_cast<Eigen::Index>(ms.size()));
    for (size_t r = 0; r < pts.size(); ++r)
      for (size_t m = 0; m < ms.size(); ++m) {
        double v = 1;
        for (size_t i = 0; i < ms[m].size(); ++i)
          if (ms[m][i]) v *= std::pow(feature(f, static_cast<int>(i), pts[r][i]), ms[m][i]);
        a(static_cast<Eigen::Index>(r), static_cast<Eigen::Index>(m)) = v;
      }
    return a;
  }

  const std::vector<std::vector<double>>& fitPoints() {
    if (pts_.empty())
      for (size_t r : rows_) {
        std::vector<double> p;
        for (const auto& col : t_.inputs) p.push_back(col[r]);
        pts_.push_back(std::move(p));
      }
    return pts_;
  }

  // The program's features: an input, or one sqrt opcode per input under a root.
  std::vector<Operand> featureOperands(Builder& b, const Features& f) const {
    std::vector<Operand> feat;
    for (int i = 0; i < static_cast<int>(t_.numInputs()); ++i)
      feat.push_back(f.sqrt_of[i] ? b.op(Op::Sqrt, inputOperand(i)) : inputOperand(i));
    return feat;
  }

  bool fits(const Program& p) const {
    if (static_cast<int>(p.code.size()) > shape_.max_length) return false;
    if (static_cast<int>(p.constants.size()) > shape_.num_constants) return false;
    for (const Instr& in : p.code)
      if (!shape_.ops.contains(in.op)) return false;
    for (float c : p.constants)
      if (!std::isfinite(c)) return false;
    return true;
  }

  static std::map<Exponents, double> coefMap(const std::vector<Exponents>& ms,
                                             const Eigen::VectorXd& x, Eigen::Index first = 0) {
    std::map<Exponents, double> m;
    for (size_t k = 0; k < ms.size(); ++k) m[ms[k]] = x[first + static_cast<Eigen::Index>(k)];
    return m;
  }

  // Where the budget allows one, a program; its outputs follow the table's.
  void fitPoly(const Features& f, int d, bool in_exp2, std::vector<StructuredFit>& out) {
    const int n = static_cast<int>(t_.numInputs());
    const int k = static_cast<int>(t_.numOutputs());
    if (monomialCount(n, d) * k > shape_.num_constants) return;
    const auto ms = monomials(n, d);
    const Eigen::MatrixXd a = design(f, ms, fitPoints());
    Builder b;
    const auto feat = featureOperands(b, f);
    for (int o = 0; o < k; ++o) {
      if (!finite_[o]) return;
      Eigen::VectorXd y = targets_[o], w = w_;
      if (in_exp2) {
        for (Eigen::Index r = 0; r < y.size(); ++r) {
          if (!(y[r] > 0)) return;  // exp2 of anything is > 0
          w[r] *= y[r];             // d(2^p) = y ln2 dp: absolute error, to first order
          y[r] = std::log2(y[r]);
        }
      }
      const Eigen::VectorXd x = solve(a, y, w);
      if (x.size() == 0) return;
      Exponents prefix(n, 0);
      const Operand v = horner(b, feat, coefMap(ms, x), prefix, 0, d);
      if (in_exp2) b.op(Op::Exp2, v);
      b.p.outputs.push_back(static_cast<uint8_t>(b.p.code.size() - 1));
    }
    if (!fits(b.p)) return;
    out.push_back({(in_exp2 ? "exp2 poly " : "poly ") + std::to_string(d) + " (" + f.label + ")",
                   std::move(b.p), static_cast<int>(ms.size()) * k});
  }

  void fitRational(const Features& f, int d, int e, std::vector<StructuredFit>& out) {
    const int n = static_cast<int>(t_.numInputs());
    if ((monomialCount(n, d) + monomialCount(n, e)) * static_cast<double>(t_.numOutputs()) >
        shape_.num_constants)
      return;
    const auto mp = monomials(n, d);
    auto mq = monomials(n, e);
    mq.erase(mq.begin());  // the constant term: 1
    const int k = static_cast<int>(t_.numOutputs());
    const int m = static_cast<int>(mp.size() + mq.size());
    if ((m + 1) * k > shape_.num_constants) return;
    const Eigen::MatrixXd ap = design(f, mp, fitPoints());
    const Eigen::MatrixXd aq = design(f, mq, fitPoints());
    const Eigen::MatrixXd bq = design(f, mq, box_);
    Builder b;
    const auto feat = featureOperands(b, f);
    for (int o = 0; o < k; ++o) {
      if (!finite_[o]) return;
      const Eigen::VectorXd& y = targets_[o];
      // y Q - P = 0 linearised: [A_p, -y A_q] [p; q] = y, reweighted by 1 / |Q| of the last
      // step (Sanathanan and Koerner 1963), so that the sum approaches that of P / Q - y.
      Eigen::MatrixXd a(ap.rows(), m);
      a << ap, -(y.asDiagonal() * aq);
      Eigen::VectorXd w = w_, x;
      for (int it = 0; it < 6; ++it) {
        x = solve(a, y, w);
        if (x.size() == 0) return;
        const Eigen::VectorXd q = (aq * x.tail(mq.size())).array() + 1.0;
        for (Eigen::Index r = 0; r < q.size(); ++r) w[r] = w_[r] / std::max(std::fabs(q[r]), 1e-3);
      }
      // No pole on the domain: Q keeps its sign, and never comes near 0 against its size.
      const Eigen::VectorXd qb = (bq * x.tail(mq.size())).array() + 1.0;
      const double lo = qb.minCoeff(), hi = qb.maxCoeff();
      if (!(lo > 0.02 * std::max(1.0, std::fabs(hi)))) return;
      Exponents prefix(n, 0);
      const Operand num = horner(b, feat, coefMap(mp, x), prefix, 0, d);
      std::map<Exponents, double> qc = coefMap(mq, x, static_cast<Eigen::Index>(mp.size()));
      qc[Exponents(n, 0)] = 1.0;
      const Operand den = horner(b, feat, qc, prefix, 0, e);
      b.op(Op::Div, num, den);
      b.p.outputs.push_back(static_cast<uint8_t>(b.p.code.size() - 1));
    }
    if (!fits(b.p)) return;
    out.push_back({"rational " + std::to_string(d) + "/" + std::to_string(e) + " (" + f.label + ")",
                   std::move(b.p), (m + 1) * k});
  }

  const RunConfig& cfg_;
  const Table& t_;
  const ProgramShape& shape_;
  const std::vector<Interval>& domain_;
  std::vector<size_t> rows_;
  std::vector<Eigen::VectorXd> targets_;
  std::vector<bool> finite_;
  Eigen::VectorXd w_;
  std::vector<std::vector<double>> pts_, box_;
};

}  // namespace

std::vector<StructuredFit> structuredFits(const RunConfig& cfg, const Table& t,
                                          const ProgramShape& shape,
                                          const std::vector<Interval>& domain) {
  return Fitter(cfg, t, shape, domain).run();
}

}  // namespace lgp
