// The SVG plotter (lgp/io/svg_plot.hpp) of the quality report and `lgp data`: well-formed XML
// for any input (empty, NaN, log axes with non-positive values, degenerate ranges),
// byte-determinism under any locale, escaping, exact geometry of clipped lines and Pareto
// staircases, heatmap cells and file size, plots side by side.
#include "lgp/io/svg_plot.hpp"

#include <gtest/gtest.h>

#include <unistd.h>

#include <clocale>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <locale>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "svg_check.hpp"

using namespace lgp::plot;
using namespace lgp::svg_check;
namespace fs = std::filesystem;

namespace {

// The part of `s` from the element starting with `start` to its matching "</g>".
std::string group(const std::string& s, const std::string& start) {
  const size_t b = s.find(start);
  if (b == std::string::npos) return {};
  int depth = 0;
  for (size_t i = b; i < s.size(); ++i) {
    if (s.compare(i, 3, "<g ") == 0 || s.compare(i, 3, "<g>") == 0) ++depth;
    if (s.compare(i, 4, "</g>") == 0 && --depth == 0) return s.substr(b, i + 4 - b);
  }
  return {};
}

Series line(std::vector<double> x, std::vector<double> y, Series::Style style,
            std::string name = "") {
  Series s;
  s.name = std::move(name);
  s.x = std::move(x);
  s.y = std::move(y);
  s.style = style;
  return s;
}

Heatmap grid(size_t nx, size_t ny) {
  Heatmap h;
  h.title = "error";
  h.xlabel = "roughness";
  h.ylabel = "NdotV";
  h.value_label = "abs error";
  for (size_t i = 0; i < nx; ++i) h.xs.push_back(i / double(nx - 1 + (nx == 1)));
  for (size_t i = 0; i < ny; ++i) h.ys.push_back(i / double(ny - 1 + (ny == 1)));
  for (size_t iy = 0; iy < ny; ++iy)
    for (size_t ix = 0; ix < nx; ++ix) h.values.push_back(std::sin(0.3 * ix) * std::cos(0.2 * iy));
  return h;
}

const double kNaN = std::nan("");

}  // namespace

TEST(SvgPlot, LineAndMarkersWithLegend) {
  Axes a;
  a.title = "Pareto front";
  a.xlabel = "size";
  a.ylabel = "RMSE";
  const std::string svg =
      svgPlot(a, {line({1, 2, 3, 4}, {4, 3, 2, 1}, Series::Style::LineMarkers, "run A"),
                  line({1, 2, 3}, {1, 2, 3}, Series::Style::Markers, "run B")});
  EXPECT_TRUE(wellFormed(svg));
  EXPECT_EQ(count(svg, "class='series'"), 2u);
  EXPECT_EQ(count(svg, "<circle"), 4u + 3u + 2u);        // points + one legend marker per series
  EXPECT_EQ(count(svg, "stroke-linejoin='round'"), 1u);  // only run A has a line
  EXPECT_NE(svg.find(">Pareto front</text>"), std::string::npos);
  EXPECT_NE(svg.find(">run A</text>"), std::string::npos);
  EXPECT_NE(svg.find(">run B</text>"), std::string::npos);
  EXPECT_NE(svg.find("fill='#1f77b4'"), std::string::npos);  // palette by index
  EXPECT_NE(svg.find("fill='#ff7f0e'"), std::string::npos);
  EXPECT_NE(svg.find("class='legend'"), std::string::npos);
  EXPECT_EQ(svg.find("no data"), std::string::npos);
}

TEST(SvgPlot, Deterministic) {
  Axes a;
  a.logy = true;
  a.hlines = {{1e-3, "target"}};
  std::vector<Series> s = {line({1, 2, 3}, {0.1, 0.01, 0.002}, Series::Style::Steps, "front")};
  s[0].labels = {"x", "sin(x)", "x*x"};
  const std::string first = svgPlot(a, s);
  EXPECT_EQ(first, svgPlot(a, s));
  s[0].y[2] = 0.003;
  EXPECT_NE(first, svgPlot(a, s));
  const Heatmap h = grid(8, 5);
  EXPECT_EQ(svgHeatmap(h), svgHeatmap(h));
}

