// Resolves the table a run config names: a CSV/JSON file (data.path) or a generated table
// (data.scene, via the datasets library). Used by `lgp run` and by lgpd.
#pragma once

#include "lgp/config/config.hpp"
#include "lgp/core/table.hpp"

namespace lgp::cli {

Expected<Table> loadRunTable(const RunConfig& cfg);

}  // namespace lgp::cli
