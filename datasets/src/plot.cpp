// `lgp data --plot`: people look at the data before they fit it. A table's heatmaps and slices,
// drawn by the project's one plotter (lgp/io/svg_plot.hpp).
#include <algorithm>

#include "lgp/datasets/generate.hpp"
#include "lgp/io/svg_plot.hpp"

namespace lgp::datasets {

namespace {
namespace fs = std::filesystem;

std::string num(double v) {
  return plot::formatNumber(v, 4);
}

// Up to 5 indices spread evenly over [0, n), both ends included.
std::vector<size_t> picks(size_t n) {
  std::vector<size_t> p;
  const size_t k = std::min<size_t>(5, n);
  for (size_t i = 0; i < k; ++i) p.push_back(k == 1 ? 0 : i * (n - 1) / (k - 1));
  return p;
}

// The output against one input (`x` of length nx), one line per picked value of the other
// input (`other`); `at(i, j)` is the output at x[i] and other[j].
template <class At>
plot::Plot slicePlot(const std::string& output, const std::string& xname,
                     const std::vector<double>& x, const std::string& oname,
                     const std::vector<double>& other, At at) {
  plot::Plot p;
  p.axes.title = output + " against " + xname;
  p.axes.xlabel = xname;
  p.axes.ylabel = output;
  p.axes.width = 450;
  p.axes.height = 380;
  p.axes.generator = "lgp data";
  for (size_t j : picks(other.size())) {
    plot::Series s;
    s.name = oname + "=" + num(other[j]);
    s.style = plot::Series::Style::Line;
    s.x = x;
    for (size_t i = 0; i < x.size(); ++i) s.y.push_back(at(i, j));
    p.series.push_back(std::move(s));
  }
  return p;
}

Status writeFile(const fs::path& f, const std::string& text, std::vector<fs::path>& files) {
  std::string err;
  if (!plot::writeTextFile(f.string(), text, &err)) return Status::error(err);
  files.push_back(f);
  return Status::ok();
}
}  // namespace

Expected<std::vector<fs::path>> writePlots(const GeneratedTable& g, const fs::path& dir,
                                           const std::string& stem) {
  std::vector<fs::path> files;
  const Table& t = g.table;
  if (t.inputs.size() != 2) return Status::error("plots need a two-input table");
  // Recover the grid axes from the rows (first input fastest).
  std::vector<double> a0, a1;
  for (size_t row = 0; row < t.rows(); ++row) {
    if (row > 0 && t.inputs[1][row] != t.inputs[1][0]) break;
    a0.push_back(t.inputs[0][row]);
  }
  const size_t n0 = a0.size();
  if (n0 == 0 || t.rows() % n0) return Status::error("plots need a full grid");
  for (size_t row = 0; row < t.rows(); row += n0) a1.push_back(t.inputs[1][row]);
  const std::string& x0 = t.input_names[0];
  const std::string& x1 = t.input_names[1];
  for (size_t k = 0; k < t.outputs.size(); ++k) {
    const auto& y = t.outputs[k];
    const std::string& name = t.output_names[k];
    const double lo = *std::min_element(y.begin(), y.end());
    const double hi = *std::max_element(y.begin(), y.end());
    plot::Heatmap h;
    h.title = name + "(" + x0 + ", " + x1 + ")  min " + num(lo) + "  max " + num(hi);
    h.xlabel = x0;
    h.ylabel = x1;
    h.value_label = name;
    h.xs = a0;
    h.ys = a1;
    h.values = y;   // row-major with the first input fastest, as the table's rows
    h.width = 608;  // a square 420 x 420 cell area
    h.height = 508;
    h.generator = "lgp data";
    if (auto s = writeFile(dir / (stem + "_" + name + "_heatmap.svg"), plot::svgHeatmap(h), files);
        !s)
      return s;
    // Slices: y against x0 at a few x1, and against x1 at a few x0.
    const std::string slices = plot::svgRow(
        {slicePlot(name, x0, a0, x1, a1, [&](size_t i, size_t j) { return y[j * n0 + i]; }),
         slicePlot(name, x1, a1, x0, a0, [&](size_t j, size_t i) { return y[j * n0 + i]; })});
    if (auto s = writeFile(dir / (stem + "_" + name + "_slices.svg"), slices, files); !s) return s;
  }
  return files;
}

}  // namespace lgp::datasets