namespace {

// A C locale with a decimal comma for printf and friends: an installed one, else one built
// with localedef into a temporary LOCPATH (glibc reads LOCPATH on every setlocale). Returns
// its name, or "" when neither works (then only the C++ locale is checked).
std::string commaCLocale(const fs::path& tmp) {
  for (const char* name : {"de_DE.UTF-8", "de_DE.utf8", "fr_FR.UTF-8", "fr_FR.utf8"})
    if (std::setlocale(LC_NUMERIC, name)) return name;
  if (!fs::exists("/usr/share/i18n/locales/de_DE")) return "";
  fs::create_directories(tmp);
  const std::string cmd = "localedef -i de_DE -f ISO-8859-1 '" +
                          (tmp / "de_DE.ISO-8859-1").string() + "' > /dev/null 2>&1";
  if (std::system(cmd.c_str()) != 0) return "";
  ::setenv("LOCPATH", tmp.c_str(), 1);
  return std::setlocale(LC_NUMERIC, "de_DE.ISO-8859-1") ? "de_DE.ISO-8859-1" : "";
}

// Equal, else where they first differ (whole plots would bury the difference).
::testing::AssertionResult same(const std::string& a, const std::string& b) {
  if (a == b) return ::testing::AssertionSuccess();
  size_t i = 0;
  while (i < a.size() && i < b.size() && a[i] == b[i]) ++i;
  const size_t from = i < 40 ? 0 : i - 40;
  return ::testing::AssertionFailure() << "differ at byte " << i << ": \"" << a.substr(from, 80)
                                       << "\" vs \"" << b.substr(from, 80) << "\"";
}

struct Outputs {
  std::string plot, heat, row, number;
};
Outputs everything() {
  Axes a;
  a.width = 1234;
  a.logy = true;
  a.hlines = {{0.015, "target 1.5%"}};
  std::vector<Series> s = {line({0.5, 1.25, 2000.75}, {1.5, 2.5, 1e6}, Series::Style::Line),
                           line({1, 2}, {0.01, 0.02}, Series::Style::Steps, "front 0.5 min")};
  s[1].labels = {"1.5", "2.25"};
  Heatmap h = grid(6, 4);
  h.xs = {0.5, 1.25, 2.5, 1000.5, 2000.25, 3000.125};
  Heatmap d = h;
  d.diverging = true;
  Axes b;
  b.xmin = 0.25, b.xmax = 1.75;
  return {svgPlot(a, s), svgHeatmap(h) + svgHeatmap(d), svgRow({{a, s}, {b, {s[1]}}}),
          formatNumber(1234.5678, 8) + " " + formatNumber(0.000125, 3)};
}

}  // namespace

TEST(SvgPlot, LocaleDoesNotChangeOutput) {
  const Outputs plain = everything();
  const fs::path tmp =
      fs::temp_directory_path() / ("lgp_svg_plot_locale_" + std::to_string(::getpid()));
  const std::string cname = commaCLocale(tmp);
  const std::locale old =
      std::locale::global(std::locale(std::locale::classic(), new CommaDecimal));
  // The locales are in effect: a number that went through a stream or printf would change.
  std::ostringstream probe;
  probe << 1234.5;
  char cbuf[32] = "";
  std::snprintf(cbuf, sizeof cbuf, "%.1f", 0.5);
  const Outputs localized = everything();
  std::locale::global(old);
  std::setlocale(LC_NUMERIC, "C");
  fs::remove_all(tmp);
  EXPECT_EQ(probe.str(), "1.234,5");
  if (!cname.empty()) {
    EXPECT_STREQ(cbuf, "0,5") << cname;
  } else {
    std::fprintf(stderr, "note: no C locale with a decimal comma; printf is not checked\n");
  }
  EXPECT_TRUE(same(plain.plot, localized.plot));
  EXPECT_TRUE(same(plain.heat, localized.heat));
  EXPECT_TRUE(same(plain.row, localized.row));
  EXPECT_EQ(plain.number, localized.number);
  EXPECT_EQ(plain.number, "1234.5678 0.000125");
}

