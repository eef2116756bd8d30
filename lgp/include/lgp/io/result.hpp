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

// Reads and checks a front.json; the error names the file and the bad field.
Expected<nlohmann::json> readFrontJson(const std::filesystem::path& path);
// A member's program, decoded against the shape recorded in the front.
Expected<Program> memberProgram(const nlohmann::json& front, size_t index);
// Plain-text table of a front (for `lgp front`).
std::string formatFrontTable(const nlohmann::json& front);

}  // namespace lgp
