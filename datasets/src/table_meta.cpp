#include "table_meta.hpp"

namespace lgp::datasets::detail {

namespace {
using nlohmann::json;

json gridMeta(const Scene& s) {
  json grid = json::object();
  for (const auto& a : s.grid) {
    json ga = {{"spacing", a.spacing}, {"count", a.values.size()}, {"values", a.values}};
    if (a.spacing != "values") ga["range"] = {a.lo, a.hi};
    grid[a.name] = ga;
  }
  // row = i_0 + n_0 * i_1 (+ n_0 n_1 * i_2)
  std::string order = "row = i_" + s.grid[0].name;
  std::string stride;
  for (size_t a = 1; a < s.grid.size(); ++a) {
    stride += (stride.empty() ? "" : " * ") + std::to_string(s.grid[a - 1].values.size());
    order += " + " + stride + " * i_" + s.grid[a].name;
  }
  grid["row_order"] = order + " (first input fastest)";
  return grid;
}

json integratorMeta(const Scene& s, const IntegratorOptions& io) {
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
  std::string space =
      "dfg/energy: GGX half-vector CDF space; zh: (theta_l, phi); N: mu and theta_v";
  if (s.needs(Effect::Sheen)) space += "; sheen: (theta_l, phi_l)";
  if (s.needs(Effect::DiffuseAlbedo))
    space +=
        "; diffuse albedo: exact (Burley: 8-node Gauss-Legendre of a degree-8 polynomial; "
        "Oren-Nayar: closed form)";
  if (s.needs(Effect::Dielectric))
    space +=
        "; dielectric: GGX half-vector CDF space per lobe; F_avg: t with mu = mu_c + "
        "(1 - mu_c) t^2 (adaptive, F_avg always)";
  integ["space"] = space;
  return integ;
}

std::string limitsMeta(const Scene& s) {
  std::string l =
      "alpha = 0: mirror limit at fixed mu (E = 1, A = 1 - (1 - mu)^5, B = (1 - mu)^5); "
      "mu = 0: limit mu -> 0; N(theta_s = 0) = 1, N(alpha = 0, theta_s > 0) = 0; "
      "beta(mu = 1): limit theta_v -> 0";
  if (s.needs(Effect::Energy) && (s.wants("ms_turquin") || s.wants("ms_lobe")))
    l += "; ms_turquin and ms_lobe: 0 at alpha = 0";
  if (s.needs(Effect::Sheen)) l += "; E_sheen: 0 at alpha = 0 (mu > 0)";
  if (s.needs(Effect::Dielectric))
    l += "; dielectric at alpha = 0: E_refl = F(mu), E_trans = 1 - F(mu) (flux) or "
         "(1 - F) / eta^2 (radiance); eta = 1: F = 0";
  return l;
}

json sampleCounts(const Counters& c) {
  json j = {{"total", c.total()},
            {"specular", c.specular},
            {"fresnel", c.fresnel},
            {"diffuse", c.diffuse},
            {"rep_point", c.rep_point}};
  // Only where used, so that the tables of the older effects keep their metadata.
  if (c.sheen) j["sheen"] = c.sheen;
  if (c.dielectric) j["dielectric"] = c.dielectric;
  return j;
}
}  // namespace

json tableMeta(const Scene& s, const IntegratorOptions& io, const GeneratedTable& g,
               const json& max_by_output) {
  json defs = json::object();
  for (const auto& o : s.outputs) defs[o] = findOutput(o)->definition;
  return {
      {"generated_by", std::string("lgp data (") + kGeneratorVersion + "): generated, do not edit"},
      {"generator_version", kGeneratorVersion},
      {"definition", defs},
      {"scene", toJson(s)},
      {"grid", gridMeta(s)},
      {"integrator", integratorMeta(s, io)},
      {"sample_counts", sampleCounts(g.counters)},
      {"max_estimated_error", g.max_error},
      {"max_estimated_error_by_output", max_by_output},
      {"accuracy_target", s.accuracy.abs_error},
      {"target_met", g.max_error <= s.accuracy.abs_error},
      {"converged", g.converged},
      {"limits", limitsMeta(s)}};
}

}  // namespace lgp::datasets::detail
