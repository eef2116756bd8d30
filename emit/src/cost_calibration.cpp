// Corpus, measurement and fit of the cost model (see cost_calibration.hpp).
#include "lgp/emit/cost_calibration.hpp"

#include <atomic>
#include <cmath>
#include <limits>
#include <mutex>
#include <thread>

#include <Eigen/Dense>

#include "lgp/core/formula.hpp"
#include "lgp/core/rng.hpp"
#include "lgp/core/variation.hpp"

namespace lgp::emit {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr int kFeatures = 2 * kNumOps + 3;  // ops, guards, literals, unfolded modifiers

std::array<double, kFeatures> featureRow(const CostFeatures& f) {
  std::array<double, kFeatures> r{};
  for (int o = 0; o < kNumOps; ++o) {
    r[o] = f.ops[o];
    r[kNumOps + o] = f.guards[o];
  }
  r[2 * kNumOps] = f.literals;
  r[2 * kNumOps + 1] = f.unfolded_neg_abs;
  r[2 * kNumOps + 2] = f.unfolded_saturate;
  return r;
}

std::vector<Interval> pickDomain(int inputs, Rng& rng) {
  const int kind = static_cast<int>(rng.below(4));
  std::vector<Interval> d;
  for (int i = 0; i < inputs; ++i) {
    switch (kind) {
      case 0:
        d.push_back(Interval{0.0, 1.0, false});
        break;
      case 1:  // the DFG table: mu in [1/64, 1], roughness in [0, 1]
        d.push_back(i == 0 ? Interval{1.0 / 64, 1.0, false} : Interval{0.0, 1.0, false});
        break;
      case 2:
        d.push_back(Interval{-1.0, 1.0, false});
        break;
      default:
        d.push_back(Interval{0.1, 10.0, false});
        break;
    }
  }
  return d;
}

}  // namespace

CalibrationSample calibrationSample(std::string name, const Program& p, int num_inputs,
                                    const std::vector<Interval>& domain) {
  CalibrationSample s;
  s.name = std::move(name);
  s.program = p;
  s.num_inputs = num_inputs;
  s.domain = domain;
  s.features = costFeatures(formulaDag(p, num_inputs, domain), domain);
  s.measured.fill(kNaN);
  return s;
}

std::vector<CalibrationSample> randomCorpus(const CorpusOptions& o) {
  static constexpr float kInline[] = {0.5f, 1.0f, 2.0f, 4.0f, -0.5f, -1.0f, -2.0f, -4.0f};
  std::vector<CalibrationSample> out;
  Rng rng(hashSeed(o.seed, 0xc057));
  for (int i = 0; out.size() < static_cast<size_t>(o.programs); ++i) {
    ProgramShape shape;
    shape.num_inputs = rng.range(1, std::max(1, o.max_inputs));
    shape.num_outputs = rng.range(1, std::max(1, o.max_outputs));
    shape.max_length = std::max(o.max_length, shape.num_outputs);
    shape.num_constants = 6;
    InitConfig init;
    init.min_length = shape.num_outputs;
    init.max_length = rng.range(shape.num_outputs, shape.max_length);
    init.const_min = -3;
    init.const_max = 3;
    Program p = pruneIntrons(randomProgram(shape, init, rng));
    for (float& c : p.constants)
      if (rng.chance(0.3)) c = kInline[rng.below(8)];
    const auto domain = pickDomain(shape.num_inputs, rng);
    CalibrationSample s =
        calibrationSample("random " + std::to_string(i), p, shape.num_inputs, domain);
    int ops = 0;
    for (int n : s.features.ops) ops += n;
    if (ops == 0) continue;
    out.push_back(std::move(s));
  }
  return out;
}

Status measureCorpus(std::vector<CalibrationSample>& samples,
                     const std::vector<GpuFamily>& families, int threads) {
  std::atomic<size_t> next{0};
  std::mutex mu;
  std::string first_error;
  auto work = [&] {
    for (size_t i; (i = next++) < samples.size();) {
      CalibrationSample& s = samples[i];
      EmitInput in;
      in.program = s.program;
      // Appended, not "x" + to_string(k): GCC 12's -Warray-bounds misreads that inlined
      // operator+ (a known false positive) and the release build should stay warning-free.
      for (int k = 0; k < s.num_inputs; ++k)
        in.input_names.emplace_back("x").append(std::to_string(k));
      in.domain = s.domain;
      MeasureOptions mo;
      mo.families = families;
      auto m = measureProgram(in, mo);
      if (!m) {
        std::lock_guard lock(mu);
        if (first_error.empty()) first_error = s.name + ": " + m.error();
        continue;
      }
      for (GpuFamily f : families)
        s.measured[static_cast<int>(f)] =
            (*m)[std::string(toString(f))]["instructions"].get<double>();
    }
  };
  std::vector<std::thread> pool;
  for (int t = 1; t < std::max(1, threads); ++t) pool.emplace_back(work);
  work();
  for (auto& t : pool) t.join();
  if (!first_error.empty()) return Status::error(first_error);
  return Status::ok();
}

