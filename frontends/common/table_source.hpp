// Resolves the table a run config names: a CSV/JSON file (data.path) or a generated table
// (data.scene, via the datasets library). Used by `lgp run`, lgp emit/front, lgpd and Python.
#pragma once

#include <functional>

#include "lgp/config/config.hpp"
#include "lgp/core/table.hpp"

namespace lgp::cli {

struct TableLoadOptions {
  // Polled while a scene's table is generated: true ends the load with
  // lgp::datasets::kGenerationStopped (lgpd's cancel, delete and shutdown; Python's Ctrl-C).
  std::function<bool()> stop;
};

// The table, checked as the search will use it (checkErrorNumerics under the config's error
// settings): an error names the data field, the column and the row. A scene's columns are
// checked against data.inputs, data.outputs and data.weights before it is generated; a table
// served from the cache that the checks refuse is regenerated once (a stale or damaged
// entry), so that an error is the scene's own.
Expected<Table> loadRunTable(const RunConfig& cfg, const TableLoadOptions& opt = {});

}  // namespace lgp::cli
