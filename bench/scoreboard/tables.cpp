// The training table of a row's run config and its held-out grid. The held-out grid takes the
// midpoints between neighbouring training points on every axis: every point is new, none lies
// outside the training domain, and the same integrator computes it.
#include <algorithm>

#include "board.hpp"
#include "lgp/datasets/generate.hpp"

namespace lgp::board {

namespace {
namespace ds = lgp::datasets;
using nlohmann::json;

std::vector<double> sortedValues(const ds::GridAxis& a) {
  std::vector<double> v = a.values;
  std::sort(v.begin(), v.end());
  v.erase(std::unique(v.begin(), v.end()), v.end());
  return v;
}

// At most `n` of the values, evenly spread, both ends kept.
std::vector<double> thinned(const std::vector<double>& v, size_t n) {
  if (v.size() <= n) return v;
  std::vector<double> out;
  for (size_t i = 0; i < n; ++i) out.push_back(v[i * (v.size() - 1) / (n - 1)]);
  return out;
}

std::vector<double> midpoints(const std::vector<double>& v) {
  if (v.size() < 2) return v;
  std::vector<double> out;
  for (size_t i = 0; i + 1 < v.size(); ++i) out.push_back(0.5 * (v[i] + v[i + 1]));
  return out;
}

// The scene with every axis replaced by explicit values f(axis).
template <class F>
Expected<ds::Scene> regridded(const ds::Scene& s, F f, double min_abs_error,
                              const std::string& origin) {
  json j = ds::toJson(s);
  for (const auto& a : s.grid) j["grid"][a.name] = {{"values", f(sortedValues(a))}};
  if (j["accuracy"]["abs_error"].get<double>() < min_abs_error)
    j["accuracy"]["abs_error"] = min_abs_error;
  return ds::parseScene(j, origin);
}

std::string describe(const ds::Scene& s) {
  std::string d;
  for (const auto& a : s.grid) {
    const auto v = sortedValues(a);
    char b[160];
    std::snprintf(b, sizeof b, "%s%s: %zu in [%.4g, %.4g]", d.empty() ? "" : ", ", a.name.c_str(),
                  v.size(), v.front(), v.back());
    d += b;
  }
  return d + "; " + std::to_string(s.rows()) + " rows";
}

Expected<Table> tableOf(const ds::Scene& s, const RunConfig& cfg, const Options& o,
                        const std::string& origin) {
  auto g = ds::generateCached(s, o.cache_dir.empty() ? ds::defaultCacheDir() : o.cache_dir);
  if (!g) return Status::error(origin + ": " + g.error());
  if (!g->table.converged || !g->table.table.meta.value("target_met", false))
    std::fprintf(stderr, "lgp_scoreboard: warning: %s: accuracy target not met (%.3g)\n",
                 origin.c_str(), g->table.max_error);
  return selectColumns(ds::toRawTable(g->table), cfg.data.inputs, cfg.data.outputs,
                       cfg.data.weights, origin);
}
}  // namespace

Status loadTables(TableRun& r, const std::filesystem::path& spec_dir, const Options& o) {
  (void)spec_dir;
  if (r.cfg.data.scene.empty())
    return Status::error(r.spec.config + ": /data/scene: the board needs a generated table");
  const std::filesystem::path path = r.cfg.base_dir / r.cfg.data.scene;
  auto scene = ds::loadScene(path);
  if (!scene) return scene.status();
  ds::Scene train = *scene;
  if (o.quick) {
    auto q = regridded(
        *scene, [](const std::vector<double>& v) { return thinned(v, 5); }, 1e-4, path.string());
    if (!q) return q.status();
    train = *q;
  }
  auto held = regridded(train, midpoints, 0, path.string() + " (held out)");
  if (!held) return held.status();
  auto t = tableOf(train, r.cfg, o, path.string());
  if (!t) return t.status();
  auto h = tableOf(*held, r.cfg, o, path.string() + " (held out)");
  if (!h) return h.status();
  r.train = std::move(*t);
  r.heldout = std::move(*h);
  r.train_desc = describe(train);
  r.heldout_desc = describe(*held);
  return Status::ok();
}

}  // namespace lgp::board
