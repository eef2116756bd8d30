// The scoreboard's data: what one table run produces (the published fits and lgp's fronts,
// scored on a held-out grid) and the rows of the board. See README.md.
#pragma once

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "lgp/config/config.hpp"
#include "lgp/core/interval.hpp"
#include "lgp/core/table.hpp"
#include "lgp/eval/objectives.hpp"

namespace lgp::board {

// A published fit, one row of its table: the config's references that compute it (every form
// computes the same values; its cost is the cheapest form's), whether it counts towards the
// headline, where it comes from and what the reader should know.
struct FitSpec {
  std::string name;                // the row's label
  std::vector<std::string> forms;  // config reference names; default {name}
  bool counted = true;  // false: listed apart (no located source, a heuristic, the shipped clamp)
  std::string source, note;
};

// One table of the spec (scoreboard.json).
struct TableSpec {
  std::string name, title;
  std::string config;           // run config, relative to the spec
  double evals_per_minute = 0;  // nominal minute -> evaluations (2 cores)
  std::vector<FitSpec> fits;
  // The declared domain per input: where a shader evaluates the formula (n.v down to 1e-4,
  // roughness down to 0.01, the light size down to 0). The held-out set covers it, edges
  // included, and a recommended member holds on all of it.
  std::map<std::string, std::pair<double, double>> domain;
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
  std::string form;  // a fit's: the form its ISA is of (the cheapest)
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
  bool counted = true;
  std::string source, note;
  Scored published;
  std::vector<Match> lgp;  // per budget
  // The peer benchmark's best held-out RMS / max at ISA <= the fit's, per channel, or why not.
  std::string operon = "not run";
};

struct TableRun {
  TableSpec spec;
  RunConfig cfg;
  Table train, heldout;  // heldout: the declared domain, edges included (tables.cpp)
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
  // The search starts from the published fits (search.seed_references) or not: the board is
  // run both ways, and a win counts where it holds without them.
  bool seed_references = false;
  // The edge rows of the declared domain are part of the objective (data.edges, weight 1):
  // what that option costs and buys, measured apart from the board.
  bool edge_objective = false;
  bool operator==(const Settings&) const = default;
};

// The settings a record keeps, and how this invocation runs.
struct Options : Settings {
  bool vulkan = true;
  std::filesystem::path cache_dir;
};

// The training table and its held-out set: a product grid over the declared domain of each
// axis's training midpoints, its edges (geometric steps from the domain's lower end up to the
// first training point, both ends) and random values (a fixed seed). quick: at most 5 points
// per training axis, accuracy at least 1e-4, fewer random values.
Status loadTables(TableRun& r, const std::filesystem::path& spec_dir, const Options& o);
// The held-out values of one axis over its declared domain [lo, hi]: the training midpoints
// inside it, both ends, geometric steps from a lower end above 0 up to the first training point
// (n.v 1e-4, 2e-4, ... 0.0128 for a grid from 1/64), points next to an end at 0 and next to the
// upper end, and `random` uniform values (seeded, so the set is the same at every run).
std::vector<double> heldoutAxis(const std::vector<double>& train, double lo, double hi, int random,
                                uint64_t seed);
// Scores the fits, runs the search to the largest budget with snapshots, measures and scores
// every member on the held-out grid, and fills the rows.
Status runTable(TableRun& r, const Options& o);
// The Operon column from the peer benchmark's result file (README.md: format).
void addOperon(std::vector<TableRun>& runs, const nlohmann::json& operon);
// The member to ship, written as HLSL, GLSL and C++ into `dir` and run on lavapipe.
void recommend(TableRun& r, const std::filesystem::path& dir, const Options& o);

// Whether a program holds on a declared domain: finite, and every output within `allowed`
// ([lo, hi] per output: the table's range widened by its width on each side), proven by the
// interval analysis over the domain box or, where that bound is too loose, by a dense sweep
// (geometric towards a lower edge above 0, linear elsewhere).
struct DomainCheck {
  bool safe = false;
  std::string method;         // "interval analysis" or "sweep of N points"
  double lo = NAN, hi = NAN;  // the values' range found (the sweep's, or the proof's)
  std::string why;            // where it fails
};
DomainCheck checkOnDomain(const Program& p, const std::vector<Interval>& domain,
                          const std::vector<std::pair<double, double>>& allowed,
                          const std::vector<TargetTransform>& transforms, int sweep_points);

// The cheapest of a fit's forms that compute the same values (within 1e-4 of each output's
// largest |value| on `t`): its index in `isa`, else an error naming the form that differs.
Expected<size_t> cheapestForm(const std::vector<Program>& forms, const std::vector<double>& isa,
                              const Table& t, const std::vector<std::string>& names);

}  // namespace lgp::board
