#include "submit_checks.hpp"

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <filesystem>

#include "files.hpp"
#include "lgp/config/json_reader.hpp"
#include "lgp/core/csv.hpp"
#include "lgp/core/table.hpp"
#include "lgp/search/search.hpp"
#include "lgp/search/semantic_cache.hpp"
#include "table_source.hpp"
#ifdef LGP_HAVE_EMIT
#include "lgp/emit/score.hpp"
#endif
#ifdef LGP_HAVE_DATASETS
#include "lgp/datasets/scene.hpp"
#endif

namespace lgpd {

using lgp::Expected;
using lgp::Status;
namespace fs = std::filesystem;

namespace {

fs::path resolved(const lgp::RunConfig& cfg, const std::string& p) {
  fs::path path(p);
  return path.is_relative() ? cfg.base_dir / path : path;
}

// The names a table with these columns gives the run, by selectColumns itself (one row of
// ones stands in for the data), so that every message is the one a full load would give.
Expected<TableColumns> namesOf(lgp::RawTable raw, const lgp::RunConfig& cfg,
                               const std::string& origin) {
  raw.columns.assign(raw.names.size(), std::vector<double>(1, 1.0));
  if (!raw.weights.empty()) raw.weights.assign(1, 1.0);
  auto t = lgp::selectColumns(raw, cfg.data.inputs, cfg.data.outputs, cfg.data.weights, origin);
  if (!t) return t.status();
  return TableColumns{t->input_names, t->output_names, true};
}

// The header row of a CSV (the first record that is neither blank nor a '#' comment), read
// as the table reader reads it.
Expected<std::vector<std::string>> csvHeader(const std::string& text, const std::string& f) {
  std::string_view body(text);
  if (body.substr(0, 3) == "\xEF\xBB\xBF") body.remove_prefix(3);  // UTF-8 byte order mark
  lgp::CsvReader reader(body, f);
  std::vector<std::string> names;
  auto got = reader.next(names);
  if (!got) {
    // A quoted field still open at the end of what was read may close further on.
    if (text.size() < kCsvHeaderBytes) return got.status();
  } else if (!*got) {
    return Status::error(f + ": empty file, expected a header row");
  }
  if (!got || (!reader.terminated() && text.size() >= kCsvHeaderBytes))
    return Status::error(f + ": no header row within the first " + std::to_string(kCsvHeaderBytes) +
                         " bytes");
  if (auto s = lgp::checkCsvHeader(names, f, reader.line()); !s) return s;
  return names;
}

}  // namespace

Status checkDataFiles(const lgp::RunConfig& cfg) {
  if (!cfg.data.scene.empty()) {
    if (auto f = RegularFile::open(resolved(cfg, cfg.data.scene)); !f)
      return Status::error("/data/scene: " + f.error());
  } else if (!cfg.data.path.empty()) {
    auto f = RegularFile::open(resolved(cfg, cfg.data.path));
    if (!f) return Status::error("/data/path: " + f.error());
    if (f->size() == 0)
      return Status::error("/data/path: " + resolved(cfg, cfg.data.path).string() +
                           " is empty (0 bytes)");
  }
  return Status::ok();
}

Expected<TableColumns> checkTableAtSubmit(const lgp::RunConfig& cfg) {
  if (!cfg.data.scene.empty()) {
    const fs::path p = resolved(cfg, cfg.data.scene);
    auto j = readJsonDocument(p, kMaxSceneFileBytes);
    if (!j) return Status::error("/data/scene: " + j.error());
#ifdef LGP_HAVE_DATASETS
    // Parsed and checked here; generated (or taken from the cache) by the job.
    auto scene = lgp::datasets::parseScene(*j, p.string());
    if (!scene) return Status::error("/data/scene: " + scene.error());
    if (scene->rows() > kMaxSceneRows)
      return Status::error("/data/scene: " + p.string() + ": the grid has " +
                           std::to_string(scene->rows()) + " rows; lgpd generates at most " +
                           std::to_string(kMaxSceneRows));
    lgp::RawTable raw;
    raw.names = scene->inputNames();
    raw.default_inputs = raw.names;
    raw.names.insert(raw.names.end(), scene->outputs.begin(), scene->outputs.end());
    raw.default_outputs = scene->outputs;
    auto cols = namesOf(std::move(raw), cfg, p.string());
    if (!cols) return Status::error("/data/scene: " + cols.error());
    return cols;
#else
    return Status::error("/data/scene: generated tables are not available in this build");
#endif
  }
  if (cfg.data.path.empty()) return Status::error("/data/path: no table file named");
  const fs::path p = resolved(cfg, cfg.data.path);
  auto file = RegularFile::open(p);
  if (!file) return Status::error("/data/path: " + file.error());
  if (file->size() == 0) return Status::error("/data/path: " + p.string() + " is empty (0 bytes)");
  if (file->size() <= kSubmitFullLoadBytes) {
    // Small enough to read in full here: every value is checked before 201.
    auto t = lgp::cli::loadRunTable(cfg);
    if (!t) return t.status();
    return TableColumns{t->input_names, t->output_names, true};
  }
  std::string ext = p.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return std::tolower(c); });
  if (ext == ".csv") {
    auto head = file->read(kCsvHeaderBytes);
    if (!head) return Status::error("/data/path: " + p.string() + ": " + head.error());
    auto names = csvHeader(*head, p.string());
    if (!names) return Status::error("/data/path: " + names.error());
    lgp::RawTable raw;
    raw.names = std::move(*names);
    auto cols = namesOf(std::move(raw), cfg, p.string());
    if (!cols) return Status::error("/data/path: " + cols.error());
    return cols;
  }
  // A large JSON table: its columns are known without reading it only when the config names
  // them; the job reads it.
  if (!cfg.data.inputs.empty() && !cfg.data.outputs.empty())
    return TableColumns{cfg.data.inputs, cfg.data.outputs, true};
  return TableColumns{};
}

