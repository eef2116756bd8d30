#include "table_source.hpp"

#include "lgp/search/search.hpp"

namespace lgp::cli {

Expected<Table> loadRunTable(const RunConfig& cfg) {
  if (!cfg.data.scene.empty()) {
    return Status::error("/data/scene: generated tables are not available in this build");
  }
  return loadTableFile(cfg.data, cfg.base_dir);
}

}  // namespace lgp::cli