TEST(SvgPlot, FormatNumberIsPrintfG) {
  for (double v : {0.0, 1.0, -2.5, 1234.5678, 1e-5, 0.000125, 123456789.0, 6.02214076e23, 1e300,
                   -1e-300, 0.1, 2.0 / 3.0})
    for (int sig : {1, 3, 4, 6, 12, 17}) {
      char b[64];
      std::snprintf(b, sizeof b, "%.*g", sig, v);
      EXPECT_EQ(formatNumber(v, sig), b) << v << " " << sig;
    }
  EXPECT_EQ(formatNumber(-0.0, 4), "0");
  EXPECT_EQ(formatNumber(kNaN, 4), "nan");
  EXPECT_EQ(formatNumber(-INFINITY, 4), "-inf");
  EXPECT_EQ(formatNumber(0.5, 0), "0.5");  // clamped to at least one digit
}

TEST(SvgPlot, RowPutsEachPlotInItsOwnColumn) {
  Axes a, b;
  a.title = "left";
  a.width = 300;
  a.height = 200;
  b.title = "right";
  b.width = 400;
  b.height = 250;
  b.generator = "not used";
  const std::vector<Series> s = {line({0, 1}, {0, 1}, Series::Style::LineMarkers, "s")};
  const std::string row = svgRow({{a, s}, {b, s}});
  EXPECT_TRUE(wellFormed(row));
  EXPECT_EQ(row.rfind("<svg xmlns='http://www.w3.org/2000/svg' width='700' height='250' "
                      "viewBox='0 0 700 250'",
                      0),
            0u);
  EXPECT_EQ(count(row, "<!-- generated by lgp -->"), 1u);  // the first plot's generator
  // Each column holds exactly what svgPlot draws inside its <svg> element.
  const auto body = [](const std::string& svg) {
    const std::string bg = "<rect width='100%' height='100%' fill='#fff'/>\n";
    const size_t b0 = svg.find(bg) + bg.size();
    return svg.substr(b0, svg.size() - b0 - std::strlen("</svg>\n"));
  };
  const std::string left = "<g transform='translate(0 0)'>\n" + body(svgPlot(a, s)) + "</g>\n";
  const std::string right = "<g transform='translate(300 0)'>\n" + body(svgPlot(b, s)) + "</g>\n";
  EXPECT_NE(row.find(left + right + "</svg>\n"), std::string::npos);
  EXPECT_TRUE(wellFormed(svgRow({})));
}

TEST(SvgPlot, GeneratorIsNamedInAComment) {
  Axes a;
  EXPECT_NE(svgPlot(a, {}).find("\n<!-- generated by lgp -->\n"), std::string::npos);
  a.generator = "lgp quality";
  EXPECT_NE(svgPlot(a, {}).find("\n<!-- generated by lgp quality -->\n"), std::string::npos);
  Heatmap h = grid(2, 2);
  h.generator = "a--b -->";  // would end the comment early
  const std::string heat = svgHeatmap(h);
  EXPECT_TRUE(wellFormed(heat));
  EXPECT_NE(heat.find("<!-- generated by a-b -&gt; -->"), std::string::npos);
}