Status checkReferencesAtSubmit(const lgp::RunConfig& cfg, const TableColumns& columns) {
#ifdef LGP_HAVE_EMIT
  auto refs = lgp::emit::parseReferences(cfg.references);
  if (!refs) return refs.status();
  for (size_t i = 0; i < refs->size(); ++i) {
    const auto& r = (*refs)[i];
    const std::string at = lgp::jsonPath("/references", i);
    for (size_t k = 0; k < r.expr.size(); ++k)
      if (r.expr[k].size() > kMaxReferenceTextBytes)
        return Status::error((r.expr.size() > 1 ? lgp::jsonPath(at + "/expr", k) : at + "/expr") +
                             ": at most " + std::to_string(kMaxReferenceTextBytes) +
                             " bytes per formula (got " + std::to_string(r.expr[k].size()) + ")");
    if (!columns.known) continue;
    lgp::emit::ParseOptions po;
    po.input_names = columns.inputs;
    po.output_names = columns.outputs;
    po.aliases = r.aliases;
    auto pf = lgp::emit::parseFormula(r.expr, po);
    if (!pf) return Status::error(at + "/expr: '" + r.name + "' does not parse: " + pf.error());
    if (cfg.search.seed_references) {
      const auto shape = cfg.shape(static_cast<int>(columns.inputs.size()),
                                   static_cast<int>(columns.outputs.size()));
      auto fit = lgp::fitToShape(pf->program, shape);
      if (!fit)
        return Status::error(at + ": '" + r.name +
                             "' cannot seed this run (search.seed_references): " + fit.error());
      if (auto v = lgp::validate(*fit, shape); !v)
        return Status::error(at + ": '" + r.name +
                             "' cannot seed this run (search.seed_references): " + v.message());
    }
  }
  return Status::ok();
#else
  (void)columns;
  if (cfg.search.seed_references)
    return Status::error("/search/seed_references: this lgpd was built without the parser");
  return Status::ok();
#endif
}

