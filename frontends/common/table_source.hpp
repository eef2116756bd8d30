// Resolves the table a run config names: a CSV/JSON file (data.path) or a generated table
// (data.scene, via the datasets library). Used by `lgp run` and by lgpd.
#pragma once

#include "lgp/config/config.hpp"
#include "lgp/core/table.hpp"

namespace lgp::cli {

// The table, checked as the search will use it (checkErrorNumerics under the config's error
// settings): an error names the data field, the column and the row.
Expected<Table> loadRunTable(const RunConfig& cfg);

}  // namespace lgp::cli
