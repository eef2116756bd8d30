#include "lgp/core/table.hpp"
#include "lgp/core/csv.hpp"
#include "lgp/core/data_roots.hpp"
#include "lgp/core/text_check.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cfloat>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <set>
#include <sstream>

#include "lgp/config/json_reader.hpp"
#include "lgp/core/program.hpp"

namespace lgp {

Expected<std::string> readInputFile(const std::filesystem::path& path, size_t max_bytes,
                                    Status (*check)(int fd, const std::string& shown)) {
  const std::string f = path.string();
  // O_NONBLOCK: opening a FIFO for reading must not wait for a writer; it is refused below.
  const int fd = ::open(f.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) return Status::error(f + ": cannot open (" + std::strerror(errno) + ")");
  struct Closer {
    int fd;
    ~Closer() { ::close(fd); }
  } closer{fd};
  struct stat st {};
  if (::fstat(fd, &st) != 0)
    return Status::error(f + ": cannot stat (" + std::strerror(errno) + ")");
  if (check)
    if (auto s = check(fd, f); !s) return s;
  if (S_ISDIR(st.st_mode)) return Status::error(f + ": is a directory");
  if (!S_ISREG(st.st_mode))
    return Status::error(f + ": not a regular file (a FIFO, socket or device is not read)");
  if (static_cast<unsigned long long>(st.st_size) > max_bytes)
    return Status::error(f + ": " + std::to_string(st.st_size) + " bytes, more than the limit of " +
                         std::to_string(max_bytes));
  std::string text;
  text.reserve(static_cast<size_t>(st.st_size));
  char buf[1 << 16];
  while (true) {
    const ssize_t n = ::read(fd, buf, sizeof buf);
    if (n < 0) {
      if (errno == EINTR) continue;
      return Status::error(f + ": read failed (" + std::strerror(errno) + ")");
    }
    if (n == 0) break;
    if (text.size() + static_cast<size_t>(n) > max_bytes)
      return Status::error(f + ": more than the limit of " + std::to_string(max_bytes) + " bytes");
    text.append(buf, static_cast<size_t>(n));
  }
  return text;
}

Status Table::validate() const {
  if (inputs.empty()) return Status::error("table has no input columns");
  if (outputs.empty()) return Status::error("table has no output columns");
  if (input_names.size() != inputs.size() || output_names.size() != outputs.size())
    return Status::error("table column names and columns differ in count");
  const size_t n = rows();
  if (n == 0) return Status::error("table has no rows");
  std::set<std::string> seen;
  auto check = [&](const std::string& name, const std::vector<double>& col) -> Status {
    if (auto s = checkNoControlCharacters(name, "a column name"); !s) return s;
    if (!seen.insert(name).second) return Status::error("column '" + name + "' appears twice");
    if (col.size() != n)
      return Status::error("column '" + name + "' has " + std::to_string(col.size()) +
                           " rows, expected " + std::to_string(n));
    for (size_t r = 0; r < n; ++r) {
      if (!std::isfinite(col[r]))
        return Status::error("column '" + name + "', row " + std::to_string(r + 1) +
                             ": value is not finite");
      if (!fitsFloat32(col[r]))
        return Status::error(
            "column '" + name + "', row " + std::to_string(r + 1) + ": " + formatDouble(col[r]) +
            " is beyond the float32 range (|v| <= " + formatDouble(kTableValueMax) +
            "); the search evaluates in float32: rescale the column");
    }
    return Status::ok();
  };
  for (size_t i = 0; i < inputs.size(); ++i)
    if (auto s = check(input_names[i], inputs[i]); !s) return s;
  for (size_t i = 0; i < outputs.size(); ++i)
    if (auto s = check(output_names[i], outputs[i]); !s) return s;
  if (!weights.empty()) {
    if (weights.size() != n) return Status::error("weights have the wrong number of rows");
    double sum = 0;
    for (size_t r = 0; r < n; ++r) {
      if (!std::isfinite(weights[r]) || weights[r] < 0)
        return Status::error("weights, row " + std::to_string(r + 1) + ": must be finite and >= 0");
      if (!fitsFloat32(weights[r]))
        return Status::error("weights, row " + std::to_string(r + 1) + ": " +
                             formatDouble(weights[r]) +
                             " is beyond the float32 range (<= " + formatDouble(kTableValueMax) +
                             "); rows are weighed in float32: rescale the weights (only their "
                             "ratios matter)");
      sum += weights[r];
    }
    if (!std::isfinite(sum)) return Status::error("weights: their sum overflows double");
    if (!(sum > 0)) return Status::error("weights sum to zero");
  }
  return Status::ok();
}

int RawTable::find(const std::string& name) const {
  for (size_t i = 0; i < names.size(); ++i)
    if (names[i] == name) return static_cast<int>(i);
  return -1;
}

Status checkCsvHeader(const std::vector<std::string>& names, const std::string& f, size_t line) {
  const std::string at = f + ": line " + std::to_string(line) + " (header), column ";
  for (size_t c = 0; c < names.size(); ++c) {
    if (names[c].empty()) return Status::error(at + std::to_string(c + 1) + ": empty name");
    if (auto s = checkNoControlCharacters(names[c], at + std::to_string(c + 1) + ": the name"); !s)
      return s;
    for (size_t e = 0; e < c; ++e)
      if (names[e] == names[c])
        return Status::error(at + std::to_string(c + 1) + ": the same name as column " +
                             std::to_string(e + 1));
  }
  return Status::ok();
}

Expected<RawTable> readCsv(const std::filesystem::path& path) {
  const std::string f = path.string();
  auto text = readDataFile(path, kMaxInputFileBytes);
  if (!text) return text.status();
  std::string_view body = *text;
  if (body.substr(0, 3) == "\xEF\xBB\xBF") body.remove_prefix(3);  // UTF-8 byte order mark
  // The file may be any file a path points at (a symlink to a secret): no message quotes it.
  CsvReader reader(body, f);
  RawTable t;
  auto header = reader.next(t.names);
  if (!header) return header.status();
  if (!*header) return Status::error(f + ": empty file, expected a header row");
  if (auto s = checkCsvHeader(t.names, f, reader.line()); !s) return s;
  t.columns.resize(t.names.size());
  std::vector<std::string> cells;
  for (;;) {
    auto more = reader.next(cells);
    if (!more) return more.status();
    if (!*more) break;
    const std::string at = f + ": line " + std::to_string(reader.line());
    if (cells.size() != t.names.size())
      return Status::error(at + ": " + std::to_string(cells.size()) + " fields, header has " +
                           std::to_string(t.names.size()));
    for (size_t c = 0; c < cells.size(); ++c) {
      auto v = parseCsvNumber(cells[c]);
      if (!v) return Status::error(at + ", column " + std::to_string(c + 1) + ": " + v.error());
      t.columns[c].push_back(*v);
    }
  }
  if (t.columns[0].empty()) return Status::error(f + ": no data rows after the header");
  return t;
}

Expected<RawTable> parseJsonTable(const nlohmann::json& j, const std::string& f) {
  if (!j.is_object()) return Status::error(f + ": a JSON table must be an object");
  if (j.contains("format") && j["format"] != "lgp-table/1")
    return Status::error(f + ": /format: unsupported, expected \"lgp-table/1\"");
  if (!j.contains("columns") || !j["columns"].is_object())
    return Status::error(f + ": /columns: required object of name -> array of numbers");
  RawTable t;
  size_t n = 0;
  bool first = true;
  for (auto it = j["columns"].begin(); it != j["columns"].end(); ++it) {
    if (auto s = checkNoControlCharacters(
            it.key(), f + ": /columns: the name of column " + std::to_string(t.names.size() + 1));
        !s)
      return s;
    const std::string at = f + ": /columns/" + it.key();
    if (!it.value().is_array()) return Status::error(at + ": must be an array of numbers");
    std::vector<double> col;
    col.reserve(it.value().size());
    size_t r = 0;
    for (const auto& v : it.value()) {
      if (!v.is_number() || !std::isfinite(v.get<double>()))
        return Status::error(at + "/" + std::to_string(r) + " (row " + std::to_string(r + 1) +
                             "): not a finite number");
      col.push_back(v.get<double>());
      ++r;
    }
    if (first) {
      n = col.size();
      first = false;
    } else if (col.size() != n) {
      return Status::error(at + ": has " + std::to_string(col.size()) + " rows, others have " +
                           std::to_string(n));
    }
    t.names.push_back(it.key());
    t.columns.push_back(std::move(col));
  }
  if (t.names.empty() || n == 0) return Status::error(f + ": /columns: no data");
  auto names = [&](const char* key, std::vector<std::string>& out) -> Status {
    if (!j.contains(key)) return Status::ok();
    if (!j[key].is_array()) return Status::error(f + ": /" + key + ": must be an array of names");
    for (const auto& v : j[key]) {
      if (!v.is_string()) return Status::error(f + ": /" + key + ": must be an array of names");
      if (t.find(v.get<std::string>()) < 0)
        return Status::error(f + ": /" + key + ": no column named '" + v.get<std::string>() + "'");
      out.push_back(v.get<std::string>());
    }
    return Status::ok();
  };
  if (auto s = names("inputs", t.default_inputs); !s) return s;
  if (auto s = names("outputs", t.default_outputs); !s) return s;
  if (j.contains("weights")) {
    if (!j["weights"].is_array() || j["weights"].size() != n)
      return Status::error(f + ": /weights: must be an array with one number per row");
    for (size_t r = 0; r < n; ++r) {
      const auto& v = j["weights"][r];
      if (!v.is_number() || !(v.get<double>() >= 0) || !std::isfinite(v.get<double>()))
        return Status::error(f + ": /weights/" + std::to_string(r) + ": must be finite and >= 0");
      t.weights.push_back(v.get<double>());
    }
  }
  if (j.contains("meta")) t.meta = j["meta"];
  return t;
}

Expected<RawTable> readJsonTable(const std::filesystem::path& path) {
  const std::string f = path.string();
  auto text = readDataFile(path, kMaxInputFileBytes);
  if (!text) return text.status();
  JsonLimits limits;
  limits.max_bytes = kMaxInputFileBytes;
  auto j = parseJson(*text, limits);
  if (!j) return Status::error(f + ": " + j.error());
  return parseJsonTable(*j, f);
}

Expected<RawTable> readTableFile(const std::filesystem::path& path) {
  auto ext = path.extension().string();
  for (auto& c : ext) c = static_cast<char>(std::tolower(c));
  if (ext == ".csv") return readCsv(path);
  return readJsonTable(path);
}

Expected<Table> selectColumns(const RawTable& raw, const std::vector<std::string>& inputs,
                              const std::vector<std::string>& outputs,
                              const std::string& weight_column, const std::string& origin) {
  Table t;
  t.meta = raw.meta;
  const auto& in_names = inputs.empty() ? raw.default_inputs : inputs;
  const auto& out_names = outputs.empty() ? raw.default_outputs : outputs;
  if (in_names.empty())
    return Status::error(origin + ": no inputs named (set data.inputs in the config)");
  if (out_names.empty())
    return Status::error(origin + ": no outputs named (set data.outputs in the config)");
  for (const auto& n : in_names) {
    const int c = raw.find(n);
    if (c < 0) return Status::error(origin + ": no column named '" + n + "' (input)");
    t.input_names.push_back(n);
    t.inputs.push_back(raw.columns[c]);
  }
  for (const auto& n : out_names) {
    const int c = raw.find(n);
    if (c < 0) return Status::error(origin + ": no column named '" + n + "' (output)");
    t.output_names.push_back(n);
    t.outputs.push_back(raw.columns[c]);
  }
  if (!weight_column.empty()) {
    const int c = raw.find(weight_column);
    if (c < 0) return Status::error(origin + ": no column named '" + weight_column + "' (weights)");
    t.weights = raw.columns[c];
  } else {
    t.weights = raw.weights;
  }
  if (auto s = t.validate(); !s) return Status::error(origin + ": " + s.message());
  return t;
}

nlohmann::json toJson(const Table& t) {
  nlohmann::json cols = nlohmann::json::object();
  for (size_t i = 0; i < t.inputs.size(); ++i) cols[t.input_names[i]] = t.inputs[i];
  for (size_t i = 0; i < t.outputs.size(); ++i) cols[t.output_names[i]] = t.outputs[i];
  nlohmann::json j = {{"format", "lgp-table/1"},
                      {"inputs", t.input_names},
                      {"outputs", t.output_names},
                      {"columns", cols},
                      {"meta", t.meta}};
  if (!t.weights.empty()) j["weights"] = t.weights;
  return j;
}

Status writeCsv(const Table& t, const std::filesystem::path& path) {
  std::ofstream out(path);
  if (!out) return Status::error(path.string() + ": cannot write");
  std::vector<const std::vector<double>*> cols;
  std::vector<std::string> names;
  for (size_t i = 0; i < t.inputs.size(); ++i) {
    cols.push_back(&t.inputs[i]);
    names.push_back(t.input_names[i]);
  }
  for (size_t i = 0; i < t.outputs.size(); ++i) {
    cols.push_back(&t.outputs[i]);
    names.push_back(t.output_names[i]);
  }
  if (!t.weights.empty()) {
    cols.push_back(&t.weights);
    names.push_back("weight");
  }
  for (size_t c = 0; c < names.size(); ++c) out << (c ? "," : "") << csvField(names[c]);
  out << "\n";
  char buf[64];
  for (size_t r = 0; r < t.rows(); ++r) {
    for (size_t c = 0; c < cols.size(); ++c) {
      std::snprintf(buf, sizeof(buf), "%.17g", (*cols[c])[r]);
      out << (c ? "," : "") << buf;
    }
    out << "\n";
  }
  out.close();  // a full disk shows when the last buffer is written
  if (!out) return Status::error(path.string() + ": write failed");
  return Status::ok();
}

}  // namespace lgp
