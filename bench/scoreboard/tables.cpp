// The training table of a row's run config and its held-out set: per axis the midpoints
// between neighbouring training points, the declared domain's edges and random values, as a
// product grid computed by the same integrator. Every point but an edge shared with the
// training grid is new, and the set reaches where shaders evaluate (n.v down to 1e-4).
#include <algorithm>
#include <random>

#include "board.hpp"
#include "lgp/datasets/edges.hpp"
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

// The scene with every axis replaced by explicit values f(axis index, its sorted values).
template <class F>
Expected<ds::Scene> regridded(const ds::Scene& s, F f, double min_abs_error,
                              const std::string& origin) {
  json j = ds::toJson(s);
  for (size_t i = 0; i < s.grid.size(); ++i)
    j["grid"][s.grid[i].name] = {{"values", f(i, sortedValues(s.grid[i]))}};
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

Expected<RawTable> rawOf(const ds::Scene& s, const Options& o, const std::string& origin) {
  auto g = ds::generateCached(s, o.cache_dir.empty() ? ds::defaultCacheDir() : o.cache_dir);
  if (!g) return Status::error(origin + ": " + g.error());
  if (!g->table.converged || !g->table.table.meta.value("target_met", false))
    std::fprintf(stderr, "lgp_scoreboard: warning: %s: accuracy target not met (%.3g)\n",
                 origin.c_str(), g->table.max_error);
  return ds::toRawTable(g->table);
}

Expected<Table> tableOf(const ds::Scene& s, const RunConfig& cfg, const Options& o,
                        const std::string& origin) {
  auto raw = rawOf(s, o, origin);
  if (!raw) return raw.status();
  return selectColumns(*raw, cfg.data.inputs, cfg.data.outputs, cfg.data.weights, origin);
}
}  // namespace

std::vector<double> heldoutAxis(const std::vector<double>& train, double lo, double hi, int random,
                                uint64_t seed) {
  std::vector<double> v;
  for (double m : midpoints(train))
    if (m >= lo && m <= hi) v.push_back(m);
  v.push_back(lo);
  v.push_back(hi);
  const double first = train.empty() ? hi : std::max(lo, train.front());
  if (lo > 0)
    for (double x = 2 * lo; x < first; x *= 2) v.push_back(x);
  else
    for (double f : {1e-3, 1e-2}) v.push_back(lo + f * (hi - lo));
  v.push_back(hi - 1e-3 * (hi - lo));
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(lo, hi);
  for (int i = 0; i < random; ++i) v.push_back(u(rng));
  std::sort(v.begin(), v.end());
  v.erase(std::unique(v.begin(), v.end()), v.end());
  return v;
}

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
        *scene, [](size_t, const std::vector<double>& v) { return thinned(v, 5); }, 1e-4,
        path.string());
    if (!q) return q.status();
    train = *q;
  }
  std::string undeclared;
  auto held = regridded(
      train,
      [&](size_t axis, const std::vector<double>& v) {
        const auto& a = train.grid[axis];
        auto d = r.spec.domain.find(a.name);
        double lo = v.front(), hi = v.back();
        if (d != r.spec.domain.end()) {
          lo = d->second.first;
          hi = d->second.second;
        } else {
          undeclared += (undeclared.empty() ? "" : ", ") + a.name;
        }
        return heldoutAxis(v, lo, hi, o.quick ? 3 : 8, axis + 1);
      },
      0, path.string() + " (held out)");
  if (!held) return held.status();
  if (!undeclared.empty())
    std::fprintf(stderr, "lgp_scoreboard: %s: no declared domain for %s: its training range\n",
                 r.spec.name.c_str(), undeclared.c_str());
  auto t = tableOf(train, r.cfg, o, path.string());
  if (!t) return t.status();
  // The edge objective: the declared domain's edge rows join the training table (as
  // data.edges does for lgp run), generated at values the held-out set does not use. A grid
  // that already spans its declared domain (fresnel_avg) has none: it is searched as it is,
  // so that one board can run every table with the option.
  if (o.edge_objective && !ds::domainBeyondGrid(train, r.spec.domain)) {
    std::fprintf(stderr,
                 "lgp_scoreboard: %s: the training grid spans the declared domain: no edge rows\n",
                 r.spec.name.c_str());
  } else if (o.edge_objective) {
    r.cfg.data.edges.domain = r.spec.domain;
    auto es = ds::edgeScene(train, r.spec.domain, path.string() + " (edges)");
    if (!es) return es.status();
    auto raw = rawOf(*es, o, path.string() + " (edges)");
    if (!raw) return raw.status();
    if (auto st = ds::appendEdgeRows(*t, train, *raw, r.cfg.data.edges, r.cfg.data.weights,
                                     path.string() + " (edges)");
        !st)
      return st;
  }
  auto h = tableOf(*held, r.cfg, o, path.string() + " (held out)");
  if (!h) return h.status();
  r.train = std::move(*t);
  r.heldout = std::move(*h);
  r.train_desc = describe(train);
  if (o.edge_objective && !r.train.meta.contains("edges"))
    r.train_desc += " (the grid spans the declared domain: no edge rows)";
  if (r.train.meta.contains("edges"))
    r.train_desc += " + " + std::to_string(r.train.meta["edges"]["rows"].get<size_t>()) +
                    " edge rows (weight 1)";
  r.heldout_desc = describe(*held);
  return Status::ok();
}

}  // namespace lgp::board
