// A generated table as lgp-table/1 JSON (and back, for the cache), as CSV, and as the core's
// RawTable.
#include <cmath>
#include <cstdio>

#include "lgp/datasets/generate.hpp"

namespace lgp::datasets {

using nlohmann::json;

json toTableJson(const GeneratedTable& g) {
  const Table& t = g.table;
  json j;
  j["format"] = "lgp-table/1";
  j["inputs"] = t.input_names;
  j["outputs"] = t.output_names;
  j["columns"] = json::object();
  for (size_t i = 0; i < t.input_names.size(); ++i) j["columns"][t.input_names[i]] = t.inputs[i];
  for (size_t k = 0; k < t.output_names.size(); ++k) j["columns"][t.output_names[k]] = t.outputs[k];
  if (!t.weights.empty()) j["weights"] = t.weights;
  j["errors"] = json::object();
  for (size_t k = 0; k < t.output_names.size() && k < g.errors.size(); ++k)
    j["errors"][t.output_names[k]] = g.errors[k];
  j["meta"] = t.meta;
  return j;
}

Expected<GeneratedTable> fromTableJson(const json& j, const std::string& origin) {
  try {
    if (j.value("format", std::string()) != "lgp-table/1")
      return Status::error(origin + ": /format: not an lgp-table/1 table");
    GeneratedTable g;
    g.table.input_names = j.at("inputs").get<std::vector<std::string>>();
    g.table.output_names = j.at("outputs").get<std::vector<std::string>>();
    const json& cols = j.at("columns");
    size_t rows = 0;
    bool first = true;
    auto column = [&](const std::string& name) -> Expected<std::vector<double>> {
      if (!cols.contains(name)) return Status::error(origin + ": /columns/" + name + ": missing");
      auto v = cols.at(name).get<std::vector<double>>();
      if (first) rows = v.size(), first = false;
      if (v.size() != rows) return Status::error(origin + ": /columns/" + name + ": wrong length");
      for (size_t i = 0; i < v.size(); ++i)
        if (!std::isfinite(v[i]))
          return Status::error(origin + ": /columns/" + name + "/" + std::to_string(i) +
                               ": not finite");
      return v;
    };
    for (const auto& n : g.table.input_names) {
      auto c = column(n);
      if (!c) return c.status();
      g.table.inputs.push_back(std::move(*c));
    }
    for (const auto& n : g.table.output_names) {
      auto c = column(n);
      if (!c) return c.status();
      g.table.outputs.push_back(std::move(*c));
      std::vector<double> e(rows, 0.0);
      if (j.contains("errors") && j["errors"].contains(n)) {
        e = j["errors"][n].get<std::vector<double>>();
        if (e.size() != rows) return Status::error(origin + ": /errors/" + n + ": wrong length");
      }
      g.errors.push_back(std::move(e));
    }
    if (j.contains("weights")) g.table.weights = j["weights"].get<std::vector<double>>();
    if (j.contains("meta")) g.table.meta = j["meta"];
    const json& sc = g.table.meta.value("sample_counts", json::object());
    g.counters.specular = sc.value("specular", uint64_t{0});
    g.counters.fresnel = sc.value("fresnel", uint64_t{0});
    g.counters.diffuse = sc.value("diffuse", uint64_t{0});
    g.counters.rep_point = sc.value("rep_point", uint64_t{0});
    g.counters.sheen = sc.value("sheen", uint64_t{0});
    g.counters.dielectric = sc.value("dielectric", uint64_t{0});
    g.max_error = g.table.meta.value("max_estimated_error", 0.0);
    g.converged = g.table.meta.value("converged", true);
    return g;
  } catch (const json::exception& e) {
    return Status::error(origin + ": malformed table: " + e.what());
  }
}

Status writeTableCsv(const GeneratedTable& g, const std::filesystem::path& path) {
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) return Status::error(path.string() + ": cannot open for writing");
  const Table& t = g.table;
  std::string line;
  for (const auto& n : t.input_names) line += (line.empty() ? "" : ",") + n;
  for (const auto& n : t.output_names) line += "," + n;
  std::fprintf(f, "%s\n", line.c_str());
  for (size_t row = 0; row < t.rows(); ++row) {
    for (size_t i = 0; i < t.inputs.size(); ++i)
      std::fprintf(f, "%s%.17g", i ? "," : "", t.inputs[i][row]);
    for (size_t k = 0; k < t.outputs.size(); ++k) std::fprintf(f, ",%.17g", t.outputs[k][row]);
    std::fprintf(f, "\n");
  }
  const bool ok = std::fclose(f) == 0;
  return ok ? Status::ok() : Status::error(path.string() + ": write failed");
}

RawTable toRawTable(const GeneratedTable& g) {
  RawTable r;
  const Table& t = g.table;
  for (size_t i = 0; i < t.input_names.size(); ++i) {
    r.names.push_back(t.input_names[i]);
    r.columns.push_back(t.inputs[i]);
  }
  for (size_t k = 0; k < t.output_names.size(); ++k) {
    r.names.push_back(t.output_names[k]);
    r.columns.push_back(t.outputs[k]);
  }
  r.default_inputs = t.input_names;
  r.default_outputs = t.output_names;
  r.weights = t.weights;
  r.meta = t.meta;
  return r;
}

}  // namespace lgp::datasets
