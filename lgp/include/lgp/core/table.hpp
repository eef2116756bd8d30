// A sampled table: named input and output columns in double precision, optional per-row
// weights, and a metadata JSON (definition, grid, integrator, ... for generated tables).
// Every data source (user CSV/JSON, generators in datasets/) produces this one type.
//
// JSON table format ("lgp-table/1"), written by `lgp data` and accepted by `lgp run`:
//   { "format": "lgp-table/1",
//     "inputs": ["mu", "r"], "outputs": ["A", "B"],      // default roles of the columns
//     "columns": { "mu": [...], "r": [...], "A": [...], "B": [...] },
//     "weights": [...],                                   // optional, one per row, >= 0
//     "errors":  { "A": [...], "B": [...] },              // optional per-entry error estimates
//     "meta": { ... } }                                   // optional, free-form
// CSV (RFC 4180: "1,5" is one field, "" a quote): a header row of column names, then one row
// of decimal numbers per sample; a UTF-8 byte order mark at the start is skipped.
//
// Values: finite, and within the float32 range (rounding to at most kTableValueMax =
// FLT_MAX, about 3.4e38, in magnitude), since the search evaluates in float32; the error
// names the column and row.
// Values below float32's smallest subnormal (1e-310, say) are finite and accepted; float32
// rounds them to 0. Weights: finite, >= 0, <= kTableValueMax, with a positive sum.
#pragma once

#include <cfloat>
#include <cmath>
#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "lgp/core/status.hpp"

namespace lgp {

inline constexpr double kTableValueMax = FLT_MAX;
// Whether v rounds to a finite float32 (|v| up to FLT_MAX plus half an ulp).
inline bool fitsFloat32(double v) {
  return std::isfinite(static_cast<float>(v));
}
// Largest table, scene or front file read (4 GiB).
inline constexpr size_t kMaxInputFileBytes = size_t{1} << 32;

// Reads a whole input file. Only a regular file is read: a directory gives "<path>: is a
// directory", a FIFO, socket or device "<path>: not a regular file" (opened without
// blocking, so a FIFO cannot stall the reader), a file over max_bytes is refused. Every
// error names the path.
// `check`, if given, is called on the open descriptor before anything is read (see
// data_roots.hpp).
Expected<std::string> readInputFile(const std::filesystem::path& path,
                                    size_t max_bytes = kMaxInputFileBytes,
                                    Status (*check)(int fd, const std::string& shown) = nullptr);

struct Table {
  std::vector<std::string> input_names;
  std::vector<std::string> output_names;
  std::vector<std::vector<double>> inputs;   // [input][row]
  std::vector<std::vector<double>> outputs;  // [output][row]
  std::vector<double> weights;               // empty = uniform
  nlohmann::json meta = nlohmann::json::object();

  size_t rows() const {
    return inputs.empty() ? (outputs.empty() ? 0 : outputs[0].size()) : inputs[0].size();
  }
  size_t numInputs() const { return inputs.size(); }
  size_t numOutputs() const { return outputs.size(); }

  // Shape, finiteness and weight checks; the message names the column and row.
  Status validate() const;
};

// All columns of a file, before roles are assigned.
struct RawTable {
  std::vector<std::string> names;
  std::vector<std::vector<double>> columns;
  std::vector<std::string> default_inputs;   // from a JSON table's "inputs", if present
  std::vector<std::string> default_outputs;  // from a JSON table's "outputs", if present
  std::vector<double> weights;               // from a JSON table's "weights", if present
  nlohmann::json meta = nlohmann::json::object();

  int find(const std::string& name) const;
};

// RFC 4180 (lgp/core/csv.hpp); decimal numbers only (no hex, inf or nan). Errors name the
// file, line and column and quote nothing of it.
Expected<RawTable> readCsv(const std::filesystem::path& path);
// Header names: not empty, no control characters, no name twice. `line`: the header's line.
Status checkCsvHeader(const std::vector<std::string>& names, const std::string& file, size_t line);
Expected<RawTable> readJsonTable(const std::filesystem::path& path);
Expected<RawTable> parseJsonTable(const nlohmann::json& j, const std::string& origin);
// By extension: .csv is CSV, anything else is parsed as a JSON table.
Expected<RawTable> readTableFile(const std::filesystem::path& path);

// Picks inputs, outputs and an optional weight column by name. Empty name lists fall back to
// the file's declared roles. `origin` names the file in error messages.
Expected<Table> selectColumns(const RawTable& raw, const std::vector<std::string>& inputs,
                              const std::vector<std::string>& outputs,
                              const std::string& weight_column, const std::string& origin);

// Writes a table in the lgp-table/1 JSON format, or CSV.
nlohmann::json toJson(const Table& t);
Status writeCsv(const Table& t, const std::filesystem::path& path);

}  // namespace lgp
