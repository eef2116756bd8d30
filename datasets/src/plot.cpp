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

// The grid's axes, recovered from the rows (first input fastest); empty if not a full grid.
std::vector<std::vector<double>> gridAxes(const Table& t) {
  std::vector<std::vector<double>> axes(t.inputs.size());
  size_t stride = 1;
  for (size_t a = 0; a < t.inputs.size(); ++a) {
    for (size_t row = 0; row < t.rows(); row += stride) {
      if (row > 0 && a + 1 < t.inputs.size() && t.inputs[a + 1][row] != t.inputs[a + 1][0]) break;
      if (!axes[a].empty() && t.inputs[a][row] == axes[a].front()) break;
      axes[a].push_back(t.inputs[a][row]);
    }
    stride *= axes[a].size();
    if (axes[a].empty()) return {};
  }
  if (stride != t.rows()) return {};
  return axes;
}

// The heatmap and slices of output `y` over the first two inputs; `y` at (i, j) is y[off + j n0
// + i], `what` names the fixed third input (or is empty).
Status writeSurface(const std::string& name, const std::vector<double>& y, size_t off,
                    const std::vector<std::string>& xn, const std::vector<double>& a0,
                    const std::vector<double>& a1, const std::string& what, const fs::path& dir,
                    const std::string& stem, std::vector<fs::path>& files) {
  const size_t n0 = a0.size();
  std::vector<double> v(y.begin() + off, y.begin() + off + n0 * a1.size());
  const double lo = *std::min_element(v.begin(), v.end());
  const double hi = *std::max_element(v.begin(), v.end());
  plot::Heatmap h;
  h.title = name + "(" + xn[0] + ", " + xn[1] + ")" + (what.empty() ? "" : " at " + what) +
            "  min " + num(lo) + "  max " + num(hi);
  h.xlabel = xn[0];
  h.ylabel = xn[1];
  h.value_label = name;
  h.xs = a0;
  h.ys = a1;
  h.values = v;   // row-major with the first input fastest, as the table's rows
  h.width = 608;  // a square 420 x 420 cell area
  h.height = 508;
  h.generator = "lgp data";
  const std::string base = stem + "_" + name + (what.empty() ? "" : "_" + what);
  if (auto s = writeFile(dir / (base + "_heatmap.svg"), plot::svgHeatmap(h), files); !s) return s;
  // Slices: y against x0 at a few x1, and against x1 at a few x0.
  const std::string slices = plot::svgRow(
      {slicePlot(name, xn[0], a0, xn[1], a1, [&](size_t i, size_t j) { return v[j * n0 + i]; }),
       slicePlot(name, xn[1], a1, xn[0], a0, [&](size_t j, size_t i) { return v[j * n0 + i]; })});
  return writeFile(dir / (base + "_slices.svg"), slices, files);
}
}  // namespace

// One input: each output against it. Two: a heatmap and two slice plots per output. Three: the
// same over the first two inputs at up to five values of the third.
Expected<std::vector<fs::path>> writePlots(const GeneratedTable& g, const fs::path& dir,
                                           const std::string& stem) {
  std::vector<fs::path> files;
  const Table& t = g.table;
  if (t.inputs.empty() || t.inputs.size() > 3)
    return Status::error("plots need a table of one to three inputs");
  const auto axes = gridAxes(t);
  if (axes.empty()) return Status::error("plots need a full grid");
  for (size_t k = 0; k < t.outputs.size(); ++k) {
    const auto& y = t.outputs[k];
    const std::string& name = t.output_names[k];
    if (t.inputs.size() == 1) {
      plot::Axes ax;
      ax.title = name + " against " + t.input_names[0];
      ax.xlabel = t.input_names[0];
      ax.ylabel = name;
      ax.generator = "lgp data";
      plot::Series line;
      line.name = name;
      line.style = plot::Series::Style::Line;
      line.x = axes[0];
      line.y = y;
      if (auto s =
              writeFile(dir / (stem + "_" + name + "_plot.svg"), plot::svgPlot(ax, {line}), files);
          !s)
        return s;
      continue;
    }
    const size_t plane = axes[0].size() * axes[1].size();
    const std::vector<size_t> at =
        t.inputs.size() == 2 ? std::vector<size_t>{0} : picks(axes[2].size());
    for (size_t j : at) {
      const std::string what =
          t.inputs.size() == 2 ? std::string() : t.input_names[2] + "=" + num(axes[2][j]);
      if (auto s = writeSurface(name, y, j * plane, t.input_names, axes[0], axes[1], what, dir,
                                stem, files);
          !s)
        return s;
    }
  }
  return files;
}

}  // namespace lgp::datasets