TEST(SvgPlot, EscapesAllText) {
  Axes a;
  a.title = "a<b & c>\"d'";
  a.xlabel = "x<1";
  a.ylabel = "y&z";
  a.hlines = {{2, "target <1%"}};
  Series s = line({1, 2}, {1, 3}, Series::Style::LineMarkers, "f(x) = x<2 ? 'a' : \"b\"");
  s.labels = {"p&q", ""};
  s.color = "red' onload='x";
  const std::string svg = svgPlot(a, {s});
  EXPECT_TRUE(wellFormed(svg));
  EXPECT_NE(svg.find("a&lt;b &amp; c&gt;&quot;d&apos;"), std::string::npos);
  EXPECT_NE(svg.find(">x&lt;1</text>"), std::string::npos);
  EXPECT_NE(svg.find(">y&amp;z</text>"), std::string::npos);
  EXPECT_NE(svg.find(">target &lt;1%</text>"), std::string::npos);
  EXPECT_NE(svg.find(">p&amp;q</text>"), std::string::npos);
  EXPECT_NE(svg.find("f(x) = x&lt;2 ? &apos;a&apos; : &quot;b&quot;"), std::string::npos);
  EXPECT_NE(svg.find("fill='red&apos; onload=&apos;x'"), std::string::npos);
  EXPECT_EQ(svg.find("a<b"), std::string::npos);
  EXPECT_EQ(svg.find("onload='"), std::string::npos);

  // Control characters and malformed UTF-8 would make the file unparsable.
  Heatmap h = grid(2, 2);
  h.title = "bad\x01 utf8 \xff\xc3 ok \xc3\xa9 \xe2\x80\xa6";
  const std::string heat = svgHeatmap(h);
  EXPECT_TRUE(wellFormed(heat));
  EXPECT_NE(heat.find(">bad  utf8 \xef\xbf\xbd\xef\xbf\xbd ok \xc3\xa9 \xe2\x80\xa6</text>"),
            std::string::npos);
}

TEST(SvgPlot, LogAxesSkipNonPositiveValues) {
  Axes a;
  a.logx = a.logy = true;
  const std::string svg =
      svgPlot(a, {line({-1, 0, 1, 10, 100}, {1, 10, 0, 1000, 1e4}, Series::Style::Markers, "m")});
  EXPECT_TRUE(wellFormed(svg));
  EXPECT_EQ(count(svg, "<circle"), 2u + 1u);  // (10, 1e3), (100, 1e4) + legend
  // Whole decades: x 10..100, y 1e3..1e4, labelled as numbers or 10^k.
  EXPECT_NE(svg.find(">10</text>"), std::string::npos);
  EXPECT_NE(svg.find(">100</text>"), std::string::npos);
  EXPECT_NE(svg.find(">1000</text>"), std::string::npos);
  EXPECT_NE(svg.find(">10<tspan dy='-5' font-size='8'>4</tspan></text>"), std::string::npos);
  EXPECT_EQ(svg.find("no data"), std::string::npos);
  // Minor ticks 2..9 between the decades on both axes: 8 each, as 3 px marks.
  EXPECT_EQ(count(svg, "v3"), 8u);
  EXPECT_EQ(count(svg, "h-3"), 8u);

  // 24 decades on a 412 px axis: every third decade labelled, the others are minor ticks.
  Axes wide;
  wide.logy = true;
  const std::string many = svgPlot(wide, {line({1, 2}, {1e-12, 1e12}, Series::Style::Line)});
  EXPECT_TRUE(wellFormed(many));
  const std::string ticks = group(many, "<g class='ticks'");
  EXPECT_EQ(count(ticks, "text-anchor='end'"), 9u);
  EXPECT_NE(ticks.find(">10<tspan dy='-5' font-size='8'>-12</tspan>"), std::string::npos);
  EXPECT_NE(ticks.find(">0.001</text>"), std::string::npos);
  EXPECT_EQ(ticks.find(">0.01</text>"), std::string::npos);
  EXPECT_EQ(count(ticks, "h-3"), 16u);

  // A line breaks at a skipped point: two sub-paths.
  const std::string broken =
      svgPlot(a, {line({1, 2, 3, 4, 5}, {1, 2, -1, 4, 5}, Series::Style::Line)});
  EXPECT_TRUE(wellFormed(broken));
  const size_t d = broken.find("stroke-linejoin='round' d='");
  ASSERT_NE(d, std::string::npos);
  const std::string path = broken.substr(d, broken.find("'/>", d) - d);
  EXPECT_EQ(count(path, "M"), 2u);
  EXPECT_EQ(count(path, "L"), 2u);

  // Nothing positive at all: no data, still a valid plot.
  const std::string none = svgPlot(a, {line({-1, 0}, {-2, -3}, Series::Style::LineMarkers)});
  EXPECT_TRUE(wellFormed(none));
  EXPECT_NE(none.find(">no data</text>"), std::string::npos);
}

