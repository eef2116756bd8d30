// The scoreboard's data: what one table run produces (the published fits and lgp's fronts,
// scored on a held-out grid) and the rows of the board. See README.md.
#pragma once

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "lgp/config/config.hpp"
#include "lgp/core/table.hpp"

namespace lgp::board {

// One table of the spec (scoreboard.json).
struct TableSpec {
  std::string name, title;
  std::string config;             // run config, relative to the spec
  double evals_per_minute = 0;    // nominal minute -> evaluations (2 cores)
  std::vector<std::string> fits;  // the config's references that are published fits
};
// Errors name the spec file and the JSON path.
std::vector<TableSpec> parseSpec(const nlohmann::json& j, const std::string& file);

struct Metrics {
  double rmse = NAN, max_abs = NAN;
};
// A formula (published fit or front member) on the held-out grid.
struct Scored {
  std::string name;
  double isa = NAN;               // measured RDNA2 instructions (hlsl --fast), NaN if unmeasured
  double model_cost = NAN;        // the run's cost model
  std::vector<Metrics> channels;  // float32 interpreter, per error channel (or output)
  std::string formula;
};

struct Snapshot {
  double minutes = 0;
  uint64_t evaluations = 0;
  double wall_s = 0;
  nlohmann::json front;         // lgp-front/1 with measured costs
  std::vector<Scored> members;  // held-out figures of every member
};

// lgp at one budget against one fit: the member at or below the fit's ISA that comes closest
// to beating it (the smallest worst ratio over channels and over RMS and max).
struct Match {
  int member = -1;
  Scored m;
  double rms_factor = NAN, max_factor = NAN;  // fit / lgp, the worst channel (> 1: lgp better)
  bool beaten = false;                        // both factors > 1
};

struct Row {
  std::string table, fit;
  Scored published;
  std::vector<Match> lgp;  // per budget
  // The peer benchmark's best held-out RMS / max at ISA <= the fit's, per channel, or why not.
  std::string operon = "not run";
};

struct TableRun {
  TableSpec spec;
  RunConfig cfg;
  Table train, heldout;
  std::string train_desc, heldout_desc;  // grids, for the report
  std::vector<std::string> channels;
  std::vector<Scored> fits;  // the published fits named by the spec
  std::vector<Snapshot> snaps;
  std::vector<Row> rows;
  bool measured = false;
  std::string measure_note;  // the compiler, or why nothing was measured
  nlohmann::json recommended;
  double table_wall_s = 0, search_wall_s = 0;
};

// What a board was run with: only the records of the same settings share a report.
struct Settings {
  bool quick = false;
  int threads = 2;
  uint64_t seed = 1;
  std::vector<double> minutes;  // nominal minutes, ascending
  bool operator==(const Settings&) const = default;
};

// The settings a record keeps, and how this invocation runs.
struct Options : Settings {
  bool vulkan = true;
  std::filesystem::path cache_dir;
};

// The training table and its held-out grid (the midpoints between neighbouring training points
// on every axis). quick: at most 5 points per training axis, accuracy at least 1e-4.
Status loadTables(TableRun& r, const std::filesystem::path& spec_dir, const Options& o);
// Scores the fits, runs the search to the largest budget with snapshots, measures and scores
// every member on the held-out grid, and fills the rows.
Status runTable(TableRun& r, const Options& o);
// The Operon column from the peer benchmark's result file (README.md: format).
void addOperon(std::vector<TableRun>& runs, const nlohmann::json& operon);
// The member to ship, written as HLSL, GLSL and C++ into `dir` and run on lavapipe.
void recommend(TableRun& r, const std::filesystem::path& dir, const Options& o);

}  // namespace lgp::board
