#include "table_source.hpp"

#include "lgp/eval/objectives.hpp"
#include "lgp/io/table_file.hpp"

#if __has_include("lgp/datasets/generate.hpp")
#include "lgp/datasets/generate.hpp"
#define LGP_HAVE_DATASETS 1
#endif

namespace lgp::cli {

namespace {
Expected<Table> loadTable(const RunConfig& cfg) {
  if (!cfg.data.scene.empty()) {
#ifdef LGP_HAVE_DATASETS
    // Generate (or fetch from the cache) the scene's table, then select columns exactly as
    // for a file table.
    namespace ds = lgp::datasets;
    const std::filesystem::path path = cfg.base_dir / cfg.data.scene;
    auto scene = ds::loadScene(path);
    if (!scene) return Status::error("/data/scene: " + scene.error());
    const std::filesystem::path dir =
        cfg.data.cache_dir.empty() ? ds::defaultCacheDir() : cfg.base_dir / cfg.data.cache_dir;
    auto gen = ds::generateCached(*scene, dir);
    if (!gen) return Status::error("/data/scene: " + path.string() + ": " + gen.error());
    return selectColumns(ds::toRawTable(gen->table), cfg.data.inputs, cfg.data.outputs,
                         cfg.data.weights, path.string());
#else
    return Status::error("/data/scene: generated tables are not available in this build");
#endif
  }
  return loadTableFile(cfg.data, cfg.base_dir);
}
}  // namespace

Expected<Table> loadRunTable(const RunConfig& cfg) {
  auto t = loadTable(cfg);
  if (!t) return t;
  // Before the search: values the float32 evaluation cannot hold would leave every error
  // NaN or infinite, and the front empty.
  if (auto s = checkErrorNumerics(*t, cfg.errorConfig(t->output_names)); !s)
    return Status::error((cfg.data.scene.empty() ? "/data/path" : "/data/scene") +
                         std::string(": ") + s.message());
  return t;
}

}  // namespace lgp::cli