TEST(SvgPlot, EmptyAndNaNData) {
  for (const auto& series : std::vector<std::vector<Series>>{
           {},
           {Series{}},
           {line({kNaN, kNaN}, {1, 2}, Series::Style::LineMarkers)},
           {line({1, 2, 3}, {}, Series::Style::Line)},
           {line({INFINITY, 1e308}, {-INFINITY, 2}, Series::Style::Steps)}}) {
    Axes a;
    a.title = "empty";
    a.hlines = {{kNaN, "nan line"}};
    const std::string svg = svgPlot(a, series);
    EXPECT_TRUE(wellFormed(svg)) << series.size();
    EXPECT_NE(svg.find(">no data</text>"), std::string::npos);
    EXPECT_EQ(count(svg, "<circle"), 0u);
    EXPECT_EQ(svg.find("nan line"), std::string::npos);
  }
}

TEST(SvgPlot, DegenerateRanges) {
  Axes a;  // no title, no legend: plot area x 72..704, y 20..432
  const std::string one = svgPlot(a, {line({3}, {-7}, Series::Style::Markers)});
  EXPECT_TRUE(wellFormed(one));
  EXPECT_NE(one.find("<circle cx='388' cy='226' r='3.5'/>"), std::string::npos);  // centred

  const std::string zeros = svgPlot(a, {line({0, 0}, {0, 0}, Series::Style::LineMarkers)});
  EXPECT_TRUE(wellFormed(zeros));
  EXPECT_NE(zeros.find("<circle cx='388' cy='226' r='3.5'/>"), std::string::npos);
  EXPECT_NE(zeros.find(">-1</text>"), std::string::npos);  // widened to [-1, 1]

  Axes fixedEqual;
  fixedEqual.xmin = fixedEqual.xmax = 5;
  fixedEqual.ymin = 2, fixedEqual.ymax = -2;  // swapped
  EXPECT_TRUE(wellFormed(svgPlot(fixedEqual, {line({5, 5}, {0, 1}, Series::Style::Line)})));

  Axes logEqual;
  logEqual.logx = logEqual.logy = true;
  logEqual.xmin = logEqual.xmax = 10;
  const std::string logSvg = svgPlot(logEqual, {line({10}, {10}, Series::Style::Markers)});
  EXPECT_TRUE(wellFormed(logSvg));
  EXPECT_NE(logSvg.find("<circle cx='388' cy='226' r='3.5'/>"), std::string::npos);

  // Huge, tiny and nearly equal magnitudes.
  for (const auto& [x0, x1] : std::vector<std::pair<double, double>>{
           {-1e300, 1e300}, {1e-300, 2e-300}, {1e15, 1e15 + 1}, {0.1, 0.1 + 1e-17}}) {
    const std::string svg = svgPlot(a, {line({x0, x1}, {x1, x0}, Series::Style::LineMarkers)});
    EXPECT_TRUE(wellFormed(svg)) << x0 << " " << x1;
    EXPECT_EQ(svg.find("no data"), std::string::npos);
  }
  // Sizes below the minimum are enlarged rather than giving a negative plot area.
  Axes tiny;
  tiny.width = tiny.height = 0;
  const std::string small = svgPlot(tiny, {line({1, 2}, {1, 2}, Series::Style::Line, "n")});
  EXPECT_TRUE(wellFormed(small));
  EXPECT_NE(small.find("width='240' height='180'"), std::string::npos);
}

