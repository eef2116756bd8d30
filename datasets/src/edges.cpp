// Edge values and the edge scene (edges.hpp).
#include "lgp/datasets/edges.hpp"

#include <algorithm>
#include <cmath>
#include <set>

namespace lgp::datasets {

std::vector<double> edgeValues(const std::vector<double>& train, double lo, double hi) {
  std::vector<double> v;
  if (train.empty() || !(lo < hi)) return v;
  const double first = train.front(), last = train.back();
  if (lo > 0) {
    for (double x = lo * std::sqrt(2.0); x < first && x <= hi; x *= 2) v.push_back(x);
  } else {
    for (double f : {0.5e-3, 0.5e-2})
      if (lo + f * (hi - lo) < first) v.push_back(lo + f * (hi - lo));
  }
  if (hi > last && last >= lo) v.push_back(0.5 * (last + hi));
  return v;
}

namespace {
std::vector<double> sortedValues(const GridAxis& a) {
  std::vector<double> v = a.values;
  std::sort(v.begin(), v.end());
  v.erase(std::unique(v.begin(), v.end()), v.end());
  return v;
}
}  // namespace

bool domainBeyondGrid(const Scene& s,
                      const std::map<std::string, std::pair<double, double>>& domain) {
  for (const auto& [input, range] : domain) {
    const GridAxis* a = s.axis(input);
    if (a && !edgeValues(sortedValues(*a), range.first, range.second).empty()) return true;
  }
  return false;
}

Expected<Scene> edgeScene(const Scene& s,
                          const std::map<std::string, std::pair<double, double>>& domain,
                          const std::string& origin) {
  nlohmann::json j = toJson(s);
  for (const auto& [input, range] : domain) {
    const GridAxis* a = s.axis(input);
    if (!a) return Status::error(origin + ": " + input + ": not an input of the scene's grid");
    if (!(std::isfinite(range.first) && std::isfinite(range.second) && range.first < range.second))
      return Status::error(origin + ": " + input + ": must be [lo, hi] with lo < hi, finite");
    std::vector<double> v = sortedValues(*a);
    const auto extra = edgeValues(v, range.first, range.second);
    if (extra.empty()) continue;
    v.insert(v.end(), extra.begin(), extra.end());
    std::sort(v.begin(), v.end());
    j["grid"][input] = {{"values", v}};
  }
  if (!domainBeyondGrid(s, domain))
    return Status::error(origin +
                         ": the declared domain adds no value to the grid (it lies inside it)");
  return parseScene(j, origin + " (edges)");
}

std::vector<bool> edgeRowMask(const Scene& train, const std::vector<std::vector<double>>& inputs) {
  std::vector<std::set<double>> on_grid;
  for (const auto& a : train.grid) on_grid.emplace_back(a.values.begin(), a.values.end());
  const size_t rows = inputs.empty() ? 0 : inputs[0].size();
  std::vector<bool> mask(rows, false);
  for (size_t r = 0; r < rows; ++r)
    for (size_t a = 0; a < inputs.size() && a < on_grid.size() && !mask[r]; ++a)
      mask[r] = !on_grid[a].count(inputs[a][r]);
  return mask;
}

Status appendEdgeRows(Table& t, const Scene& train, RawTable edge_table, const EdgeConfig& e,
                      const std::string& weights_column, const std::string& origin) {
  RawTable& raw = edge_table;
  // The edge table's axis columns, in the scene's order, pick the rows off the training grid.
  std::vector<std::vector<double>> axes;
  for (const auto& a : train.grid) {
    auto it = std::find(raw.names.begin(), raw.names.end(), a.name);
    if (it == raw.names.end()) return Status::error(origin + ": no column " + a.name);
    axes.push_back(raw.columns[it - raw.names.begin()]);
  }
  const std::vector<bool> keep = edgeRowMask(train, axes);
  auto filter = [&](std::vector<double>& col) {
    std::vector<double> kept;
    for (size_t r = 0; r < col.size() && r < keep.size(); ++r)
      if (keep[r]) kept.push_back(col[r]);
    col = std::move(kept);
  };
  for (auto& col : raw.columns) filter(col);
  if (!raw.weights.empty()) filter(raw.weights);
  auto edges = selectColumns(raw, t.input_names, t.output_names, weights_column, origin);
  if (!edges) return edges.status();
  const size_t n = t.rows(), m = edges->rows();
  double mean = 1.0;
  if (!t.weights.empty()) {
    mean = 0;
    for (double w : t.weights) mean += w;
    mean /= static_cast<double>(n);
  } else {
    t.weights.assign(n, 1.0);
  }
  for (size_t r = 0; r < m; ++r)
    t.weights.push_back(e.weight * mean * (edges->weights.empty() ? 1.0 : edges->weights[r]));
  for (size_t i = 0; i < t.inputs.size(); ++i)
    t.inputs[i].insert(t.inputs[i].end(), edges->inputs[i].begin(), edges->inputs[i].end());
  for (size_t o = 0; o < t.outputs.size(); ++o)
    t.outputs[o].insert(t.outputs[o].end(), edges->outputs[o].begin(), edges->outputs[o].end());
  nlohmann::json dom = nlohmann::json::object();
  for (const auto& [k, v] : e.domain) dom[k] = {v.first, v.second};
  t.meta["edges"] = {{"rows", m}, {"training_rows", n}, {"domain", dom}, {"weight", e.weight}};
  return Status::ok();
}

}  // namespace lgp::datasets
