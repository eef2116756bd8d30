// generate(): a scene's table. Only what the outputs need is integrated (Scene::needs), in
// parallel over rows; quantities that depend on one input only (E_avg on r, F_avg on eta) are
// integrated once per grid value first.
#include "lgp/datasets/generate.hpp"

#include <omp.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <cmath>
#include <functional>
#include <numbers>

#include "lgp/core/program.hpp"
#include "lgp/datasets/dfg.hpp"
#include "lgp/datasets/dielectric.hpp"
#include "lgp/datasets/diffuse_albedo.hpp"
#include "lgp/datasets/energy.hpp"
#include "lgp/datasets/normalization.hpp"
#include "lgp/datasets/quadrature.hpp"
#include "lgp/datasets/sheen.hpp"
#include "lgp/datasets/zh.hpp"
#include "table_meta.hpp"

namespace lgp::datasets {

namespace {
using nlohmann::json;

// The evaluator that writes each output: a switch with no `default:`, so a new catalogue entry
// (outputs.hpp) fails to compile until it is given one; an output its evaluator then does not
// write is an error, not a column of zeros (kUnwritten).
enum class Evaluator { Specular, Eavg, Zh, Normalization, Sheen, Burley, OrenNayar, Dielectric };
inline constexpr size_t kNumEvaluators = static_cast<size_t>(Evaluator::Dielectric) + 1;
Evaluator evaluatorOf(Output o) {
  switch (o) {
    case Output::A:
    case Output::B:
    case Output::E:
    case Output::one_minus_E:
    case Output::ms_turquin:
    case Output::ms_lobe:
      return Evaluator::Specular;
    case Output::E_avg:
      return Evaluator::Eavg;
    case Output::ZH0:
    case Output::ZH1:
    case Output::ZH2:
    case Output::ZH1_over_ZH0:
    case Output::ZH2_over_ZH0:
    case Output::beta:
      return Evaluator::Zh;
    case Output::N:
      return Evaluator::Normalization;
    case Output::E_sheen:
      return Evaluator::Sheen;
    case Output::E_burley:
      return Evaluator::Burley;
    case Output::E_oren_nayar:
      return Evaluator::OrenNayar;
    case Output::F_dielectric:
    case Output::F_avg:
    case Output::E_refl:
    case Output::E_trans:
    case Output::E_dielectric:
      return Evaluator::Dielectric;
  }
  return Evaluator::Specular;
}

// What to compute, and where each output goes (-1: not asked for).
struct Plan {
  IntegratorOptions io;
  std::vector<size_t> stride, count;  // row = sum_a i_a stride_a, first input fastest
  int ax_mu = -1, ax_r = -1, ax_eta = -1;
  std::array<int, kNumOutputs> col{};              // per Output, its column in the table
  std::array<bool, kNumEvaluators> evaluators{};  // per Evaluator, whether an output needs it
  bool split = false, eavg = false;

  int at(Output o) const { return col[static_cast<size_t>(o)]; }
  bool wants(Output o) const { return at(o) >= 0; }
  bool runs(Evaluator e) const { return evaluators[static_cast<size_t>(e)]; }
  size_t index(size_t row, int axis) const { return (row / stride[axis]) % count[axis]; }
};

Plan makePlan(const Scene& s) {
  Plan p;
  p.io.kind = s.accuracy.integrator;
  p.io.abs_tol = 0.5 * s.accuracy.abs_error;  // the estimates are conservative; keep a margin
  p.io.order = s.accuracy.gauss_order;
  p.io.qmc_points = s.accuracy.qmc_points;
  size_t stride = 1;
  for (size_t a = 0; a < s.grid.size(); ++a) {
    p.stride.push_back(stride);
    p.count.push_back(s.grid[a].values.size());
    stride *= s.grid[a].values.size();
    const std::string& n = s.grid[a].name;
    if (n == "mu") p.ax_mu = static_cast<int>(a);
    if (n == "r") p.ax_r = static_cast<int>(a);
    if (n == "eta") p.ax_eta = static_cast<int>(a);
  }
  p.col.fill(-1);
  for (size_t k = 0; k < s.outputs.size(); ++k)
    if (const OutputSpec* o = findOutput(s.outputs[k])) {
      p.col[static_cast<size_t>(o->id)] = static_cast<int>(k);
      p.evaluators[static_cast<size_t>(evaluatorOf(o->id))] = true;
    }
  // E_avg is the Eavg evaluator's; ms_lobe needs it too.
  p.eavg = p.wants(Output::E_avg) || p.wants(Output::ms_lobe);
  p.split = s.needs(Effect::Fresnel);
  return p;
}

// The shared state of one parallel pass: per-thread counters and convergence, and the stop
// request (GenerateOptions::stop, polled before each integral; once seen, the remaining
// iterations are skipped).
struct Pass {
  int nt;
  std::vector<Counters> counters;
  std::vector<char> conv;
  const std::function<bool()>& stop;
  std::atomic<bool> stopped{false};