TEST(SvgPlot, NiceLinearTicks) {
  Axes a;
  const std::string svg = svgPlot(a, {line({0, 1}, {0, 100}, Series::Style::Line)});
  const std::string ticks = group(svg, "<g class='ticks'");
  for (const char* label :
       {">0</text>", ">0.2</text>", ">0.4</text>", ">1</text>", ">10</text>", ">100</text>"})
    EXPECT_NE(ticks.find(label), std::string::npos) << label;
  EXPECT_EQ(ticks.find(">0.25</text>"), std::string::npos);
  EXPECT_EQ(ticks.find(">0.5</text>"), std::string::npos);
  EXPECT_EQ(count(ticks, "<text"), 6u + 11u);  // 0..1 by 0.2, 0..100 by 10

  // A narrower plot (legend column) gets coarser steps: 0..25 by 5, not by 2 or 10.
  const std::string narrow =
      svgPlot(a, {line({1, 25}, {0, 1}, Series::Style::Line, "a legend entry")});
  const std::string xt = group(narrow, "<g class='ticks'");
  EXPECT_NE(xt.find(">25</text>"), std::string::npos);
  EXPECT_EQ(count(xt, "text-anchor='middle'"), 6u);
}

TEST(SvgPlot, FixedRangeClipsLinesAndMarkers) {
  Axes a;
  a.xmin = a.ymin = 0;
  a.xmax = a.ymax = 5;
  const std::string svg = svgPlot(a, {line({0, 10}, {0, 10}, Series::Style::LineMarkers)});
  EXPECT_TRUE(wellFormed(svg));
  EXPECT_NE(svg.find("d='M72 432L704 20'"), std::string::npos);  // cut at the frame corner
  EXPECT_EQ(count(svg, "<circle"), 1u);                          // (10, 10) is outside

  // Segments wholly outside draw nothing, whichever way they run.
  for (const auto& [x, y] : std::vector<std::pair<std::vector<double>, std::vector<double>>>{
           {{6, 7}, {6, 7}}, {{7, 6}, {7, 6}}, {{-1, 6}, {6, 7}}, {{6, -1}, {-1, -2}}}) {
    const std::string out = svgPlot(a, {line(x, y, Series::Style::LineMarkers)});
    EXPECT_TRUE(wellFormed(out));
    EXPECT_EQ(count(out, "stroke-linejoin"), 0u) << x[0] << " " << x[1];
    EXPECT_EQ(count(out, "<circle"), 0u);
    EXPECT_EQ(out.find("no data"), std::string::npos);  // data exists, just not in view
  }

  // Only one end fixed beyond the data: the fixed end stays, the other one follows it.
  Axes from3;
  from3.xmin = 3;
  const std::string shifted = svgPlot(from3, {line({0, 1}, {0, 1}, Series::Style::Markers)});
  EXPECT_TRUE(wellFormed(shifted));
  const std::string ticks = group(shifted, "<g class='ticks'");
  EXPECT_NE(ticks.find(">3</text>"), std::string::npos);
  EXPECT_NE(ticks.find(">3.5</text>"), std::string::npos);
  EXPECT_EQ(count(shifted, "<circle"), 0u);
}

