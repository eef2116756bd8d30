#include "lgp/datasets/generate.hpp"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <map>

#include "lgp/datasets/dfg.hpp"
#include "lgp/datasets/energy.hpp"
#include "lgp/datasets/normalization.hpp"
#include "lgp/datasets/zh.hpp"

namespace lgp::datasets {

namespace {
using nlohmann::json;

const std::map<std::string, std::string>& definitions() {
  static const std::map<std::string, std::string> d = {
      {"A", "integral_H D G2 (1 - (1 - v.h)^5) / (4 (n.l)(n.v)) (n.l) dl  (scale on F0)"},
      {"B", "integral_H D G2 (1 - v.h)^5 / (4 (n.l)(n.v)) (n.l) dl  (bias, times F90)"},
      {"E", "integral_H D G2 / (4 (n.l)(n.v)) (n.l) dl  (directional albedo, F = 1)"},
      {"one_minus_E", "1 - E(mu, r)"},
      {"E_avg", "2 integral_0^1 E(mu, r) mu dmu"},
      {"ZH0", "0.2820948 integral CBRDF(w) dw"},
      {"ZH1", "0.4886025 integral CBRDF(w) (d.w) dw,  d = normalized first moment of CBRDF"},
      {"ZH2", "0.3153916 integral CBRDF(w) (3 (d.w)^2 - 1) dw"},
      {"ZH1_over_ZH0", "ZH1 / ZH0"},
      {"ZH2_over_ZH0", "ZH2 / ZH0"},
      {"beta", "d = normalize((1 - beta) n + beta v)"},
      {"N",
       "[2 integral_{cos ts}^1 E(mu) mu dmu] / [2 pi sin^2(ts) integral_0^1 f(l_rep(v), v) "
       "(n.l_rep) mu_v dmu_v]; light centred on n, l_rep = smoothed representative point, "
       "F = 1 (see datasets/README.md)"}};
  return d;
}

double thetaOf(const Scene& s, double x) {
  return s.light.size == "theta_s" ? x : 2.0 * std::atan(x);
}
}  // namespace

Expected<GeneratedTable> generate(const Scene& s, const GenerateOptions& opt) {
  if (s.grid.size() != 2 || s.outputs.empty())
    return Status::error("scene: needs two grid inputs and at least one output");
  GeneratedTable g;
  const size_t n0 = s.grid[0].values.size(), n1 = s.grid[1].values.size();
  const size_t rows = n0 * n1;
  const size_t K = s.outputs.size();
  IntegratorOptions io;
  io.kind = s.accuracy.integrator;
  io.abs_tol = 0.5 * s.accuracy.abs_error;  // the estimates are conservative; keep a margin
  io.order = s.accuracy.gauss_order;
  io.qmc_points = s.accuracy.qmc_points;
  const Material& m = s.material;
  const bool want_n = s.needs(Effect::Normalization);
  const bool want_spec = s.wants("A") || s.wants("B") || s.wants("E") || s.wants("one_minus_E");
  const bool split = s.needs(Effect::Fresnel);
  const bool want_zh = s.needs(Effect::Diffuse);
  const bool want_eavg = s.wants("E_avg");

  g.table.input_names = s.inputNames();
  g.table.output_names = s.outputs;
  g.table.inputs.assign(2, std::vector<double>(rows));
  g.table.outputs.assign(K, std::vector<double>(rows));
  g.errors.assign(K, std::vector<double>(rows));
  for (size_t row = 0; row < rows; ++row) {
    g.table.inputs[0][row] = s.grid[0].values[row % n0];
    g.table.inputs[1][row] = s.grid[1].values[row / n0];
  }
  const int nt = opt.threads > 0 ? opt.threads : omp_get_max_threads();
  std::vector<Counters> counters(nt);
  std::vector<char> conv(nt, 1);

  std::vector<double> eavg(n1, 0.0), eavg_err(n1, 0.0);
  if (want_eavg) {
#pragma omp parallel for schedule(dynamic) num_threads(nt)
    for (long j = 0; j < static_cast<long>(n1); ++j) {
      const int t = omp_get_thread_num();
      const EavgValue e = eAvg(m.alpha(s.grid[1].values[j]), m.visibility, io, &counters[t]);
      eavg[j] = e.value;
      eavg_err[j] = e.error;
      if (!e.converged) conv[t] = 0;
    }
  }

  auto col = [&](const char* name) -> int {
    for (size_t k = 0; k < K; ++k)
      if (s.outputs[k] == name) return static_cast<int>(k);
    return -1;
  };
  const int cA = col("A"), cB = col("B"), cE = col("E"), c1E = col("one_minus_E"),
            cEa = col("E_avg"), cZ0 = col("ZH0"), cZ1 = col("ZH1"), cZ2 = col("ZH2"),
            cR1 = col("ZH1_over_ZH0"), cR2 = col("ZH2_over_ZH0"), cBeta = col("beta"),
            cN = col("N");

#pragma omp parallel for schedule(dynamic) num_threads(nt)
  for (long row = 0; row < static_cast<long>(rows); ++row) {
    const int t = omp_get_thread_num();
    Counters& c = counters[t];
    const double x0 = g.table.inputs[0][row], x1 = g.table.inputs[1][row];
    auto put = [&](int k, double v, double e) {
      if (k < 0) return;
      g.table.outputs[k][row] = v;
      g.errors[k][row] = e;
    };
    if (want_n) {
      const NormalizationValue nv =
          normalizationPoint(m.alpha(x0), thetaOf(s, x1), m.visibility, s.light.softmin_s, io, &c);
      put(cN, nv.N, nv.error);
      if (!nv.converged) conv[t] = 0;
      continue;
    }
    const double mu = x0, r = x1;
    if (want_spec) {
      const DfgValue d = dfgPoint(mu, m.alpha(r), m.visibility, split, io, &c);
      put(cA, d.A, d.err_A);
      put(cB, d.B, d.err_B);
      put(cE, d.E, d.err_E);
      put(c1E, 1.0 - d.E, d.err_E);
      if (!d.converged) conv[t] = 0;
    }
    if (want_eavg) put(cEa, eavg[row / n0], eavg_err[row / n0]);
    if (want_zh) {
      const ZhValue z = zhPoint(mu, r, m.diffuse, io, &c);
      put(cZ0, z.zh0, z.err_zh0);
      put(cZ1, z.zh1, z.err_zh1);
      put(cZ2, z.zh2, z.err_zh2);
      put(cR1, z.ratio1, z.err_ratio1);
      put(cR2, z.ratio2, z.err_ratio2);
      put(cBeta, z.beta, z.err_beta);
      if (!z.converged) conv[t] = 0;
    }
  }
  for (int t = 0; t < nt; ++t) {
    g.counters.add(counters[t]);
    g.converged = g.converged && conv[t];
  }
  json max_by = json::object();
  for (size_t k = 0; k < K; ++k) {
    double mx = 0;
    for (size_t row = 0; row < rows; ++row) {
      if (!std::isfinite(g.table.outputs[k][row]))
        return Status::error("generator produced a non-finite " + s.outputs[k] + " at " +
                             s.grid[0].name + "=" + std::to_string(g.table.inputs[0][row]) + ", " +
                             s.grid[1].name + "=" + std::to_string(g.table.inputs[1][row]));
      mx = std::max(mx, g.errors[k][row]);
    }
    max_by[s.outputs[k]] = mx;
    g.max_error = std::max(g.max_error, mx);
  }

  json defs = json::object();
  for (const auto& o : s.outputs) defs[o] = definitions().at(o);
  json grid = json::object();
  for (const auto& a : s.grid) {
    json ga = {{"spacing", a.spacing}, {"count", a.values.size()}, {"values", a.values}};
    if (a.spacing != "values") ga["range"] = {a.lo, a.hi};
    grid[a.name] = ga;
  }
  grid["row_order"] = "row = i_" + s.grid[0].name + " + " + std::to_string(n0) + " * i_" +
                      s.grid[1].name + " (first input fastest)";
  json integ = {{"method", toString(io.kind)}};
  switch (io.kind) {
    case IntegratorKind::Adaptive:
      integ["abs_tol_per_integral"] = io.abs_tol;
      integ["points_per_dim_per_region"] = io.adaptive_order;
      integ["max_evals_per_integral"] = io.max_evals;
      integ["error_estimate"] =
          "sum over regions of |Q_region - Q_children|, scaled up where a region is unresolved "
          "(max(raw, resasc min(1, (20 raw / resasc)^1.5))), plus a rounding floor of 64 eps int "
          "|f|";
      break;
    case IntegratorKind::Gauss:
      integ["order"] = io.order;
      integ["error_estimate"] =
          "sum over boxes of |Q_n - Q_2n|, plus a rounding floor of 64 eps int |f|";
      break;
    case IntegratorKind::Qmc:
      integ["points_per_shift"] = io.qmc_points;
      integ["shifts"] = io.qmc_shifts;
      integ["error_estimate"] = "3 standard errors over the random shifts";
      break;
  }
  integ["space"] = "dfg/energy: GGX half-vector CDF space; zh: (theta_l, phi); N: mu and theta_v";
  g.table.meta = {
      {"generated_by", std::string("lgp data (") + kGeneratorVersion + "): generated, do not edit"},
      {"generator_version", kGeneratorVersion},
      {"definition", defs},
      {"scene", toJson(s)},
      {"grid", grid},
      {"integrator", integ},
      {"sample_counts",
       {{"total", g.counters.total()},
        {"specular", g.counters.specular},
        {"fresnel", g.counters.fresnel},
        {"diffuse", g.counters.diffuse},
        {"rep_point", g.counters.rep_point}}},
      {"max_estimated_error", g.max_error},
      {"max_estimated_error_by_output", max_by},
      {"accuracy_target", s.accuracy.abs_error},
      {"target_met", g.max_error <= s.accuracy.abs_error},
      {"converged", g.converged},
      {"limits",
       "alpha = 0: mirror limit at fixed mu (E = 1, A = 1 - (1 - mu)^5, B = (1 - mu)^5); "
       "mu = 0: limit mu -> 0; N(theta_s = 0) = 1, N(alpha = 0, theta_s > 0) = 0; "
       "beta(mu = 1): limit theta_v -> 0"}};
  return g;
}

json toTableJson(const GeneratedTable& g) {
  const Table& t = g.table;
  json j;
  j["format"] = "lgp-table/1";
  j["inputs"] = t.input_names;
  j["outputs"] = t.output_names;
  j["columns"] = json::object();
  for (size_t i = 0; i < t.input_names.size(); ++i) j["columns"][t.input_names[i]] = t.inputs[i];
  for (size_t k = 0; k < t.output_names.size(); ++k) j["columns"][t.output_names[k]] = t.outputs[k];
  if (!t.weights.empty()) j["weights"] = t.weights;
  j["errors"] = json::object();
  for (size_t k = 0; k < t.output_names.size() && k < g.errors.size(); ++k)
    j["errors"][t.output_names[k]] = g.errors[k];
  j["meta"] = t.meta;
  return j;
}

Expected<GeneratedTable> fromTableJson(const json& j, const std::string& origin) {
  try {
    if (j.value("format", std::string()) != "lgp-table/1")
      return Status::error(origin + ": /format: not an lgp-table/1 table");
    GeneratedTable g;
    g.table.input_names = j.at("inputs").get<std::vector<std::string>>();
    g.table.output_names = j.at("outputs").get<std::vector<std::string>>();
    const json& cols = j.at("columns");
    size_t rows = 0;
    bool first = true;
    auto column = [&](const std::string& name) -> Expected<std::vector<double>> {
      if (!cols.contains(name)) return Status::error(origin + ": /columns/" + name + ": missing");
      auto v = cols.at(name).get<std::vector<double>>();
      if (first) rows = v.size(), first = false;
      if (v.size() != rows) return Status::error(origin + ": /columns/" + name + ": wrong length");
      for (size_t i = 0; i < v.size(); ++i)
        if (!std::isfinite(v[i]))
          return Status::error(origin + ": /columns/" + name + "/" + std::to_string(i) +
                               ": not finite");
      return v;
    };
    for (const auto& n : g.table.input_names) {
      auto c = column(n);
      if (!c) return c.status();
      g.table.inputs.push_back(std::move(*c));
    }
    for (const auto& n : g.table.output_names) {
      auto c = column(n);
      if (!c) return c.status();
      g.table.outputs.push_back(std::move(*c));
      std::vector<double> e(rows, 0.0);
      if (j.contains("errors") && j["errors"].contains(n)) {
        e = j["errors"][n].get<std::vector<double>>();
        if (e.size() != rows) return Status::error(origin + ": /errors/" + n + ": wrong length");
      }
      g.errors.push_back(std::move(e));
    }
    if (j.contains("weights")) g.table.weights = j["weights"].get<std::vector<double>>();
    if (j.contains("meta")) g.table.meta = j["meta"];
    const json& sc = g.table.meta.value("sample_counts", json::object());
    g.counters.specular = sc.value("specular", uint64_t{0});
    g.counters.fresnel = sc.value("fresnel", uint64_t{0});
    g.counters.diffuse = sc.value("diffuse", uint64_t{0});
    g.counters.rep_point = sc.value("rep_point", uint64_t{0});
    g.max_error = g.table.meta.value("max_estimated_error", 0.0);
    g.converged = g.table.meta.value("converged", true);
    return g;
  } catch (const json::exception& e) {
    return Status::error(origin + ": malformed table: " + e.what());
  }
}

Status writeTableCsv(const GeneratedTable& g, const std::filesystem::path& path) {
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) return Status::error(path.string() + ": cannot open for writing");
  const Table& t = g.table;
  std::string line;
  for (const auto& n : t.input_names) line += (line.empty() ? "" : ",") + n;
  for (const auto& n : t.output_names) line += "," + n;
  std::fprintf(f, "%s\n", line.c_str());
  for (size_t row = 0; row < t.rows(); ++row) {
    for (size_t i = 0; i < t.inputs.size(); ++i)
      std::fprintf(f, "%s%.17g", i ? "," : "", t.inputs[i][row]);
    for (size_t k = 0; k < t.outputs.size(); ++k) std::fprintf(f, ",%.17g", t.outputs[k][row]);
    std::fprintf(f, "\n");
  }
  const bool ok = std::fclose(f) == 0;
  return ok ? Status::ok() : Status::error(path.string() + ": write failed");
}

RawTable toRawTable(const GeneratedTable& g) {
  RawTable r;
  const Table& t = g.table;
  for (size_t i = 0; i < t.input_names.size(); ++i) {
    r.names.push_back(t.input_names[i]);
    r.columns.push_back(t.inputs[i]);
  }
  for (size_t k = 0; k < t.output_names.size(); ++k) {
    r.names.push_back(t.output_names[k]);
    r.columns.push_back(t.outputs[k]);
  }
  r.default_inputs = t.input_names;
  r.default_outputs = t.output_names;
  r.weights = t.weights;
  r.meta = t.meta;
  return r;
}

}  // namespace lgp::datasets
