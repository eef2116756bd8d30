// The result of a run as written by `lgp run` and read by `lgp front`, `lgp emit` and lgpd.
//
// front.json ("lgp-front/1"):
// { "format": "lgp-front/1",
//   "config": {...},                    // the resolved RunConfig
//   "table": {"inputs": [...], "outputs": [...], "rows": N, "domain": {"mu": [lo, hi], ...},
//             "meta": {...}},
//   "progress": {"generation": G, "evaluations": E, "elapsed_s": T, "stop_reason": "..."},
//   "cost_model": "gpu-generic",
//   "members": [
//     { "index": 0, "error": e, "cost": c, "discontinuity": d,
//       "cost_by_target": {"gpu-generic": c, "nvidia": ..., ...},
//       "outputs": [ {"name": "A", "expression": "...", "transform": "none",
//                     "float32": {"rmse":..,"max_abs":..,"mae":..,"mean_rel":..,"r2":..},
//                     "double":  {...}} ],
//       "channels": [ {"name": "F0=1", "float32": {...}, "double": {...}} ],  // with channels
//       "program": {"code": [...], "constants": [...], "outputs": [...]} } ],
//   "error_channels": ["A", "B"],    // what "error" combines: channel names, or the outputs
//   "references": [...] }           // formulas listed in the config, as given
// front.csv: one row per member and output: index,output,error,cost,discontinuity,
// rmse,max_abs,mae,mean_rel,r2,expression.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "lgp/core/status.hpp"
#include "lgp/search/search.hpp"

namespace lgp {

nlohmann::json metricsToJson(const OutputMetrics& m);
nlohmann::json frontToJson(const Search& s, const std::vector<FrontEntry>& front);
Status writeFrontJson(const nlohmann::json& front, const std::filesystem::path& path);
Status writeFrontCsv(const nlohmann::json& front, const std::filesystem::path& path);

// Writes `j` to `path` through a temporary file, flushed to disk and renamed, so a crash
// leaves the old file or the new one, never a half-written one. indent < 0 = compact.
Status writeJsonAtomic(const nlohmann::json& j, const std::filesystem::path& path, int indent);
// A search checkpoint file (`lgp run --checkpoint`): written atomically, read back with the
// file named in every error.
Status writeCheckpointFile(const nlohmann::json& state, const std::filesystem::path& path);
Expected<nlohmann::json> readCheckpointFile(const std::filesystem::path& path);
// The `lgp run --status` file: the progress counters as JSON (format lgp-status/1).
nlohmann::json progressToJson(const SearchProgress& p);

// Reads and checks a front.json; the error names the file and the bad field.
Expected<nlohmann::json> readFrontJson(const std::filesystem::path& path);
// A member's program, decoded against the shape recorded in the front.
Expected<Program> memberProgram(const nlohmann::json& front, size_t index);
// Plain-text table of a front (for `lgp front`).
std::string formatFrontTable(const nlohmann::json& front);

}  // namespace lgp
