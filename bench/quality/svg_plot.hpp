// Dependency-free SVG plots for the quality report: x/y plots (scatter, lines, Pareto staircases)
// and heatmaps with a colour bar.
//
// The output is byte-deterministic: the same input gives the same bytes (numbers are formatted
// with std::to_chars, which ignores the locale; nothing depends on time or addresses), so reports
// diff cleanly between runs. No ids are emitted, so several plots can be inlined into one HTML
// page. Text is escaped for XML; bytes that are not valid UTF-8 or XML become U+FFFD or a space.
// Bad input (empty or non-finite data, degenerate ranges, mismatched lengths) never throws: it
// draws what is valid and notes "no data" when nothing is.
#pragma once

#include <cmath>
#include <string>
#include <utility>
#include <vector>

namespace lgp::quality {

struct Series {
  std::string name;                 // legend entry ("" = not in the legend)
  std::vector<double> x, y;         // same length (extra entries of the longer one are ignored)
  std::vector<std::string> labels;  // optional per-point text next to the marker ("" = none)
  // Non-finite points (and non-positive ones on a log axis) are skipped; a line breaks there.
  // Steps: a Pareto-front staircase, horizontal from (x_i, y_i) to (x_{i+1}, y_i) then vertical
  // (the caller sorts the points by x); its points get markers too, so labels have an anchor.
  enum class Style { Markers, Line, LineMarkers, Steps } style = Style::LineMarkers;
  enum class Marker { Circle, Square, Diamond, Triangle, Cross } marker = Marker::Circle;
  std::string color;  // any SVG colour; "" = from a fixed palette by series index
};

struct Axes {
  std::string title, xlabel, ylabel;
  bool logx = false, logy = false;  // log10 axes; non-positive values are skipped on a log axis
  // Optional fixed ranges; NaN = automatic (data range padded by 5%; whole decades on a log
  // axis). The automatic y range includes the hlines.
  double xmin = NAN, xmax = NAN, ymin = NAN, ymax = NAN;
  int width = 720, height = 480;
  // Horizontal reference lines (e.g. an error target), drawn dashed with their label.
  std::vector<std::pair<double, std::string>> hlines;
};

std::string svgPlot(const Axes& axes, const std::vector<Series>& series);

struct Heatmap {
  std::string title, xlabel, ylabel, value_label;
  // Grid coordinates (ascending): every cell gets the same size and the tick labels show these
  // values, so non-uniform (e.g. log-spaced) grids are drawn in index space.
  std::vector<double> xs, ys;
  std::vector<double> values;  // row-major: values[iy * nx + ix]; non-finite or missing cells grey
  bool log_scale = false;      // colour by log10(value); values <= 0 get the minimum colour
  bool diverging = false;  // blue-white-red, symmetric around zero (signed errors); wins over log
  int width = 560, height = 480;
};

// Cells are drawn as one <rect> each inside <g class='cells'>, followed by a colour bar.
std::string svgHeatmap(const Heatmap& h);

// Writes text to a file, creating parent directories; returns false with a message on failure.
bool writeTextFile(const std::string& path, const std::string& text, std::string* error);

}  // namespace lgp::quality
