// The structured accurate end (structured.hpp): polynomial, rational and exp2-of-polynomial
// least-squares fits, written as programs in Horner form.
#include "lgp/search/structured.hpp"

#include <omp.h>
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <functional>
#include <map>

#include "lgp/core/bernstein.hpp"
#include "lgp/core/rng.hpp"
#include "lgp/eval/objectives.hpp"

namespace lgp {

namespace {

using Exponents = std::vector<int>;  // per feature

// Every exponent vector of `n` features with total degree <= d (or, `tensor`, degree <= d in
// each feature: the biquadratic terms of MaterialX's DFG fit are tensor degree 2), in a fixed
// order.
std::vector<Exponents> monomials(int n, int d, bool tensor = false) {
  std::vector<Exponents> out;
  Exponents e(n, 0);
  std::function<void(int, int)> rec = [&](int v, int left) {
    if (v == n) {
      out.push_back(e);
      return;
    }
    for (int k = 0; k <= left; ++k) {
      e[v] = k;
      rec(v + 1, tensor ? d : left - k);
    }
    e[v] = 0;
  };
  rec(0, d);
  return out;
}

// How many monomials `monomials(n, d, tensor)` lists, C(n + d, d) or (d + 1)^n, without
// listing them (in double: 30 inputs at degree 8 are 4.9e7, far past any constant budget).
double monomialCount(int n, int d, bool tensor = false) {
  if (tensor) return std::pow(d + 1.0, n);
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
// nested over the features: P = sum_i f0^i P_i(f1, ...), P_i by the same rule (of degree
// `degree` - i, or `degree` for a tensor family). Returns the operand holding its value (a
// constant slot for a constant polynomial).
Operand horner(Builder& b, const std::vector<Operand>& feat,
               const std::map<Exponents, double>& coef, Exponents& prefix, int v, int degree,
               bool tensor) {
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
    Operand o = horner(b, feat, coef, prefix, v + 1, tensor ? degree : degree - k, tensor);
    prefix[v] = 0;
    return o;
  };
  Operand acc = part(degree);
  for (int k = degree - 1; k >= 0; --k) acc = b.op(Op::Mad, acc, feat[v], part(k));
  return acc;
}

// A feature is an input, its square root or its square (MaterialX's DFG fit is in n.v and
// alpha = r^2).
enum class Power : uint8_t { One, Sqrt, Square };

struct Features {
  std::vector<Power> power;  // per input
  std::string label;
};

// One fit to make: a family, its degrees and its features (jobs run in parallel, the fits
// are kept in the order of the jobs).
struct Job {
  size_t features = 0;
  enum Kind : uint8_t { Poly, Exp2, Rational } kind = Poly;
  int d = 0, e = 0;
  bool tensor = false;
};

// Steps a mixed-radix counter, the first digit fastest (digit i counts to radix(i)); false
// once it wraps back to all zeros. Walks grids of cells and feature choices alike.
template <class T, class Radix>
bool advance(std::vector<T>& idx, Radix radix) {
  for (size_t i = 0; i < idx.size(); ++i) {
    if (++idx[i] < static_cast<T>(radix(i))) return true;
    idx[i] = 0;
  }
  return false;
}

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
      more = advance(idx, [&](size_t) { return per_axis; });
    }
  }

  static constexpr int kMaxBoxPoints = 8192;

  std::vector<StructuredFit> run(int threads) {
    const auto& sc = cfg_.search.structured;
    if (sc.max_degree <= 0 || t_.numInputs() == 0 || t_.numOutputs() == 0) return {};
    const int n = static_cast<int>(t_.numInputs());
    const double k = static_cast<double>(t_.numOutputs());
    const double slots = shape_.num_constants;
    const bool exp2 = sc.exp2 && shape_.ops.contains(Op::Exp2);
    const bool rational = sc.rational && shape_.ops.contains(Op::Div);
    features_ = featureSets();
    std::vector<Job> jobs;
    for (size_t f = 0; f < features_.size(); ++f) {
      for (int d = 1; d <= sc.max_degree; ++d) {
        // Past the constant budget at degree d, every larger degree is too.
        if (monomialCount(n, d) * k > slots) break;
        jobs.push_back({f, Job::Poly, d, 0, false});
        if (exp2) jobs.push_back({f, Job::Exp2, d, 0, false});
        if (rational)
          for (int e = 1; e <= std::min(d, 3); ++e) jobs.push_back({f, Job::Rational, d, e, false});
      }
      // Degree d in each of two inputs (total degree 2d); d = 1 is the bilinear polynomial.
      if (sc.tensor && n == 2)
        for (int d = 1; d <= sc.max_degree && monomialCount(n, d, true) * k <= slots; ++d) {
          if (d > 1) jobs.push_back({f, Job::Poly, d, 0, true});
          if (rational)
            for (int e = 1; e <= d; ++e) jobs.push_back({f, Job::Rational, d, e, true});
        }
    }
    fitPoints();
    std::vector<std::vector<StructuredFit>> made(jobs.size());
#pragma omp parallel for num_threads(std::max(1, threads)) schedule(dynamic)
    for (size_t j = 0; j < jobs.size(); ++j) {
      // Eigen's products would otherwise spread over omp_get_max_threads() threads where this
      // region is a team of one, changing the sums' order with the core count; this task's
      // setting ends with the region.
      omp_set_num_threads(1);
      const Job& job = jobs[j];
      if (job.kind == Job::Rational)
        fitRational(features_[job.features], job.d, job.e, job.tensor, made[j]);
      else
        fitPoly(features_[job.features], job.d, job.kind == Job::Exp2, job.tensor, made[j]);
    }
    std::vector<StructuredFit> out;
    for (auto& m : made)
      for (auto& f : m) out.push_back(std::move(f));
    return out;
  }

 private:
  // Raw inputs, and where sc.sqrt_inputs and the input is >= 0 on the table, each subset of
  // inputs under a square root (at most 3 inputs); where sc.square_inputs, each input also
  // squared (at most 2 inputs).
  std::vector<Features> featureSets() const {
    const int n = static_cast<int>(t_.numInputs());
    const auto& sc = cfg_.search.structured;
    std::vector<std::vector<Power>> choice(n, {Power::One});
    for (int i = 0; i < n; ++i) {
      if (sc.sqrt_inputs && domain_[i].lo >= 0 && n <= 3) choice[i].push_back(Power::Sqrt);
      if (sc.square_inputs && n <= 2) choice[i].push_back(Power::Square);
    }
    std::vector<Features> out;
    std::vector<size_t> idx(n, 0);
    for (bool more = true; more;) {
      Features f;
      for (int i = 0; i < n; ++i) {
        const Power p = choice[i][idx[i]];
        f.power.push_back(p);
        const std::string& name = t_.input_names[i];
        f.label += (i ? ", " : "") + (p == Power::Sqrt     ? "sqrt " + name
                                      : p == Power::Square ? name + "^2"
                                                           : name);
      }
      out.push_back(std::move(f));
      // The first input's choice varies fastest (raw, root, square).
      more = advance(idx, [&](size_t i) { return choice[i].size(); });
    }
    return out;
  }

  static double feature(const Features& f, int i, double x) {
    switch (f.power[i]) {
      case Power::Sqrt:
        return std::sqrt(std::max(0.0, x));
      case Power::Square:
        return x * x;
      default:
        return x;
    }
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

  // Built once, before the jobs run in parallel.
  const std::vector<std::vector<double>>& fitPoints() {
    if (pts_.empty())
      for (size_t r : rows_) {
        std::vector<double> p;
        for (const auto& col : t_.inputs) p.push_back(col[r]);
        pts_.push_back(std::move(p));
      }
    return pts_;
  }

  // The program's features: an input, or one opcode per input under a root or squared.
  std::vector<Operand> featureOperands(Builder& b, const Features& f) const {
    std::vector<Operand> feat;
    for (int i = 0; i < static_cast<int>(t_.numInputs()); ++i) {
      const Operand x = inputOperand(i);
      feat.push_back(f.power[i] == Power::Sqrt     ? b.op(Op::Sqrt, x)
                     : f.power[i] == Power::Square ? b.op(Op::Mul, x, x)
                                                   : x);
    }
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

  static std::string name(const char* kind, int d, bool tensor) {
    return std::string(kind) + (tensor ? "tensor " : "") + std::to_string(d);
  }

  // Where the budget allows one, a program; its outputs follow the table's.
  void fitPoly(const Features& f, int d, bool in_exp2, bool tensor,
               std::vector<StructuredFit>& out) const {
    const int n = static_cast<int>(t_.numInputs());
    const int k = static_cast<int>(t_.numOutputs());
    if (monomialCount(n, d, tensor) * k > shape_.num_constants) return;
    const auto ms = monomials(n, d, tensor);
    const Eigen::MatrixXd a = design(f, ms, pts_);
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
      const Operand v = horner(b, feat, coefMap(ms, x), prefix, 0, d, tensor);
      if (in_exp2) b.op(Op::Exp2, v);
      b.p.outputs.push_back(static_cast<uint8_t>(b.p.code.size() - 1));
    }
    if (!fits(b.p)) return;
    out.push_back({name(in_exp2 ? "exp2 poly " : "poly ", d, tensor) + " (" + f.label + ")",
                   std::move(b.p), static_cast<int>(ms.size()) * k});
  }

  // The domain box's design matrices, and the range a rational may take there: the
  // target's, widened by its span on both sides.
  struct Box {
    Eigen::MatrixXd p, q;
    double lo = 0, hi = 0;
  };

  // No pole on the box: Q keeps its sign and never comes near 0 against its size (MaterialX's
  // DFG denominators span 1 to 86), and P / Q stays in the box's range (a Q that only just keeps
  // its margin still makes a spike between grid points that the fit would exploit).
  static bool bounded(const Box& box, const Eigen::VectorXd& x) {
    const Eigen::VectorXd qb = (box.q * x.tail(box.q.cols())).array() + 1.0;
    const double lo = qb.minCoeff(), hi = qb.maxCoeff();
    if (!(lo > 1e-3 * std::max(1.0, std::fabs(hi)))) return false;
    const Eigen::VectorXd v = (box.p * x.head(box.p.cols())).cwiseQuotient(qb);
    return v.allFinite() && v.minCoeff() >= box.lo && v.maxCoeff() <= box.hi;
  }

  // sum (w (P / Q - y))^2; infinite where the rational is not bounded on the box.
  static double rationalCost(const Eigen::MatrixXd& ap, const Eigen::MatrixXd& aq, const Box& box,
                             const Eigen::VectorXd& y, const Eigen::VectorXd& w,
                             const Eigen::VectorXd& x) {
    if (!bounded(box, x)) return INFINITY;
    const Eigen::VectorXd q = (aq * x.tail(aq.cols())).array() + 1.0;
    const Eigen::VectorXd r = w.cwiseProduct((ap * x.head(ap.cols())).cwiseQuotient(q) - y);
    const double c = r.squaredNorm();
    return std::isfinite(c) ? c : INFINITY;
  }

  // The range of a feature over an input interval.
  static Interval featureRange(Power p, double lo, double hi) {
    switch (p) {
      case Power::Sqrt:
        return {std::sqrt(std::max(0.0, lo)), std::sqrt(std::max(0.0, hi)), false};
      case Power::Square:
        if (lo >= 0) return {lo * lo, hi * hi, false};
        if (hi <= 0) return {hi * hi, lo * lo, false};
        return {0.0, std::max(lo * lo, hi * hi), false};
      default:
        return {lo, hi, false};
    }
  }

  // A proof, cell by cell over the domain (Bernstein bounds, core/bernstein.hpp), that Q > 0
  // everywhere on it, between the sampled points too, and that |P / Q| stays below `limit`.
  bool certified(const Features& f, const std::vector<Exponents>& mp,
                 const std::vector<Exponents>& mq, const Eigen::VectorXd& x, double limit) const {
    const int n = static_cast<int>(t_.numInputs());
    const int cells = n == 1 ? 64 : n == 2 ? 16 : n == 3 ? 4 : 1;
    const Polynomial p = coefMap(mp, x);
    Polynomial q = coefMap(mq, x, static_cast<Eigen::Index>(mp.size()));
    q[Exponents(n, 0)] = 1.0;
    std::vector<int> idx(n, 0);
    std::vector<Interval> box(n);
    for (bool more = true; more;) {
      for (int i = 0; i < n; ++i) {
        const double lo = domain_[i].lo, w = (domain_[i].hi - domain_[i].lo) / cells;
        box[i] = featureRange(f.power[i], lo + w * idx[i],
                              idx[i] + 1 == cells ? domain_[i].hi : lo + w * (idx[i] + 1));
      }
      const Interval qr = bernsteinRange(q, box), pr = bernsteinRange(p, box);
      if (qr.nan || pr.nan || !(qr.lo > 0)) return false;
      if (std::max(std::fabs(pr.lo), std::fabs(pr.hi)) > limit * qr.lo) return false;
      more = advance(idx, [&](size_t) { return cells; });
    }
    return true;
  }

  // Levenberg-Marquardt on the rational's own residual, P / Q - y (the linearised fit only
  // approaches it), from a pole-free start; a step that would put a pole on the domain box is
  // refused like one that raises the error. On at most kPolishRows rows (an even stride).
  static Eigen::VectorXd polish(const Eigen::MatrixXd& ap, const Eigen::MatrixXd& aq,
                                const Box& box, const Eigen::VectorXd& y, const Eigen::VectorXd& w,
                                Eigen::VectorXd x, int steps) {
    const Eigen::Index np = ap.cols(), m = x.size();
    double cost = rationalCost(ap, aq, box, y, w, x), lambda = 1e-3;
    if (!std::isfinite(cost)) return x;
    for (int it = 0; it < steps; ++it) {
      const Eigen::VectorXd q = (aq * x.tail(aq.cols())).array() + 1.0;
      const Eigen::VectorXd f = (ap * x.head(np)).cwiseQuotient(q);
      Eigen::MatrixXd j(ap.rows(), m);
      const Eigen::VectorXd s = w.cwiseQuotient(q);   // d(w P/Q)/dp = w a_p / Q
      const Eigen::VectorXd sf = -s.cwiseProduct(f);  // d(w P/Q)/dq = -w (P/Q) a_q / Q
      j << s.asDiagonal() * ap, sf.asDiagonal() * aq;
      const Eigen::VectorXd r = w.cwiseProduct(f - y);
      const Eigen::MatrixXd jtj = j.transpose() * j;
      const Eigen::VectorXd g = j.transpose() * r;
      bool taken = false;
      for (int tries = 0; tries < 8 && !taken; ++tries) {
        Eigen::MatrixXd h = jtj;
        for (Eigen::Index i = 0; i < m; ++i) h(i, i) += lambda * std::max(jtj(i, i), 1e-12);
        const Eigen::VectorXd next = x - h.ldlt().solve(g);
        const double c = next.allFinite() ? rationalCost(ap, aq, box, y, w, next) : INFINITY;
        if (c < cost) {
          taken = (cost - c) > 1e-12 * cost;
          x = next;
          cost = c;
          lambda = std::max(lambda / 4, 1e-9);
          if (!taken) return x;  // converged
        } else {
          lambda *= 8;
        }
      }
      if (!taken) break;
    }
    return x;
  }

  static constexpr Eigen::Index kPolishRows = 4096;

  void fitRational(const Features& f, int d, int e, bool tensor,
                   std::vector<StructuredFit>& out) const {
    const int n = static_cast<int>(t_.numInputs());
    const int k = static_cast<int>(t_.numOutputs());
    const auto mp = monomials(n, d, tensor);
    auto mq = monomials(n, e, tensor);
    mq.erase(mq.begin());  // the constant term: 1
    const int m = static_cast<int>(mp.size() + mq.size());
    if ((m + 1) * k > shape_.num_constants) return;
    const Eigen::MatrixXd ap = design(f, mp, pts_);
    const Eigen::MatrixXd aq = design(f, mq, pts_);
    Box box{design(f, mp, box_), design(f, mq, box_)};
    // The polish's rows: an even stride (the Jacobian is rows x coefficients, every step).
    const Eigen::Index rows = ap.rows();
    const Eigen::Index step = std::max<Eigen::Index>(1, (rows + kPolishRows - 1) / kPolishRows);
    std::vector<Eigen::Index> sub;
    for (Eigen::Index r = 0; r < rows; r += step) sub.push_back(r);
    const Eigen::MatrixXd aps = ap(sub, Eigen::all), aqs = aq(sub, Eigen::all);
    const Eigen::VectorXd ws = w_(sub);
    const int steps = cfg_.search.structured.polish;
    Builder b;
    const auto feat = featureOperands(b, f);
    for (int o = 0; o < k; ++o) {
      if (!finite_[o]) return;
      const Eigen::VectorXd& y = targets_[o];
      const double span =
          std::max(y.maxCoeff() - y.minCoeff(), 1e-6 * (1 + y.cwiseAbs().maxCoeff()));
      box.lo = y.minCoeff() - span;
      box.hi = y.maxCoeff() + span;
      // y Q - P = 0 linearised: [A_p, -y A_q] [p; q] = y, reweighted by 1 / |Q| of the last
      // step (Sanathanan and Koerner 1963), so that the sum approaches that of P / Q - y.
      Eigen::MatrixXd a(ap.rows(), m);
      a << ap, -(y.asDiagonal() * aq);
      Eigen::VectorXd w = w_, x;
      for (int it = 0; it < 6; ++it) {
        x = solve(a, y, w);
        if (x.size() == 0) break;
        const Eigen::VectorXd q = (aq * x.tail(mq.size())).array() + 1.0;
        for (Eigen::Index r = 0; r < q.size(); ++r) w[r] = w_[r] / std::max(std::fabs(q[r]), 1e-3);
      }
      const Eigen::VectorXd ys = y(sub);
      const double limit = 2 * std::max(std::fabs(box.lo), std::fabs(box.hi));
      const bool sk_ok = x.size() == m && x.allFinite() && bounded(box, x);
      // Candidates, best first: with polish steps, the polish of two pole-free starts (the
      // linearised fit where it has no pole, and P alone with Q = 1, which cannot have one);
      // without (and last), the linearised fit. The first one proven pole-free is kept.
      std::vector<std::pair<double, Eigen::VectorXd>> cands;
      if (steps > 0) {
        std::vector<Eigen::VectorXd> starts;
        if (sk_ok) starts.push_back(x);
        if (Eigen::VectorXd p = solve(ap, y, w_);
            p.size() == static_cast<Eigen::Index>(mp.size())) {
          Eigen::VectorXd s = Eigen::VectorXd::Zero(m);
          s.head(mp.size()) = p;
          starts.push_back(s);
        }
        for (const auto& s : starts) {
          Eigen::VectorXd pol = polish(aps, aqs, box, ys, ws, s, steps);
          const double c = rationalCost(aps, aqs, box, ys, ws, pol);
          if (std::isfinite(c)) cands.emplace_back(c, std::move(pol));
        }
        std::stable_sort(cands.begin(), cands.end(),
                         [](const auto& u, const auto& v) { return u.first < v.first; });
        if (sk_ok) cands.emplace_back(INFINITY, x);  // the linearised fit, as a last resort
      } else if (sk_ok) {
        cands.emplace_back(0.0, x);
      }
      bool kept = false;
      for (const auto& [c, xc] : cands)
        if (certified(f, mp, mq, xc, limit)) {
          x = xc;
          kept = true;
          break;
        }
      if (!kept) return;
      Exponents prefix(n, 0);
      const Operand num = horner(b, feat, coefMap(mp, x), prefix, 0, d, tensor);
      std::map<Exponents, double> qc = coefMap(mq, x, static_cast<Eigen::Index>(mp.size()));
      qc[Exponents(n, 0)] = 1.0;
      const Operand den = horner(b, feat, qc, prefix, 0, e, tensor);
      b.op(Op::Div, num, den);
      b.p.outputs.push_back(static_cast<uint8_t>(b.p.code.size() - 1));
    }
    if (!fits(b.p)) return;
    out.push_back({name("rational ", d, tensor) + "/" + std::to_string(e) + " (" + f.label + ")",
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
  std::vector<Features> features_;
};

}  // namespace

std::vector<StructuredFit> structuredFits(const RunConfig& cfg, const Table& t,
                                          const ProgramShape& shape,
                                          const std::vector<Interval>& domain, int threads) {
  if (threads <= 0) threads = cfg.search.threads > 0 ? cfg.search.threads : omp_get_max_threads();
  return Fitter(cfg, t, shape, domain).run(threads);
}

}  // namespace lgp
