#include "table_source.hpp"

#include <algorithm>

#include "lgp/eval/objectives.hpp"
#include "lgp/io/table_file.hpp"

#if __has_include("lgp/datasets/generate.hpp")
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

// The scene's table (through the cache unless data.cache_dir is "-"), its columns selected
// and its values checked; a cached table the checks refuse is regenerated once.
Expected<Table> sceneTable(const RunConfig& cfg, const TableLoadOptions& opt) {
  const std::filesystem::path path = cfg.base_dir / cfg.data.scene;
  auto scene = ds::loadScene(path);
  if (!scene) return Status::error("/data/scene: " + scene.error());
  if (auto s = checkSceneColumns(*scene, cfg.data, path.string()); !s)
    return Status::error("/data/scene: " + s.message());
  ds::GenerateOptions gopt;
  gopt.stop = opt.stop;
  const bool cached = cfg.data.cache_dir != kNoCache;
  const std::filesystem::path dir = cfg.data.cache_dir.empty() ? ds::defaultCacheDir()
                                    : cached ? cfg.base_dir / cfg.data.cache_dir
                                             : std::filesystem::path();
  auto load = [&](bool refresh) -> Expected<Table> {
    Expected<ds::GeneratedTable> g = Status::error("not generated");
    bool hit = false;
    if (cached) {
      auto c = ds::generateCached(*scene, dir, gopt, refresh);
      if (!c) return Status::error("/data/scene: " + path.string() + ": " + c.error());
      hit = c->hit;
      g = std::move(c->table);
    } else {
      g = ds::generate(*scene, gopt);
      if (!g) return Status::error("/data/scene: " + path.string() + ": " + g.error());
    }
    auto t = selectColumns(ds::toRawTable(*g), cfg.data.inputs, cfg.data.outputs,
                           cfg.data.weights, path.string());
    Status s = t ? checkNumerics(cfg, *t) : t.status();
    if (!s && hit) return Status::error(kStaleCacheEntry);
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
  auto t = loadTableFile(cfg.data, cfg.base_dir);
  if (!t) return t;
  if (auto s = checkNumerics(cfg, *t); !s) return s;
  return t;
}

}  // namespace lgp::cli
