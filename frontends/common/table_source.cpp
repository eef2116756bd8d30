#include "table_source.hpp"

#include <algorithm>

#include "lgp/eval/objectives.hpp"
#include "lgp/io/table_file.hpp"

#if __has_include("lgp/datasets/generate.hpp")
#include "lgp/datasets/edges.hpp"
#include "lgp/datasets/generate.hpp"
#define LGP_HAVE_DATASETS 1
#endif

namespace lgp::cli {

namespace {
// A cached table that the checks below refuse (loadRunTable regenerates it once).
constexpr const char* kStaleCacheEntry = "the cached table is not usable";

// Before the search: values the float32 evaluation cannot hold would leave every error NaN
// or infinite, and the front empty; and the program shape must fit the table's outputs.
Status checkNumerics(const RunConfig& cfg, const Table& t) {
  if (auto s = checkErrorNumerics(t, cfg.errorConfig(t.output_names)); !s)
    return Status::error((cfg.data.scene.empty() ? "/data/path" : "/data/scene") +
                         std::string(": ") + s.message());
  return cfg.validateShape(t.numOutputs());
}

#ifdef LGP_HAVE_DATASETS
namespace ds = lgp::datasets;

// The columns the run selects are the scene's (the messages of selectColumns), before
// anything is generated.
Status checkSceneColumns(const ds::Scene& scene, const DataConfig& d, const std::string& origin) {
  const std::vector<std::string> inputs = scene.inputNames();
  auto has = [&](const std::string& n) {
    return std::find(inputs.begin(), inputs.end(), n) != inputs.end() || scene.wants(n);
  };
  for (const auto& n : d.inputs)
    if (!has(n)) return Status::error(origin + ": no column named '" + n + "' (input)");
  for (const auto& n : d.outputs)
    if (!has(n)) return Status::error(origin + ": no column named '" + n + "' (output)");
  if (!d.weights.empty() && !has(d.weights))
    return Status::error(origin + ": no column named '" + d.weights + "' (weights)");
  return Status::ok();
}

// The table of `scene` (through the cache unless data.cache_dir is "-"), every column of it.
Expected<RawTable> generatedTable(const RunConfig& cfg, const ds::Scene& scene,
                                  const std::filesystem::path& path, const TableLoadOptions& opt,
                                  bool refresh, bool& hit) {
  ds::GenerateOptions gopt;
  gopt.stop = opt.stop;
  hit = false;
  if (cfg.data.cache_dir == kNoCache) {
    auto g = ds::generate(scene, gopt);
    if (!g) return Status::error("/data/scene: " + path.string() + ": " + g.error());
    return ds::toRawTable(*g);
  }
  const std::filesystem::path dir =
      cfg.data.cache_dir.empty() ? ds::defaultCacheDir() : cfg.base_dir / cfg.data.cache_dir;
  auto c = ds::generateCached(scene, dir, gopt, refresh);
  if (!c) return Status::error("/data/scene: " + path.string() + ": " + c.error());
  hit = c->hit;
  return ds::toRawTable(c->table);
}

// The edge rows of data.edges (datasets/edges.hpp), generated like the table, appended to `t`.
Status edgeRows(const RunConfig& cfg, const ds::Scene& scene, const std::filesystem::path& path,
                const TableLoadOptions& opt, bool refresh, bool& hit, Table& t) {
  const EdgeConfig& e = cfg.data.edges;
  auto es = ds::edgeScene(scene, e.domain, "/data/edges/domain");
  if (!es) return es.status();
  auto raw = generatedTable(cfg, *es, path, opt, refresh, hit);
  if (!raw) return raw.status();
  return ds::appendEdgeRows(t, scene, *raw, e, cfg.data.weights, path.string() + " (edges)");
}

// The scene's table (through the cache unless data.cache_dir is "-"), its columns selected,
// the edge rows of data.edges appended and its values checked; a cached table the checks
// refuse is regenerated once.
Expected<Table> sceneTable(const RunConfig& cfg, const TableLoadOptions& opt) {
  const std::filesystem::path path = cfg.base_dir / cfg.data.scene;
  auto scene = ds::loadScene(path);
  if (!scene) return Status::error("/data/scene: " + scene.error());
  if (auto s = checkSceneColumns(*scene, cfg.data, path.string()); !s)
    return Status::error("/data/scene: " + s.message());
  auto load = [&](bool refresh) -> Expected<Table> {
    bool hit = false, edge_hit = false;
    auto raw = generatedTable(cfg, *scene, path, opt, refresh, hit);
    if (!raw) return raw.status();
    auto t =
        selectColumns(*raw, cfg.data.inputs, cfg.data.outputs, cfg.data.weights, path.string());
    if (!t) return hit ? Status::error(kStaleCacheEntry) : t.status();
    if (!cfg.data.edges.domain.empty())
      if (auto s = edgeRows(cfg, *scene, path, opt, refresh, edge_hit, *t); !s)
        return edge_hit ? Status::error(kStaleCacheEntry) : s;
    Status s = checkNumerics(cfg, *t);
    if (!s && (hit || edge_hit)) return Status::error(kStaleCacheEntry);
    if (!s) return s;
    return t;
  };
  auto t = load(false);
  if (!t && t.error() == kStaleCacheEntry) return load(true);
  return t;
}
#endif
}  // namespace

Expected<Table> loadRunTable(const RunConfig& cfg, const TableLoadOptions& opt) {
  if (!cfg.data.scene.empty()) {
#ifdef LGP_HAVE_DATASETS
    return sceneTable(cfg, opt);
#else
    (void)opt;
    return Status::error("/data/scene: generated tables are not available in this build");
#endif
  }
  if (!cfg.data.edges.domain.empty())
    return Status::error(
        "/data/edges: needs data.scene (edge rows are generated by the scene's integrator)");
  auto t = loadTableFile(cfg.data, cfg.base_dir);
  if (!t) return t;
  if (auto s = checkNumerics(cfg, *t); !s) return s;
  return t;
}

}  // namespace lgp::cli