CostFit fitCostModel(const std::vector<CalibrationSample>& train,
                     const std::vector<CalibrationSample>& test, GpuFamily family) {
  const int fam = static_cast<int>(family);
  std::vector<const CalibrationSample*> rows;
  // A sample the compiler folded to nothing (measured 0) shows a limit of our simplifier
  // (lerp(a, a, t), x/x), not a price: it is left out of the fit and of the held-out figures.
  auto usable_sample = [&](const CalibrationSample& s) {
    return std::isfinite(s.measured[fam]) && s.measured[fam] > 0;
  };
  for (const auto& s : train)
    if (usable_sample(s)) rows.push_back(&s);
  const int n = static_cast<int>(rows.size());
  Eigen::MatrixXd A(n, kFeatures);
  Eigen::VectorXd y(n);
  for (int i = 0; i < n; ++i) {
    const auto r = featureRow(rows[i]->features);
    for (int j = 0; j < kFeatures; ++j) A(i, j) = r[j];
    y(i) = rows[i]->measured[fam];
  }
  // Lawson-Hanson active set: P holds the free (positive) prices, the rest are zero.
  std::vector<uint8_t> usable(kFeatures, 0), in_p(kFeatures, 0);
  for (int j = 0; j < kFeatures; ++j) usable[j] = A.col(j).squaredNorm() > 0;
  Eigen::VectorXd x = Eigen::VectorXd::Zero(kFeatures);
  auto solveP = [&](Eigen::VectorXd& z) {
    std::vector<int> idx;
    for (int j = 0; j < kFeatures; ++j)
      if (in_p[j]) idx.push_back(j);
    z = Eigen::VectorXd::Zero(kFeatures);
    if (idx.empty()) return;
    Eigen::MatrixXd Ap(n, idx.size());
    for (size_t k = 0; k < idx.size(); ++k) Ap.col(k) = A.col(idx[k]);
    const Eigen::VectorXd zp = Ap.colPivHouseholderQr().solve(y);
    for (size_t k = 0; k < idx.size(); ++k) z(idx[k]) = zp(k);
  };
  for (int outer = 0; outer < 4 * kFeatures; ++outer) {
    const Eigen::VectorXd w = A.transpose() * (y - A * x);
    int best = -1;
    for (int j = 0; j < kFeatures; ++j)
      if (usable[j] && !in_p[j] && w(j) > 1e-9 && (best < 0 || w(j) > w(best))) best = j;
    if (best < 0) break;
    in_p[best] = 1;
    for (int inner = 0; inner < 4 * kFeatures; ++inner) {
      Eigen::VectorXd z;
      solveP(z);
      bool feasible = true;
      for (int j = 0; j < kFeatures; ++j) feasible = feasible && (!in_p[j] || z(j) > 0);
      if (feasible) {
        x = z;
        break;
      }
      double alpha = 1;
      for (int j = 0; j < kFeatures; ++j)
        if (in_p[j] && z(j) <= 0) alpha = std::min(alpha, x(j) / (x(j) - z(j)));
      x += alpha * (z - x);
      for (int j = 0; j < kFeatures; ++j)
        if (in_p[j] && std::fabs(x(j)) < 1e-12) {
          in_p[j] = 0;
          x(j) = 0;
        }
    }
  }
  CostFit fit;
  fit.family = family;
  for (int o = 0; o < kNumOps; ++o) {
    fit.model.cost[o] = x(o);
    fit.model.guard[o] = x(kNumOps + o);
  }
  fit.model.extras = {x(2 * kNumOps), x(2 * kNumOps + 1), x(2 * kNumOps + 2)};
  fit.train = n;
  // Held-out figures.
  double ss_res = 0, ss_tot = 0, mean = 0;
  int m = 0;
  for (const auto& s : test)
    if (usable_sample(s)) {
      mean += s.measured[fam];
      ++m;
    }
  fit.test = m;
  if (m == 0) return fit;
  mean /= m;
  for (const auto& s : test) {
    const double v = s.measured[fam];
    if (!usable_sample(s)) continue;
    const double e = fit.model.price(s.features) - v;
    ss_res += e * e;
    ss_tot += (v - mean) * (v - mean);
    fit.worst_abs = std::max(fit.worst_abs, std::fabs(e));
    if (v >= 4) fit.worst_rel = std::max(fit.worst_rel, std::fabs(e) / v);
  }
  fit.rmse = std::sqrt(ss_res / m);
  fit.r2 = ss_tot > 0 ? 1 - ss_res / ss_tot : 0;
  return fit;
}

}  // namespace lgp::emit
