// The result of a run as written by `lgp run` and read by `lgp front`, `lgp emit` and lgpd.
//
// front.json ("lgp-front/1"):
// { "format": "lgp-front/1",
//   "config": {...},                    // the resolved RunConfig
//   "config_dir": "/abs/dir",           // where the config was (its data path is relative)
//   "table": {"inputs": [...], "outputs": [...], "rows": N, "domain": {"mu": [lo, hi], ...},
//             "meta": {...}},
//   "progress": {"generation": G, "evaluations": E, "elapsed_s": T, "stop_reason": "..."},
//   "cost_model": "gpu-generic",
//   "members": [
//     { "index": 0, "error": e, "cost": c, "discontinuity": d,
//       "cost_by_target": {"gpu-generic": c, "nvidia": ..., ...},
//       "formula": "t0 = r^2; A = 1 - t0; B = exp2(-7*mu - 4*t0)",  // programFormula
//       "cancellation": {"bits_lost": 2.1, "flagged": false},      // cancellation.hpp
//       "outputs": [ {"name": "A", "expression": "...", "transform": "none",
//                     "float32": {"rmse":..,"max_abs":..,"mae":..,"mean_rel":..,"r2":..},
//                     "double":  {...}} ],
//       "channels": [ {"name": "F0=1", "float32": {...}, "double": {...}} ],  // with channels
//       "program": {"code": [...], "constants": [...], "outputs": [...]} } ],
//   "error_channels": ["A", "B"],    // what "error" combines: channel names, or the outputs
//   "references": [...] }           // formulas listed in the config, as given
// "expression" is the output's formula on its own (its temporaries first); "formula" the whole
// program. Both are the simplified DAG on the table's domain (core/formula.hpp).
// front.csv: one row per member and output: index,output,error,cost,discontinuity,
// rmse,max_abs,mae,mean_rel,r2,bits_lost,expression,formula.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "lgp/core/formula.hpp"
#include "lgp/core/snap.hpp"
#include "lgp/core/status.hpp"
#include "lgp/search/search.hpp"

namespace lgp {

nlohmann::json metricsToJson(const OutputMetrics& m);
nlohmann::json frontToJson(const Search& s, const std::vector<FrontEntry>& front);
Status writeFrontJson(const nlohmann::json& front, const std::filesystem::path& path);
Status writeFrontCsv(const nlohmann::json& front, const std::filesystem::path& path);

// Writes `text` to `path` through a temporary file, flushed to disk and renamed, so a crash
// leaves the old file or the new one, never a half-written one.
Status writeTextAtomic(const std::string& text, const std::filesystem::path& path);
// The same for JSON; indent < 0 = compact.
Status writeJsonAtomic(const nlohmann::json& j, const std::filesystem::path& path, int indent);
// A search checkpoint file (`lgp run --checkpoint`): written atomically, read back with the
// file named in every error.
Status writeCheckpointFile(const nlohmann::json& state, const std::filesystem::path& path);
Expected<nlohmann::json> readCheckpointFile(const std::filesystem::path& path);
// The `lgp run --status` file: the progress counters as JSON (format lgp-status/1).
nlohmann::json progressToJson(const SearchProgress& p);

// Reads and checks a front.json; the error names the file and the bad field.
Expected<nlohmann::json> readFrontJson(const std::filesystem::path& path);
// The checks of readFrontJson on a front from elsewhere (a daemon's answer): members with a
// program, outputs and cost, table names without control characters. `origin` starts errors.
Status checkFrontJson(const nlohmann::json& front, const std::string& origin);
// A member's program, decoded against the shape recorded in the front.
Expected<Program> memberProgram(const nlohmann::json& front, size_t index);
// The same for any entry with a "program" (a member, or a scored reference of "references").
Expected<Program> frontEntryProgram(const nlohmann::json& front, const nlohmann::json& entry);
// The table's domain recorded in a front (/table/domain), one interval per /table/inputs
// entry (the whole line where none is recorded).
std::vector<Interval> frontDomain(const nlohmann::json& front);
// A member's formula: printFormula of formulaDag(program) on the front's input and output
// names and domain, recomputed from the program (so fronts written before the "formula" field
// print the same way). This is the text for reports and pages; memberFormula joins it.
Expected<Formula> memberFormulaStatements(const nlohmann::json& front, size_t index);
Expected<std::string> memberFormula(const nlohmann::json& front, size_t index);

// The GPU families whose measured cost the front records (/cost_measured_info/families; set by
// emit's addMeasuredCost), in order; empty when none was measured.
std::vector<std::string> measuredFamilies(const nlohmann::json& front);

struct FrontTableOptions {
  // Flag threshold for the bits-lost column; unset: the member's own "flagged".
  std::optional<double> cancel_bits;
};
// Plain-text table of a front (for `lgp front`): per member its cost, the measured
// instructions per family where the front has them (e.g. "14/15/14"), discontinuity, error,
// the float32 rmse and max_abs per output, the bits lost to cancellation ("!" = flagged) and
// the formula, one statement per line for several outputs.
std::string formatFrontTable(const nlohmann::json& front, const FrontTableOptions& o = {});

// The run config recorded in a front, with base_dir set so that its data path resolves:
// /config_dir when the table is there, else the front file's directory. With `data` set, the
// config reads that table file instead (path as given; columns as recorded). Errors say where
// it looked. A front is untrusted input: its data.cache_dir is dropped (a scene's table is
// cached where the user's runs cache it), and data.inputs/outputs are the front's /table
// columns where the config does not list them, so that loading checks a scene's columns
// before generating it.
Expected<RunConfig> frontRunConfig(const nlohmann::json& front,
                                   const std::filesystem::path& front_path,
                                   const std::string& data = "");
// Member `index` with its constants snapped (snap.hpp) against `t` (the run's table) with the
// front's error settings, re-scored: a member object like frontToJson's (error, cost,
// discontinuity, metrics, formula, cancellation, program) plus "snap": {"constants": n,
// "error_before": e0}. `cfg` is the run config (frontRunConfig).
Expected<nlohmann::json> snapFrontMember(const nlohmann::json& front, size_t index,
                                         const RunConfig& cfg, const Table& t,
                                         const SnapOptions& o = {});

}  // namespace lgp
