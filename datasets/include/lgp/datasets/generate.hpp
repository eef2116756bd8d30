// Table generation from a scene, the lgp-table/1 JSON of a generated table, and the cache.
//
// generate() evaluates only what the scene's outputs need (Scene::needs), in parallel over
// rows with OpenMP (one to three inputs, the first fastest), and records per-entry error estimates,
// evaluation counts per effect and the metadata (definition, scene, grid, integrator, sample
// counts, max estimated error, generator version) that `lgp data` writes.
//
// Cache: <dir>/<key>.lgpt, key = FNV-1a 64 of the canonical scene JSON plus kGeneratorVersion.
// A cache file is "lgp-cache/1 <fnv64 hex of payload> <payload bytes>\n" followed by the
// lgp-table/1 JSON; a file whose length or checksum does not match, or that is not the scene's
// table (generateCached says how that is checked), is never used: it is regenerated and
// rewritten (atomically, via a temporary file and rename).
#pragma once

#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "lgp/core/status.hpp"
#include "lgp/core/table.hpp"
#include "lgp/datasets/integrator.hpp"
#include "lgp/datasets/scene.hpp"

namespace lgp::datasets {

inline constexpr const char* kGeneratorVersion = "lgp-datasets/1.2.0";

struct GenerateOptions {
  int threads = 0;  // OpenMP threads; 0 = the OpenMP default; at most the cores available
  // Polled (from any thread) before each integral: once it returns true the remaining rows
  // are skipped and generation returns the error kGenerationStopped. Empty: never stops.
  std::function<bool()> stop;
};

// The error message of a generation stopped by GenerateOptions::stop.
inline constexpr const char* kGenerationStopped = "generation stopped";

struct GeneratedTable {
  Table table;                              // inputs, outputs, meta
  std::vector<std::vector<double>> errors;  // [output][row] estimated absolute errors
  Counters counters;                        // integrand evaluations per effect
  double max_error = 0;                     // max over all entries
  bool converged = true;                    // every integral met its tolerance
};

Expected<GeneratedTable> generate(const Scene& scene, const GenerateOptions& opt = {});

// The outputs and their error estimates at some rows of the scene's table only ([output][i]
// for rows[i]), computed exactly as generate() computes them: how a cache entry is checked.
struct RowValues {
  std::vector<std::vector<double>> value, error;
};
Expected<RowValues> generateRows(const Scene& scene, const std::vector<size_t>& rows,
                                 const GenerateOptions& opt = {});

// lgp-table/1 JSON with "errors" and "meta"; and back (for the cache).
nlohmann::json toTableJson(const GeneratedTable& g);
Expected<GeneratedTable> fromTableJson(const nlohmann::json& j, const std::string& origin);
// CSV: a header of input and output names, then one row per sample.
Status writeTableCsv(const GeneratedTable& g, const std::filesystem::path& path);
// All columns as a RawTable (inputs then outputs), with the default roles and meta.
RawTable toRawTable(const GeneratedTable& g);

std::string cacheKey(const Scene& scene);
std::filesystem::path defaultCacheDir();  // $LGP_CACHE_DIR, $XDG_CACHE_HOME/lgp, ~/.cache/lgp

struct CachedTable {
  GeneratedTable table;
  bool hit = false;            // served from the cache
  std::filesystem::path file;  // the cache file
  std::string note;            // e.g. why a cache file was discarded
};
// The scene's table from <cache_dir>/<key>.lgpt when that entry is the scene's (its recorded
// scene and generator version, columns and grid, and 8 rows recomputed at random agree), else
// generated and written there. A cache another user could write (a directory writable by
// others and not sticky, or owned by another user; an entry that is a link, not ours, or
// writable by others) is neither read nor written; `note` says so. refresh: regenerate and
// rewrite whatever the cache holds (a caller that found a cached table unusable).
Expected<CachedTable> generateCached(const Scene& scene, const std::filesystem::path& cache_dir,
                                     const GenerateOptions& opt = {}, bool refresh = false);

// SVG heatmaps (every output over the two inputs) and 1-D slices (each output against each
// input, at a few values of the other). Returns the files written.
Expected<std::vector<std::filesystem::path>> writePlots(const GeneratedTable& g,
                                                        const std::filesystem::path& dir,
                                                        const std::string& stem);

}  // namespace lgp::datasets
