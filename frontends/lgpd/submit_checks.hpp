// What POST /api/v1/runs checks before it answers 201, without doing a job's work in the
// HTTP handler: the data files are regular files that can be read (never opened in a way
// that could block), small tables are read in full, a large CSV only up to its header, a
// scene is parsed but not generated, and every reference formula is parsed against the
// table's columns (and, with search.seed_references, fitted to the run's program shape).
// Errors name the JSON path: "/data/path: /tmp/t.fifo is not a regular file (a FIFO)".
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "lgp/config/config.hpp"
#include "lgp/core/status.hpp"

namespace lgpd {

// Tables up to this size are loaded in full at submit (every value is checked); larger ones
// are checked by their header (CSV) or left to the job (a JSON table whose config does not
// name its columns).
inline constexpr size_t kSubmitFullLoadBytes = size_t{4} << 20;
// A CSV header must lie within this many bytes of the start of the file.
inline constexpr size_t kCsvHeaderBytes = size_t{1} << 20;
// A scene file is at most this large, and its grid at most this many rows.
inline constexpr size_t kMaxSceneFileBytes = size_t{1} << 20;
inline constexpr size_t kMaxSceneRows = size_t{1} << 24;
// One text of a reference formula ("expr", or one element of it).
inline constexpr size_t kMaxReferenceTextBytes = size_t{64} << 10;

// The table's input and output names as the run uses them, when submit could learn them.
struct TableColumns {
  std::vector<std::string> inputs, outputs;
  bool known = false;
};

// data.path and data.scene (absolute by now) exist, are regular files and can be opened for
// reading. Called at submit and again when a job (or a residuals request) loads the table.
lgp::Status checkDataFiles(const lgp::RunConfig& cfg);

// checkDataFiles, then the cheap part of loading the table (see above). Not for inline
// tables (the caller has them parsed already).
lgp::Expected<TableColumns> checkTableAtSubmit(const lgp::RunConfig& cfg);

// Every reference parses (errors: "/references/2/expr: 'name' does not parse: ..."), no text
// is longer than kMaxReferenceTextBytes, and with search.seed_references every reference
// fits the program shape ("/references/2: 'name' cannot seed this run: ..."). With unknown
// columns only the format and the lengths are checked.
lgp::Status checkReferencesAtSubmit(const lgp::RunConfig& cfg, const TableColumns& columns);

// What lgpd does not run although `lgp run` does: the exhaustive enumeration
// (search.exhaustive), whose minutes before the first generation no cancel reaches and whose
// certificate would not survive a restart. A 400 at submit, a failed run for a run stored by
// an lgpd that took it.
lgp::Status checkServedByLgpd(const lgp::RunConfig& cfg);

// The longest program a run's shape allows: opcodes and constant slots.
struct ProgramSize {
  uint64_t opcodes = 0, constants = 0;
};

// What a search of `cfg` on a table of `outputs` outputs holds in memory, roughly, by what
// sets it: its programs (each at its longest, ProgramSize: program.max_length opcodes, or
// outputs x genes where that is more, plus the output layer's opcodes and constants under
// linear scaling; 255 of each when the outputs are not known; four per population slot, the
// population, its offspring and the selection pool with its copies, plus the archive's),
// kIslandOverheadBytes per island, and the semantic cache, which is allocated in full when the
// search starts. The table and the evaluation buffers are not counted.
struct SearchBytes {
  uint64_t programs = 0, islands = 0, semantic_cache = 0;
  ProgramSize program_size;
  uint64_t total() const { return programs + islands + semantic_cache; }
};
SearchBytes estimateSearchBytes(const lgp::RunConfig& cfg, std::optional<size_t> outputs);
inline constexpr uint64_t kIslandOverheadBytes = uint64_t{64} << 10;
// A 400 naming the largest share (/search/population, /search/islands/count or
// /search/semantic_cache) when estimateSearchBytes exceeds `limit` (the daemon's
// max_run_memory_mb).
lgp::Status checkSearchMemory(const lgp::RunConfig& cfg, std::optional<size_t> outputs,
                              uint64_t limit);

}  // namespace lgpd
