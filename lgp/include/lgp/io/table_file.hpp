// The table a run config names by file (data.path): read by extension (CSV or JSON, see
// lgp/core/table.hpp) and its columns picked by data.inputs, data.outputs and data.weights.
#pragma once

#include <filesystem>

#include "lgp/config/config.hpp"
#include "lgp/core/table.hpp"

namespace lgp {

// Loads the table a config names (data.path, relative to `base_dir`). Scenes are resolved by
// the frontends, which link the datasets library; an empty data.path is an error.
Expected<Table> loadTableFile(const DataConfig& data, const std::filesystem::path& base_dir);

}  // namespace lgp