TEST(SvgPlot, StepsDrawAStaircase) {
  Axes a;
  a.xmin = 0, a.xmax = 5, a.ymin = 0, a.ymax = 4;
  Series s = line({1, 2, 4}, {3, 2, 1}, Series::Style::Steps);
  s.marker = Series::Marker::Diamond;
  const std::string svg = svgPlot(a, {s});
  EXPECT_TRUE(wellFormed(svg));
  // X(v) = 72 + 126.4 v, Y(v) = 432 - 103 v.
  EXPECT_NE(svg.find("d='M198.4 123L324.8 123L324.8 226L577.6 226L577.6 329'"), std::string::npos);
  EXPECT_EQ(count(svg, "l4.4 4.4l-4.4 4.4l-4.4 -4.4z"), 3u);  // a diamond per point
}

TEST(SvgPlot, ReferenceLinesAndLabels) {
  Axes a;
  a.hlines = {{0.01, "target"}};
  Series s = line({1, 2}, {1, 2}, Series::Style::Markers, "s");
  s.labels = {"first"};  // shorter than the data: the rest have none
  s.marker = Series::Marker::Cross;
  s.color = "#123456";
  const std::string svg = svgPlot(a, {s});
  EXPECT_TRUE(wellFormed(svg));
  EXPECT_EQ(count(svg, "class='hline'"), 1u);  // the automatic range takes it in
  EXPECT_NE(svg.find(">target</text>"), std::string::npos);
  EXPECT_NE(svg.find(">first</text>"), std::string::npos);
  EXPECT_NE(svg.find("fill='#123456' stroke='#123456'"), std::string::npos);
  EXPECT_EQ(count(svg, "l7 7m0 -7l-7 7"), 3u);  // two points + legend

  a.ymin = 0.5;  // a fixed range can leave it out
  EXPECT_EQ(count(svgPlot(a, {s}), "class='hline'"), 0u);
}

TEST(SvgPlot, LongLegendNamesAreShortened) {
  Axes a;
  const std::string name(500, 'n');
  const std::string svg = svgPlot(a, {line({1, 2}, {1, 2}, Series::Style::Line, name)});
  EXPECT_TRUE(wellFormed(svg));
  EXPECT_EQ(svg.find(name), std::string::npos);
  EXPECT_NE(svg.find("nnn\xe2\x80\xa6</text>"), std::string::npos);
}

TEST(SvgPlot, LegendNamesThatFitAreWhole) {
  Axes a;  // 720 wide: the legend column grows to 288 px, room for 36 characters
  for (size_t n = 1; n <= 36; ++n) {
    const std::string name(n, 'x');
    const std::string svg = svgPlot(a, {line({1, 2}, {1, 2}, Series::Style::Line, name)});
    EXPECT_NE(svg.find(">" + name + "</text>"), std::string::npos) << n;
  }
}

TEST(SvgHeatmap, OneRectPerCellAndGreyNaN) {
  Heatmap h = grid(5, 3);
  h.values[7] = kNaN;
  const std::string svg = svgHeatmap(h);
  EXPECT_TRUE(wellFormed(svg));
  const std::string cells = group(svg, "<g class='cells'");
  EXPECT_EQ(count(cells, "<rect"), 15u);
  EXPECT_EQ(count(cells, "fill='#b0b0b0'"), 1u);
  // Rows top down: iy = 1 is the middle one; its third cell is the grey one.
  const std::string row = group(cells, "<g transform='translate(0 1)'>");
  EXPECT_EQ(count(row, "<rect"), 5u);
  const size_t at = row.find("<rect x='2' ");
  ASSERT_NE(at, std::string::npos);
  EXPECT_NE(row.substr(at, row.find('\n', at) - at).find("fill='#b0b0b0'"), std::string::npos);
  EXPECT_NE(svg.find(">not finite</text>"), std::string::npos);
  EXPECT_NE(svg.find(">abs error</text>"), std::string::npos);
  EXPECT_EQ(count(group(svg, "<g class='colorbar'"), "<rect"), 64u + 1u + 1u);

  // Missing values (too short a vector) are drawn as not finite too.
  h.values.resize(10);
  const std::string shortSvg = svgHeatmap(h);
  EXPECT_TRUE(wellFormed(shortSvg));
  EXPECT_EQ(count(group(shortSvg, "<g class='cells'"), "fill='#b0b0b0'"), 1u + 5u);
}