namespace {

// The longest program of the run's shape (what ProgramShape allows, plus the output layer's
// opcodes and constants under linear scaling), for `outputs` table outputs; unknown outputs
// (a large JSON table whose columns the config does not name): the 255 of either.
ProgramSize programSize(const lgp::RunConfig& cfg, std::optional<size_t> outputs) {
  if (!outputs) return {255, 255};
  const uint64_t n = *outputs;
  const uint64_t genes = cfg.search.linear_scaling ? static_cast<uint64_t>(cfg.program.genes) : 1;
  uint64_t opcodes = std::max<uint64_t>(static_cast<uint64_t>(cfg.program.max_length), n * genes);
  uint64_t constants = static_cast<uint64_t>(cfg.program.num_constants);
  if (cfg.search.linear_scaling) {
    opcodes += n * genes;
    constants += n * (genes + 1);
  }
  return {std::min<uint64_t>(opcodes, 255), std::min<uint64_t>(constants, 255)};
}

uint64_t programBytes(const ProgramSize& size) {
  // The vectors' contents plus the Program and its objectives; 64 bytes of allocator slack.
  return sizeof(lgp::Program) + sizeof(lgp::Objectives) + 64 + sizeof(lgp::Instr) * size.opcodes +
         sizeof(float) * size.constants + 64;
}

std::string gib(uint64_t bytes) {
  char buf[32];
  if (bytes < (uint64_t{1} << 30))
    std::snprintf(buf, sizeof buf, "%.0f MiB", static_cast<double>(bytes) / (1u << 20));
  else
    std::snprintf(buf, sizeof buf, "%.1f GiB", static_cast<double>(bytes) / (1u << 30));
  return buf;
}

}  // namespace

Status checkServedByLgpd(const lgp::RunConfig& cfg) {
  if (cfg.search.exhaustive.max_ops > 0)
    return Status::error(
        "/search/exhaustive: lgpd does not run the exhaustive enumeration (no cancel reaches it "
        "and its certificate would not survive a restart); run it with `lgp run` or lgp.fit, or "
        "set search.exhaustive.max_ops to 0");
  return Status::ok();
}

SearchBytes estimateSearchBytes(const lgp::RunConfig& cfg, std::optional<size_t> outputs) {
  const uint64_t programs = 4 * static_cast<uint64_t>(std::max(cfg.search.population, 0)) +
                            static_cast<uint64_t>(std::max(cfg.search.archive.max_size, 0));
  SearchBytes b;
  b.program_size = programSize(cfg, outputs);
  b.programs = programs * programBytes(b.program_size);
  b.islands = static_cast<uint64_t>(std::max(cfg.search.islands.count, 0)) * kIslandOverheadBytes;
  b.semantic_cache =
      lgp::SemanticCache::bytesFor(static_cast<size_t>(std::max(cfg.search.semantic_cache, 0)));
  return b;
}

lgp::Status checkSearchMemory(const lgp::RunConfig& cfg, std::optional<size_t> outputs,
                              uint64_t limit) {
  const SearchBytes b = estimateSearchBytes(cfg, outputs);
  const uint64_t need = b.total();
  if (need <= limit) return lgp::Status::ok();
  const std::string what = "this run would need about " + gib(need) + " (" + gib(b.programs) +
                           " for " + std::to_string(cfg.search.population) + " programs of up to " +
                           std::to_string(b.program_size.opcodes) + " opcodes, " + gib(b.islands) +
                           " for " + std::to_string(cfg.search.islands.count) + " islands, " +
                           gib(b.semantic_cache) + " for a semantic cache of " +
                           std::to_string(cfg.search.semantic_cache) +
                           " entries), more than this lgpd allows a run (" + gib(limit) +
                           ", its max_run_memory_mb; by default half the machine's memory)";
  if (b.semantic_cache >= b.programs && b.semantic_cache >= b.islands)
    return lgp::Status::error("/search/semantic_cache: " + what +
                              ": lower search.semantic_cache (0 turns it off)");
  if (b.islands > b.programs)
    return lgp::Status::error("/search/islands/count: " + what + ": lower search.islands.count");
  return lgp::Status::error("/search/population: " + what +
                            ": lower search.population or program.max_length");
}

}  // namespace lgpd