  Pass(int threads, const std::function<bool()>& s)
      : nt(threads), counters(threads), conv(threads, 1), stop(s) {}
  bool stopping() {
    if (stopped.load(std::memory_order_relaxed)) return true;
    if (stop && stop()) stopped.store(true, std::memory_order_relaxed);
    return stopped.load(std::memory_order_relaxed);
  }
};

// One value per grid point of one axis, integrated in parallel before the rows; only at the
// points `need` marks (all when it is empty).
struct PerAxis {
  std::vector<double> value, error;
};
PerAxis perAxis(const std::vector<double>& xs, const std::vector<char>& need, Pass& pass,
                const std::function<void(double, Counters&, double&, double&, bool&)>& f) {
  PerAxis out{std::vector<double>(xs.size()), std::vector<double>(xs.size())};
#pragma omp parallel for schedule(dynamic) num_threads(pass.nt)
  for (long j = 0; j < static_cast<long>(xs.size()); ++j) {
    if ((!need.empty() && !need[j]) || pass.stopping()) continue;
    const int t = omp_get_thread_num();
    bool ok = true;
    f(xs[j], pass.counters[t], out.value[j], out.error[j], ok);
    if (!ok) pass.conv[t] = 0;
  }
  return out;
}

// The value every output starts at: a NaN with a payload no arithmetic makes, so that a value
// no evaluator wrote is told apart from a NaN an integral produced.
constexpr uint64_t kUnwrittenBits = 0x7ff80000c0ffee00ull;
double unwritten() {
  return std::bit_cast<double>(kUnwrittenBits);
}
bool isUnwritten(double v) {
  return std::bit_cast<uint64_t>(v) == kUnwrittenBits;
}

// Where the outputs of table row `row` go: slot `slot` of every output's value and error.
struct RowSink {
  std::vector<std::vector<double>>& value;
  std::vector<std::vector<double>>& error;
  size_t row, slot;
  void put(int k, double v, double e) const {
    if (k < 0) return;
    value[k][slot] = v;
    error[k][slot] = e;
  }
};

// ms_lobe = (1 - E) / sqrt(pi d), d = 1 - E_avg, multiplies E's error by 1 / sqrt(pi d) and
// E_avg's by (1 - E) / (2 sqrt(pi) d^1.5) <= 1 / (2 sqrt(pi) d^1.5): for a sharp lobe
// (d ~ 1e-4) the integrals are resolved that much further (down to 1e-10 for both; beyond
// that the estimate says what is left: at r < 0.25 the target of a 1e-6 table is out of
// reach), with four times the evaluation budget for that second E_avg.
EavgValue eAvgFor(double alpha, Visibility vis, const IntegratorOptions& io, bool ms_lobe,
                  Counters& c) {
  EavgValue e = eAvg(alpha, vis, io, &c);
  const double d = 1.0 - e.value;
  if (!ms_lobe || !(d > 0.0)) return e;
  const double need = io.abs_tol * std::sqrt(std::numbers::pi) * d * std::sqrt(d);
  if (e.error <= need) return e;
  IntegratorOptions tight = io;
  tight.abs_tol = std::max(1e-10, 0.5 * need);
  tight.max_evals = 4 * io.max_evals;
  const uint64_t before = e.evals;
  e = eAvg(alpha, vis, tight, &c);
  e.evals += before;
  return e;
}

// The dfg family and the energy terms built from E at (mu, r). ms_turquin = (1 - E) / E
// multiplies E's error by 1 / E^2 (up to 11 at r = 1, mu = 1): a second pass tightens E there.
bool rowSpecular(const Plan& p, const Material& m, double mu, double r, const PerAxis& eavg,
                 size_t ir, const RowSink& out, Counters& c) {
  IntegratorOptions io = p.io;
  if (p.wants(Output::ms_lobe) && eavg.value[ir] < 1.0)  // see eAvgFor
    io.abs_tol = std::max(
        1e-10, io.abs_tol * std::min(1.0, std::sqrt(std::numbers::pi * (1.0 - eavg.value[ir]))));
  DfgValue d = dfgPoint(mu, m.alpha(r), m.visibility, p.split, io, &c);
  if (p.wants(Output::ms_turquin) && d.E > 0.0 && d.err_E > p.io.abs_tol * d.E * d.E) {
    io.abs_tol = std::min(io.abs_tol, 0.5 * p.io.abs_tol * d.E * d.E);
    d = dfgPoint(mu, m.alpha(r), m.visibility, p.split, io, &c);
  }
  out.put(p.at(Output::A), d.A, d.err_A);
  out.put(p.at(Output::B), d.B, d.err_B);
  out.put(p.at(Output::E), d.E, d.err_E);
  out.put(p.at(Output::one_minus_E), 1.0 - d.E, d.err_E);
  const DerivedValue t = msTurquin(d.E, d.err_E);
  out.put(p.at(Output::ms_turquin), t.value, t.error);
  if (p.wants(Output::ms_lobe)) {
    const DerivedValue l = msLobe(d.E, d.err_E, eavg.value[ir], eavg.error[ir]);
    out.put(p.at(Output::ms_lobe), l.value, l.error);
  }
  return d.converged;
}

bool rowZh(const Plan& p, const Material& m, double mu, double r, const RowSink& out, Counters& c) {
  const ZhValue z = zhPoint(mu, r, m.diffuse, p.io, &c);
  out.put(p.at(Output::ZH0), z.zh0, z.err_zh0);
  out.put(p.at(Output::ZH1), z.zh1, z.err_zh1);
  out.put(p.at(Output::ZH2), z.zh2, z.err_zh2);
  out.put(p.at(Output::ZH1_over_ZH0), z.ratio1, z.err_ratio1);
  out.put(p.at(Output::ZH2_over_ZH0), z.ratio2, z.err_ratio2);
  out.put(p.at(Output::beta), z.beta, z.err_beta);
  return z.converged;
}

bool rowDielectric(const Plan& p, const Material& m, double mu, double r, double eta,
                   const PerAxis& favg, size_t ieta, const RowSink& out, Counters& c) {
  if (p.wants(Output::F_dielectric)) out.put(p.at(Output::F_dielectric), fresnelDielectric(mu, eta), kRoundoff);
  if (p.wants(Output::F_avg)) out.put(p.at(Output::F_avg), favg.value[ieta], favg.error[ieta]);
  const bool refl = p.wants(Output::E_refl) || p.wants(Output::E_dielectric);
  const bool trans = p.wants(Output::E_trans) || p.wants(Output::E_dielectric);
  if (!refl && !trans) return true;
  const DielectricValue d =
      dielectricPoint(mu, m.alpha(r), eta, m.visibility, m.transmission, refl, trans, p.io, &c);
  out.put(p.at(Output::E_refl), d.refl, d.err_refl);
  out.put(p.at(Output::E_trans), d.trans, d.err_trans);
  out.put(p.at(Output::E_dielectric), d.refl + d.trans, d.err_refl + d.err_trans);
  return d.converged;
}

// Every output of one row; false if an integral did not converge.
bool evalRow(const Scene& s, const Plan& p, const PerAxis& eavg, const PerAxis& favg,
             const RowSink& out, Counters& c) {
  const Material& m = s.material;
  const size_t row = out.row;
  if (p.runs(Evaluator::Normalization)) {
    const double r = s.grid[0].values[p.index(row, 0)];
    const double x1 = s.grid[1].values[p.index(row, 1)];
    const double theta = s.light.size == "theta_s" ? x1 : 2.0 * std::atan(x1);
    const NormalizationValue nv =
        normalizationPoint(m.alpha(r), theta, m.visibility, s.light.softmin_s, p.io, &c);
    out.put(p.at(Output::N), nv.N, nv.error);
    return nv.converged;
  }
  auto at = [&](int axis, double dflt) {
    return axis < 0 ? dflt : s.grid[axis].values[p.index(row, axis)];
  };
  const double mu = at(p.ax_mu, 1.0), r = at(p.ax_r, 0.0), eta = at(p.ax_eta, 1.0);
  const size_t ir = p.ax_r < 0 ? 0 : p.index(row, p.ax_r);
  const size_t ieta = p.ax_eta < 0 ? 0 : p.index(row, p.ax_eta);
  bool ok = true;
  if (p.runs(Evaluator::Specular)) ok = rowSpecular(p, m, mu, r, eavg, ir, out, c) && ok;
  if (p.runs(Evaluator::Eavg)) out.put(p.at(Output::E_avg), eavg.value[ir], eavg.error[ir]);
  if (p.runs(Evaluator::Zh)) ok = rowZh(p, m, mu, r, out, c) && ok;
  if (p.runs(Evaluator::Sheen)) {
    const SheenValue v = sheenPoint(mu, m.alpha(r), p.io, &c);
    out.put(p.at(Output::E_sheen), v.E, v.error);
    ok = v.converged && ok;
  }
  if (p.runs(Evaluator::Burley)) {
    const AlbedoValue v = burleyAlbedo(mu, r, &c);
    out.put(p.at(Output::E_burley), v.E, v.error);
  }
  if (p.runs(Evaluator::OrenNayar)) {
    const AlbedoValue v = orenNayarAlbedo(mu, r, &c);
    out.put(p.at(Output::E_oren_nayar), v.E, v.error);
  }
  if (p.runs(Evaluator::Dielectric)) ok = rowDielectric(p, m, mu, r, eta, favg, ieta, out, c) && ok;
  return ok;
}

// Every value finite; the largest estimate per output (and overall) into `max_by`.
Status checkAndSummarize(const Scene& s, GeneratedTable& g, json& max_by) {
  max_by = json::object();
  for (size_t k = 0; k < s.outputs.size(); ++k) {
    double mx = 0;
    for (size_t row = 0; row < g.table.rows(); ++row) {
      if (isUnwritten(g.table.outputs[k][row]))
        return Status::error("no evaluator wrote " + s.outputs[k] +
                             " (datasets/src/generate.cpp: evaluatorOf and its evaluator)");
      if (!std::isfinite(g.table.outputs[k][row])) {
        // The shortest form that reads back to the grid's value: it names the point (r =
        // 5e-324, not 0.000000).
        std::string at;
        for (size_t a = 0; a < s.grid.size(); ++a)
          at += (a ? ", " : "") + s.grid[a].name + "=" + formatDouble(g.table.inputs[a][row]);
        return Status::error("generator produced a non-finite " + s.outputs[k] + " at " + at +
                             " (row " + std::to_string(row + 1) + ")");
      }
      mx = std::max(mx, g.errors[k][row]);
    }
    max_by[s.outputs[k]] = mx;
    g.max_error = std::max(g.max_error, mx);
  }
  return Status::ok();
}
}  // namespace

namespace {
// Evaluates the table rows `rows` (every row when it is empty) into slots 0, 1, ... of
// `value` and `error` ([output][slot], sized by the caller); the per-axis integrals run only
// where those rows need them.
Status evaluate(const Scene& s, const Plan& p, const std::vector<size_t>& rows,
                const GenerateOptions& opt, std::vector<std::vector<double>>& value,
                std::vector<std::vector<double>>& error, Counters& counters, bool& converged) {
  const size_t n = rows.empty() ? s.rows() : rows.size();
  auto rowAt = [&](size_t i) { return rows.empty() ? i : rows[i]; };
  auto axisNeed = [&](int axis) {
    std::vector<char> need;
    if (rows.empty() || axis < 0) return need;
    need.assign(p.count[axis], 0);
    for (size_t r : rows) need[p.index(r, axis)] = 1;
    return need;
  };
  // Never more threads than the cores this process may use (a request for thousands would
  // exhaust the address space or the thread limit, which ends the process in OpenMP).
  const int cores = std::max(1, omp_get_num_procs());
  Pass pass(std::min(opt.threads > 0 ? opt.threads : omp_get_max_threads(), cores), opt.stop);
  const Material& m = s.material;
  PerAxis eavg, favg;
  if (p.eavg)
    eavg = perAxis(s.axis("r")->values, axisNeed(p.ax_r), pass,
                   [&](double r, Counters& c, double& v, double& e, bool& ok) {
                     const EavgValue x = eAvgFor(m.alpha(r), m.visibility, p.io, p.wants(Output::ms_lobe), c);
                     v = x.value, e = x.error, ok = x.converged;
                   });
  if (p.wants(Output::F_avg))
    favg = perAxis(s.axis("eta")->values, axisNeed(p.ax_eta), pass,
                   [&](double eta, Counters& c, double& v, double& e, bool& ok) {
                     const FavgValue x = fresnelAverageDielectric(eta, p.io, &c);
                     v = x.value, e = x.error, ok = x.converged;
                   });
#pragma omp parallel for schedule(dynamic) num_threads(pass.nt)
  for (long i = 0; i < static_cast<long>(n); ++i) {
    if (pass.stopping()) continue;
    const int t = omp_get_thread_num();
    const RowSink out{value, error, rowAt(static_cast<size_t>(i)), static_cast<size_t>(i)};
    if (!evalRow(s, p, eavg, favg, out, pass.counters[t])) pass.conv[t] = 0;
  }
  if (pass.stopped.load()) return Status::error(kGenerationStopped);
  for (int t = 0; t < pass.nt; ++t) {
    counters.add(pass.counters[t]);
    converged = converged && pass.conv[t];
  }
  return Status::ok();
}
}  // namespace

Expected<GeneratedTable> generate(const Scene& s, const GenerateOptions& opt) {
  if (s.grid.empty() || s.grid.size() > 3 || s.outputs.empty())
    return Status::error("scene: needs one to three grid inputs and at least one output");
  const Plan p = makePlan(s);
  GeneratedTable g;
  const size_t rows = s.rows(), K = s.outputs.size();
  g.table.input_names = s.inputNames();
  g.table.output_names = s.outputs;
  g.table.inputs.assign(s.grid.size(), std::vector<double>(rows));
  g.table.outputs.assign(K, std::vector<double>(rows, unwritten()));
  g.errors.assign(K, std::vector<double>(rows));
  for (size_t row = 0; row < rows; ++row)
    for (size_t a = 0; a < s.grid.size(); ++a)
      g.table.inputs[a][row] = s.grid[a].values[p.index(row, static_cast<int>(a))];
  if (auto st = evaluate(s, p, {}, opt, g.table.outputs, g.errors, g.counters, g.converged); !st)
    return st;
  json max_by;
  if (auto st = checkAndSummarize(s, g, max_by); !st) return st;
  g.table.meta = detail::tableMeta(s, p.io, g, max_by);
  return g;
}

Expected<RowValues> generateRows(const Scene& s, const std::vector<size_t>& rows,
                                 const GenerateOptions& opt) {
  if (s.grid.empty() || s.grid.size() > 3 || s.outputs.empty())
    return Status::error("scene: needs one to three grid inputs and at least one output");
  for (size_t r : rows)
    if (r >= s.rows()) return Status::error("row " + std::to_string(r) + " is not in the scene");
  if (rows.empty()) return RowValues{};
  const Plan p = makePlan(s);
  RowValues out;
  out.value.assign(s.outputs.size(), std::vector<double>(rows.size(), unwritten()));
  out.error.assign(s.outputs.size(), std::vector<double>(rows.size()));
  Counters counters;
  bool converged = true;
  if (auto st = evaluate(s, p, rows, opt, out.value, out.error, counters, converged); !st)
    return st;
  return out;
}

}  // namespace lgp::datasets