TEST(SvgHeatmap, Grid64IsSmall) {
  const Heatmap h = grid(64, 64);
  const std::string svg = svgHeatmap(h);
  EXPECT_TRUE(wellFormed(svg));
  EXPECT_EQ(count(group(svg, "<g class='cells'"), "<rect"), 64u * 64u);
  EXPECT_LT(svg.size(), 300u * 1024u);
  EXPECT_EQ(svg.find("not finite"), std::string::npos);
}

TEST(SvgHeatmap, ColourScales) {
  Heatmap h = grid(3, 1);
  h.values = {-2, 0, 2};
  h.diverging = true;
  std::string svg = svgHeatmap(h);
  EXPECT_TRUE(wellFormed(svg));
  std::string cells = group(svg, "<g class='cells'");
  EXPECT_NE(cells.find("fill='#2166ac'"), std::string::npos);  // -max: blue end
  EXPECT_NE(cells.find("fill='#f7f7f7'"), std::string::npos);  // zero: white centre
  EXPECT_NE(cells.find("fill='#b2182b'"), std::string::npos);  // +max: red end

  h.diverging = false;
  h.log_scale = true;
  h.values = {0, 1e-3, 10};  // 0 cannot be logged: minimum colour
  svg = svgHeatmap(h);
  EXPECT_TRUE(wellFormed(svg));
  cells = group(svg, "<g class='cells'");
  EXPECT_EQ(count(cells, "fill='#440154'"), 2u);
  EXPECT_EQ(count(cells, "fill='#fde725'"), 1u);
  EXPECT_NE(svg.find(">0.001</text>"), std::string::npos);  // decade ticks on the colour bar
  EXPECT_NE(svg.find(">10</text>"), std::string::npos);

  h.log_scale = false;
  h.values = {4, 4, 4};  // constant: the middle colour, not a division by zero
  svg = svgHeatmap(h);
  EXPECT_TRUE(wellFormed(svg));
  EXPECT_EQ(count(group(svg, "<g class='cells'"), "fill='#21918c'"), 3u);
}

TEST(SvgHeatmap, EmptyGrid) {
  Heatmap h;
  const std::string svg = svgHeatmap(h);
  EXPECT_TRUE(wellFormed(svg));
  EXPECT_NE(svg.find(">no data</text>"), std::string::npos);
  EXPECT_EQ(svg.find("class='cells'"), std::string::npos);
  h.xs = {1, 2};
  h.ys = {1};
  const std::string allNaN = svgHeatmap(h);  // no values at all
  EXPECT_TRUE(wellFormed(allNaN));
  EXPECT_EQ(count(group(allNaN, "<g class='cells'"), "fill='#b0b0b0'"), 2u);
}

TEST(WriteTextFile, CreatesDirectoriesAndReportsFailure) {
  const fs::path dir =
      fs::temp_directory_path() / ("lgp_svg_plot_test_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  const std::string text = "<svg>\r\n</svg>\n";
  std::string error;
  ASSERT_TRUE(writeTextFile((dir / "a" / "b" / "p.svg").string(), text, &error)) << error;
  std::ifstream in(dir / "a" / "b" / "p.svg", std::ios::binary);
  std::stringstream back;
  back << in.rdbuf();
  EXPECT_EQ(back.str(), text);

  // A file where a directory should be.
  EXPECT_FALSE(writeTextFile((dir / "a" / "b" / "p.svg" / "x.svg").string(), text, &error));
  EXPECT_NE(error.find("p.svg"), std::string::npos);
  error.clear();
  EXPECT_FALSE(writeTextFile("", text, &error));
  EXPECT_FALSE(error.empty());
  EXPECT_FALSE(writeTextFile((dir / "a").string(), text, nullptr));  // a directory
  fs::remove_all(dir);
}
