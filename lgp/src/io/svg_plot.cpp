// The project's SVG plotter (see svg_plot.hpp). Everything is appended to strings, never to a
// stream, so no locale reaches a number.
#include "lgp/io/svg_plot.hpp"

#include <algorithm>
#include <charconv>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string_view>
#include <system_error>
#include <tuple>

namespace lgp::plot {

namespace {

// Larger magnitudes count as non-finite: it keeps every span and pixel computation finite.
constexpr double kHuge = 1e300;
constexpr double kInf = std::numeric_limits<double>::infinity();

// Appends the pieces: the whole file is built from strings, so no stream locale can leak in.
template <class... T>
void put(std::string& o, const T&... parts) {
  (o.append(parts), ...);
}

std::string general(double v, int sig) {
  if (std::isnan(v)) return "nan";
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  char b[64];
  const auto r = std::to_chars(b, b + sizeof b, v, std::chars_format::general, sig);
  std::string s(b, r.ptr);
  return s == "-0" ? "0" : s;
}

// Fixed-point with at most `decimals` digits and no trailing zeros ("-0" becomes "0").
std::string fixed(double v, int decimals) {
  if (!std::isfinite(v)) return general(v, 4);
  char b[64];
  const auto r = std::to_chars(b, b + sizeof b, v, std::chars_format::fixed, decimals);
  if (r.ec != std::errc()) return general(v, 6);
  std::string s(b, r.ptr);
  if (s.find('.') != std::string::npos) {
    while (s.back() == '0') s.pop_back();
    if (s.back() == '.') s.pop_back();
  }
  return s == "-0" ? "0" : s;
}

// Pixel coordinate: 0.01 px is plenty and keeps files small.
std::string px(double v) {
  return fixed(std::clamp(std::isfinite(v) ? v : 0.0, -1e6, 1e6), 2);
}

std::string num(int v) {
  return std::to_string(v);
}

// XML text/attribute escaping. Control characters become spaces and malformed UTF-8 (or
// U+FFFE/FFFF) becomes U+FFFD: either would make the whole file unparsable.
std::string esc(std::string_view s) {
  std::string o;
  o.reserve(s.size());
  for (size_t i = 0; i < s.size();) {
    const auto c = static_cast<unsigned char>(s[i]);
    if (c < 0x80) {
      switch (c) {
        case '&':
          o += "&amp;";
          break;
        case '<':
          o += "&lt;";
          break;
        case '>':
          o += "&gt;";
          break;
        case '"':
          o += "&quot;";
          break;
        case '\'':
          o += "&apos;";
          break;
        default:
          o += c < 0x20 || c == 0x7f ? ' ' : static_cast<char>(c);
      }
      ++i;
      continue;
    }
    const size_t n = c >= 0xf0 ? 4 : c >= 0xe0 ? 3 : c >= 0xc2 ? 2 : 0;
    bool ok = n > 0 && c < 0xf5 && i + n <= s.size();
    for (size_t k = 1; ok && k < n; ++k) ok = (static_cast<unsigned char>(s[i + k]) & 0xc0) == 0x80;
    if (ok && n > 2) {  // overlong forms, surrogates, > U+10FFFF, U+FFFE/FFFF
      const auto c1 = static_cast<unsigned char>(s[i + 1]);
      const auto c2 = static_cast<unsigned char>(s[i + 2]);
      ok = !((c == 0xe0 && c1 < 0xa0) || (c == 0xed && c1 >= 0xa0) || (c == 0xf0 && c1 < 0x90) ||
             (c == 0xf4 && c1 >= 0x90) || (c == 0xef && c1 == 0xbf && c2 >= 0xbe));
    }
    if (ok) {
      o.append(s.substr(i, n));
      i += n;
    } else {
      o += "\xef\xbf\xbd";
      ++i;
    }
  }
  return o;
}

size_t codePoints(const std::string& s) {
  return static_cast<size_t>(
      std::count_if(s.begin(), s.end(), [](char c) { return (c & 0xc0) != 0x80; }));
}

// At most `n` code points (cut on a character boundary), with an ellipsis when cut.
std::string shorten(const std::string& s, size_t n) {
  if (codePoints(s) <= n) return s;
  if (n == 0) return {};
  size_t seen = 0, i = 0;
  for (; i < s.size(); ++i)
    if ((s[i] & 0xc0) != 0x80 && ++seen > n - 1) break;
  return s.substr(0, i) + "\xe2\x80\xa6";
}

struct Rgb {
  double r, g, b;
};

std::string ramp(const Rgb (&stops)[5], double t) {
  t = std::clamp(std::isfinite(t) ? t : 0.0, 0.0, 1.0) * 4.0;
  const int i = std::min(3, static_cast<int>(t));
  const double f = t - i;
  const auto mix = [&](double Rgb::*c) {
    return static_cast<int>(std::lround(stops[i].*c + f * (stops[i + 1].*c - stops[i].*c)));
  };
  char b[8];
  std::snprintf(b, sizeof b, "#%02x%02x%02x", mix(&Rgb::r), mix(&Rgb::g), mix(&Rgb::b));
  return b;
}

// Viridis (5 stops); RdBu (reversed: blue < 0 < red) for signed values.
const Rgb kViridis[5] = {{68, 1, 84}, {59, 82, 139}, {33, 145, 140}, {94, 201, 98}, {253, 231, 37}};
const Rgb kDiverging[5] = {
    {33, 102, 172}, {103, 169, 207}, {247, 247, 247}, {239, 138, 98}, {178, 24, 43}};
constexpr const char* kMissing = "#b0b0b0";

// The "tab10" line palette.
const char* const kPalette[] = {"#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd",
                                "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf"};

// ---------------------------------------------------------------------------------------------
// Axis ranges and ticks. "Axis space" is the value itself, or its log10 on a log axis.

struct Scale {
  double lo = 0, hi = 1;  // axis space, hi > lo
  bool log = false;
  bool valid(double v) const { return std::isfinite(v) && std::abs(v) <= kHuge && (!log || v > 0); }
  double fwd(double v) const { return log ? std::log10(v) : v; }
  double unit(double a) const { return (a - lo) / (hi - lo); }
};

bool tooNarrow(double lo, double hi) {
  return !(hi > lo) || !std::isfinite(hi - lo) ||
         hi - lo <= 1e-12 * std::max(std::abs(lo), std::abs(hi));
}

// A range around c when the data has no width: a decade either side on a log axis, else 10%.
std::pair<double, double> around(double c, bool log) {
  const double d = log ? 1.0 : c != 0 ? std::abs(c) * 0.1 : 1.0;
  return {c - d, c + d};
}

// The data extent [dlo, dhi] (axis space; dlo > dhi when there is none) padded by 5% or widened
// to whole decades; the fixed ends that are given (and valid on this axis) take precedence.
Scale makeScale(bool log, double dlo, double dhi, double fmin, double fmax) {
  Scale s;
  s.log = log;
  const bool fixLo = s.valid(fmin), fixHi = s.valid(fmax);
  double lo = 0, hi = 1;
  if (dlo > dhi) {
  } else if (tooNarrow(dlo, dhi)) {
    std::tie(lo, hi) = around(0.5 * (dlo + dhi), log);
  } else if (log) {
    lo = std::floor(dlo), hi = std::ceil(dhi);
  } else {
    lo = dlo - 0.05 * (dhi - dlo), hi = dhi + 0.05 * (dhi - dlo);
  }
  if (fixLo) lo = s.fwd(fmin);
  if (fixHi) hi = s.fwd(fmax);
  if (fixLo && fixHi && lo > hi) std::swap(lo, hi);
  if (tooNarrow(lo, hi)) {  // keep the fixed end, move the automatic one
    if (fixLo && !fixHi) {
      hi = lo + 2 * (around(lo, log).second - lo);
    } else if (fixHi && !fixLo) {
      lo = hi - 2 * (hi - around(hi, log).first);
    } else {
      std::tie(lo, hi) = around(0.5 * (lo + hi), log);
    }
  }
  if (tooNarrow(lo, hi)) lo = 0, hi = 1;
  s.lo = lo, s.hi = hi;
  return s;
}

// Enough digits to tell ticks `10^e` apart: fixed-point for everyday magnitudes, else %g.
std::string tickLabel(double v, int e, double mag) {
  if (v == 0) return "0";
  if (mag < 1e5 && e >= -4) return fixed(v, std::max(0, -e));
  const int lead = static_cast<int>(std::floor(std::log10(mag)));
  return general(v, std::clamp(lead - e + 1, 1, 12));
}

// 1-2-5 steps giving about `target` intervals over the values [lo, hi] (the step nearest to the
// ideal one on a log scale, so a plot gets neither 3 labels nor 15).
std::vector<std::pair<double, std::string>> niceTicks(double lo, double hi, int target) {
  std::vector<std::pair<double, std::string>> out;
  const double raw = (hi - lo) / std::max(target, 1);
  if (!(raw > 0) || !std::isfinite(raw)) return out;
  int e = static_cast<int>(std::floor(std::log10(raw)));
  const double f = raw / std::pow(10.0, e);
  int m = f < 1.5 ? 1 : f < 3.2 ? 2 : f < 7 ? 5 : 10;
  if (m == 10) m = 1, ++e;
  const double step = m * std::pow(10.0, e);
  const double k0 = std::ceil(lo / step - 1e-9), k1 = std::floor(hi / step + 1e-9);
  if (!(k1 - k0 >= 0 && k1 - k0 < 1000)) return out;  // also catches exhausted precision
  const double mag = std::max(std::abs(lo), std::abs(hi));
  for (int i = 0; i <= static_cast<int>(k1 - k0); ++i) {
    double v = (k0 + i) * step;
    if (std::abs(v) < step * 1e-6) v = 0;
    out.emplace_back(v, tickLabel(v, e, mag));
  }
  return out;
}

struct Ticks {
  std::vector<std::pair<double, std::string>> major;  // axis space, label markup
  std::vector<double> minor;                          // axis space
};

std::string decadeLabel(int d) {
  if (d >= -3 && d <= 3) return general(std::pow(10.0, d), 4);
  return "10<tspan dy='-5' font-size='8'>" + num(d) + "</tspan>";
}

// Ticks for an axis `pixels` long with about one label per `spacing` pixels. Log axes label
// decades (every n-th when crowded) with minor ticks between; spans under two decades fall back
// to 1-2-5 values.
Ticks axisTicks(const Scale& s, double pixels, double spacing) {
  Ticks t;
  const int target = std::max(2, static_cast<int>(pixels / spacing));
  if (!s.log) {
    t.major = niceTicks(s.lo, s.hi, target);
    return t;
  }
  const double d0 = std::ceil(s.lo - 1e-9), d1 = std::floor(s.hi + 1e-9);
  if (d1 - d0 >= 1) {
    const int n = static_cast<int>(d1 - d0) + 1;
    const int every = std::max(1, (n - 1 + target - 1) / target);
    for (int i = 0; i < n; ++i) {
      const int d = static_cast<int>(d0) + i;
      if (d % every == 0) {
        t.major.emplace_back(d, decadeLabel(d));
      } else {
        t.minor.push_back(d);
      }
    }
    if (every == 1 && s.hi - s.lo <= pixels / 50) {  // 2..9 only where they do not crowd
      for (int d = static_cast<int>(std::floor(s.lo)); d < s.hi; ++d)
        for (int m = 2; m <= 9; ++m) {
          const double a = d + std::log10(m);
          if (a >= s.lo && a <= s.hi) t.minor.push_back(a);
        }
    }
    return t;
  }
  for (const auto& [v, label] : niceTicks(std::pow(10.0, s.lo), std::pow(10.0, s.hi), target))
    if (v > 0) t.major.emplace_back(std::log10(v), label);
  return t;
}

// ---------------------------------------------------------------------------------------------
// Drawing helpers.

std::string open(int w, int h, const std::string& generator) {
  std::string by = esc(generator);  // "--" would end the comment early
  for (size_t i; (i = by.find("--")) != std::string::npos;) by.erase(i, 1);
  std::string o;
  put(o, "<svg xmlns='http://www.w3.org/2000/svg' width='", num(w), "' height='", num(h),
      "' viewBox='0 0 ", num(w), " ", num(h),
      "' font-family='sans-serif' font-size='12'>\n<!-- generated by ", by,
      " -->\n<rect width='100%' height='100%' fill='#fff'/>\n");
  return o;
}

// `markup` must already be escaped; `attrs` are extra literal attributes.
void text(std::string& o, double x, double y, std::string_view attrs, const std::string& markup) {
  put(o, "<text x='", px(x), "' y='", px(y), "'", attrs, ">", markup, "</text>\n");
}

void titles(std::string& o, int w, double fx, double fy, double fw, double fh, int h,
            const std::string& title, const std::string& xlabel, const std::string& ylabel) {
  if (!title.empty()) text(o, w / 2.0, 24, " text-anchor='middle' font-size='14'", esc(title));
  if (!xlabel.empty()) text(o, fx + fw / 2, h - 10, " text-anchor='middle'", esc(xlabel));
  if (!ylabel.empty()) {
    const double y = fy + fh / 2;
    put(o, "<text x='16' y='", px(y), "' transform='rotate(-90 16 ", px(y),
        ")' text-anchor='middle'>", esc(ylabel), "</text>\n");
  }
}

void noData(std::string& o, double x, double y) {
  text(o, x, y, " class='nodata' text-anchor='middle' fill='#888'", "no data");
}

int clampSize(int v, int lo) {
  return std::clamp(v, lo, 16384);
}

// The plot area and its two scales.
struct Frame {
  Scale sx, sy;
  double x = 0, y = 0, w = 1, h = 1;  // pixels
  double X(double a) const { return x + w * sx.unit(a); }
  double Y(double a) const { return y + h * (1 - sy.unit(a)); }
  bool inside(double ax, double ay) const {
    const double u = sx.unit(ax), v = sy.unit(ay);
    return u >= -1e-9 && u <= 1 + 1e-9 && v >= -1e-9 && v <= 1 + 1e-9;
  }
};

// Liang-Barsky: clips the segment (axis space) to the plot area; false when nothing is left.
bool clip(const Frame& f, double& x0, double& y0, double& x1, double& y1) {
  const double dx = x1 - x0, dy = y1 - y0;
  const double p[4] = {-dx, dx, -dy, dy};
  const double q[4] = {x0 - f.sx.lo, f.sx.hi - x0, y0 - f.sy.lo, f.sy.hi - y0};
  double t0 = 0, t1 = 1;
  for (int i = 0; i < 4; ++i) {
    if (p[i] == 0) {
      if (q[i] < 0) return false;
      continue;
    }
    const double r = q[i] / p[i];
    if (p[i] < 0) {
      if (r > t1) return false;
      t0 = std::max(t0, r);
    } else {
      if (r < t0) return false;
      t1 = std::min(t1, r);
    }
  }
  const double ax = x0 + t0 * dx, ay = y0 + t0 * dy;
  x1 = x0 + t1 * dx, y1 = y0 + t1 * dy;
  x0 = ax, y0 = ay;
  return true;
}

// A clipped polyline as one path: segments that continue where the last one ended extend it.
class PathBuilder {
 public:
  explicit PathBuilder(const Frame& f) : f_(f) {}
  void segment(double x0, double y0, double x1, double y1) {
    if (!clip(f_, x0, y0, x1, y1)) return;
    const std::string a = px(f_.X(x0)) + " " + px(f_.Y(y0));
    const std::string b = px(f_.X(x1)) + " " + px(f_.Y(y1));
    if (a != pen_) put(d_, "M", a);
    if (b != a) put(d_, "L", b);
    pen_ = b;
  }
  void lift() { pen_.clear(); }
  const std::string& d() const { return d_; }

 private:
  const Frame& f_;
  std::string d_, pen_;
};

void marker(std::string& o, Series::Marker m, double x, double y) {
  const std::string X = px(x), Y = px(y);
  switch (m) {
    case Series::Marker::Circle:
      put(o, "<circle cx='", X, "' cy='", Y, "' r='3.5'/>\n");
      break;
    case Series::Marker::Square:
      put(o, "<rect x='", px(x - 3.2), "' y='", px(y - 3.2), "' width='6.4' height='6.4'/>\n");
      break;
    case Series::Marker::Diamond:
      put(o, "<path d='M", X, " ", px(y - 4.4), "l4.4 4.4l-4.4 4.4l-4.4 -4.4z'/>\n");
      break;
    case Series::Marker::Triangle:
      put(o, "<path d='M", X, " ", px(y - 4.4), "l4 7h-8z'/>\n");
      break;
    case Series::Marker::Cross:
      put(o, "<path d='M", px(x - 3.5), " ", px(y - 3.5), "l7 7m0 -7l-7 7'/>\n");
      break;
  }
}

// Filled markers get a thin white outline so overlapping ones stay apart; the cross is a stroke.
const char* markerGroup(Series::Marker m) {
  return m == Series::Marker::Cross ? "<g fill='none' stroke-width='1.6'>\n"
                                    : "<g stroke='#fff' stroke-width='0.6'>\n";
}

bool hasLine(Series::Style s) {
  return s != Series::Style::Markers;
}
bool hasMarkers(Series::Style s) {
  return s != Series::Style::Line;
}

std::string seriesColor(const Series& s, size_t k) {
  return s.color.empty() ? kPalette[k % std::size(kPalette)] : esc(s.color);
}

void axisTicksSvg(std::string& o, const Frame& f) {
  const Ticks tx = axisTicks(f.sx, f.w, 90), ty = axisTicks(f.sy, f.h, 50);
  const double bottom = f.y + f.h;
  std::string grid, marks;
  for (const auto& [a, label] : tx.major) {
    put(grid, "M", px(f.X(a)), " ", px(f.y), "v", px(f.h));
    put(marks, "M", px(f.X(a)), " ", px(bottom), "v5");
  }
  for (const auto& [a, label] : ty.major) {
    put(grid, "M", px(f.x), " ", px(f.Y(a)), "h", px(f.w));
    put(marks, "M", px(f.x), " ", px(f.Y(a)), "h-5");
  }
  for (double a : tx.minor) put(marks, "M", px(f.X(a)), " ", px(bottom), "v3");
  for (double a : ty.minor) put(marks, "M", px(f.x), " ", px(f.Y(a)), "h-3");
  if (!grid.empty()) put(o, "<path class='grid' fill='none' stroke='#ececec' d='", grid, "'/>\n");
  put(o, "<g class='ticks' font-size='10' fill='#333'>\n");
  if (!marks.empty()) put(o, "<path fill='none' stroke='#888' d='", marks, "'/>\n");
  for (const auto& [a, label] : tx.major)
    text(o, f.X(a), bottom + 17, " text-anchor='middle'", label);
  for (const auto& [a, label] : ty.major)
    text(o, f.x - 7, f.Y(a) + 3.5, " text-anchor='end'", label);
  put(o, "</g>\n");
}

int plotWidth(const Axes& axes) {
  return clampSize(axes.width, 240);
}
int plotHeight(const Axes& axes) {
  return clampSize(axes.height, 180);
}

// Everything of one x/y plot inside its <svg> element, in its own coordinates.
void drawPlot(std::string& o, const Axes& axes, const std::vector<Series>& series) {
  const int W = plotWidth(axes), H = plotHeight(axes);

  // A fixed legend column right of the plot: it never covers data.
  size_t longest = 0;
  for (const auto& s : series) longest = std::max(longest, codePoints(s.name));
  const double legendW = longest == 0 ? 0 : std::clamp(longest * 6.4 + 52, 90.0, 0.4 * W);
  // The epsilon keeps a column sized for n characters from holding n - 1 (57.6 / 6.4 < 9).
  const size_t legendChars = static_cast<size_t>(std::max(3.0, (legendW - 52) / 6.4 + 1e-9));

  Frame f;
  f.x = 72, f.y = axes.title.empty() ? 20 : 40;
  f.w = W - f.x - 16 - legendW, f.h = H - f.y - 48;

  // Data extent over points valid on both axes, plus the reference lines.
  Scale vx, vy;
  vx.log = axes.logx, vy.log = axes.logy;
  double xlo = kInf, xhi = -kInf, ylo = kInf, yhi = -kInf;
  size_t points = 0;
  for (const auto& s : series)
    for (size_t i = 0; i < std::min(s.x.size(), s.y.size()); ++i) {
      if (!vx.valid(s.x[i]) || !vy.valid(s.y[i])) continue;
      const double a = vx.fwd(s.x[i]), b = vy.fwd(s.y[i]);
      xlo = std::min(xlo, a), xhi = std::max(xhi, a), ylo = std::min(ylo, b),
      yhi = std::max(yhi, b);
      ++points;
    }
  for (const auto& [v, label] : axes.hlines)
    if (vy.valid(v)) ylo = std::min(ylo, vy.fwd(v)), yhi = std::max(yhi, vy.fwd(v));
  f.sx = makeScale(axes.logx, xlo, xhi, axes.xmin, axes.xmax);
  f.sy = makeScale(axes.logy, ylo, yhi, axes.ymin, axes.ymax);

  titles(o, W, f.x, f.y, f.w, f.h, H, axes.title, axes.xlabel, axes.ylabel);
  axisTicksSvg(o, f);

  for (const auto& [v, label] : axes.hlines) {
    if (!f.sy.valid(v) || !f.inside(f.sx.lo, f.sy.fwd(v))) continue;
    const double y = f.Y(f.sy.fwd(v));
    put(o, "<path class='hline' fill='none' stroke='#555' stroke-dasharray='6 4' d='M", px(f.x),
        " ", px(y), "h", px(f.w), "'/>\n");
    if (!label.empty())
      text(o, f.x + f.w - 4, y - 4, " text-anchor='end' font-size='10' fill='#555'", esc(label));
  }

  for (size_t k = 0; k < series.size(); ++k) {
    const Series& s = series[k];
    const size_t n = std::min(s.x.size(), s.y.size());
    std::vector<std::pair<double, double>> p(n, {NAN, NAN});  // axis space; NaN = skipped
    for (size_t i = 0; i < n; ++i)
      if (f.sx.valid(s.x[i]) && f.sy.valid(s.y[i])) p[i] = {f.sx.fwd(s.x[i]), f.sy.fwd(s.y[i])};
    const std::string c = seriesColor(s, k);
    put(o, "<g class='series' fill='", c, "' stroke='", c, "'>\n");
    if (hasLine(s.style)) {
      PathBuilder path(f);
      const std::pair<double, double>* prev = nullptr;
      for (const auto& q : p) {
        if (std::isnan(q.first)) {
          path.lift(), prev = nullptr;
          continue;
        }
        if (prev && s.style == Series::Style::Steps) {
          path.segment(prev->first, prev->second, q.first, prev->second);
          path.segment(q.first, prev->second, q.first, q.second);
        } else if (prev) {
          path.segment(prev->first, prev->second, q.first, q.second);
        }
        prev = &q;
      }
      if (!path.d().empty())
        put(o, "<path fill='none' stroke-width='1.8' stroke-linejoin='round' d='", path.d(),
            "'/>\n");
    }
    if (hasMarkers(s.style)) {
      o += markerGroup(s.marker);
      for (const auto& [a, b] : p)
        if (!std::isnan(a) && f.inside(a, b)) marker(o, s.marker, f.X(a), f.Y(b));
      o += "</g>\n";
    }
    std::string labels;
    for (size_t i = 0; i < std::min(n, s.labels.size()); ++i)
      if (!s.labels[i].empty() && !std::isnan(p[i].first) && f.inside(p[i].first, p[i].second))
        text(labels, f.X(p[i].first) + 6, f.Y(p[i].second) - 6, "", esc(s.labels[i]));
    if (!labels.empty()) put(o, "<g stroke='none' font-size='10'>\n", labels, "</g>\n");
    o += "</g>\n";
  }

  put(o, "<rect x='", px(f.x), "' y='", px(f.y), "' width='", px(f.w), "' height='", px(f.h),
      "' fill='none' stroke='#888'/>\n");
  if (points == 0) noData(o, f.x + f.w / 2, f.y + f.h / 2);

  if (legendW > 0) {
    const double lx = f.x + f.w + 12;
    size_t rows = 0;
    for (const auto& s : series) rows += !s.name.empty();
    put(o, "<g class='legend' font-size='11'>\n<rect x='", px(lx), "' y='", px(f.y), "' width='",
        px(legendW - 12), "' height='", px(8 + 18.0 * rows), "' fill='#fff' stroke='#ccc'/>\n");
    size_t row = 0;
    for (size_t k = 0; k < series.size(); ++k) {
      const Series& s = series[k];
      if (s.name.empty()) continue;
      const double y = f.y + 16 + 18.0 * row++;
      const std::string c = seriesColor(s, k);
      put(o, "<g fill='", c, "' stroke='", c, "'>\n");
      if (s.style == Series::Style::Steps) {
        put(o, "<path fill='none' stroke-width='1.8' d='M", px(lx + 6), " ", px(y - 4),
            "h11v8h11'/>\n");
      } else if (hasLine(s.style)) {
        put(o, "<path fill='none' stroke-width='1.8' d='M", px(lx + 6), " ", px(y), "h22'/>\n");
      }
      if (hasMarkers(s.style)) {
        o += markerGroup(s.marker);
        marker(o, s.marker, lx + 17, y);
        o += "</g>\n";
      }
      text(o, lx + 34, y + 4, " stroke='none' fill='#222'", esc(shorten(s.name, legendChars)));
      o += "</g>\n";
    }
    o += "</g>\n";
  }
}

}  // namespace

std::string svgPlot(const Axes& axes, const std::vector<Series>& series) {
  std::string o = open(plotWidth(axes), plotHeight(axes), axes.generator);
  drawPlot(o, axes, series);
  o += "</svg>\n";
  return o;
}

std::string svgRow(const std::vector<Plot>& plots) {
  int W = 0, H = 0;
  for (const auto& p : plots) W += plotWidth(p.axes), H = std::max(H, plotHeight(p.axes));
  std::string o = open(clampSize(W, 240), clampSize(H, 180),
                       plots.empty() ? Axes().generator : plots.front().axes.generator);
  int x = 0;
  for (const auto& p : plots) {
    put(o, "<g transform='translate(", num(x), " 0)'>\n");
    drawPlot(o, p.axes, p.series);
    o += "</g>\n";
    x += plotWidth(p.axes);
  }
  o += "</svg>\n";
  return o;
}

std::string svgHeatmap(const Heatmap& h) {
  const int W = clampSize(h.width, 240), H = clampSize(h.height, 180);
  const size_t nx = h.xs.size(), ny = h.ys.size();
  Frame f;
  f.x = 72, f.y = h.title.empty() ? 20 : 40;
  f.w = W - f.x - 116, f.h = H - f.y - 48;
  const auto value = [&](size_t ix, size_t iy) {
    const size_t i = iy * nx + ix;
    return i < h.values.size() ? h.values[i] : NAN;
  };

  // Colour range over the exact data range (no padding: the map's ends are the extremes).
  Scale cs;
  cs.log = h.log_scale && !h.diverging;
  double lo = kInf, hi = -kInf;
  bool missing = false;
  for (size_t iy = 0; iy < ny; ++iy)
    for (size_t ix = 0; ix < nx; ++ix) {
      const double v = value(ix, iy);
      missing |= !std::isfinite(v);
      if (!cs.valid(v)) continue;
      const double a = h.diverging ? std::abs(v) : cs.fwd(v);
      lo = std::min(lo, a), hi = std::max(hi, a);
    }
  if (h.diverging) {
    const double m = hi > 0 ? hi : 1.0;
    cs.lo = -m, cs.hi = m;
  } else if (lo > hi) {
    cs.lo = 0, cs.hi = 1;
  } else if (tooNarrow(lo, hi)) {
    std::tie(cs.lo, cs.hi) = around(0.5 * (lo + hi), cs.log);
  } else {
    cs.lo = lo, cs.hi = hi;
  }
  const Rgb(&stops)[5] = h.diverging ? kDiverging : kViridis;
  const auto color = [&](double v) -> std::string {
    if (!std::isfinite(v)) return kMissing;
    if (cs.log && v <= 0) return ramp(stops, 0);
    return ramp(stops, cs.unit(cs.fwd(v)));
  };

  std::string o = open(W, H, h.generator);
  titles(o, W, f.x, f.y, f.w, f.h, H, h.title, h.xlabel, h.ylabel);
  if (nx == 0 || ny == 0) {
    noData(o, f.x + f.w / 2, f.y + f.h / 2);
  } else {
    // Cells in grid units under one transform, a group per row: short integer coordinates keep
    // a 64x64 map near 230 KB. The slight overlap hides anti-aliasing seams between neighbours.
    const double cw = f.w / nx, ch = f.h / ny;
    put(o, "<g class='cells' transform='translate(", px(f.x), " ", px(f.y), ") scale(",
        general(cw, 6), " ", general(ch, 6), ")'>\n");
    const std::string ow = general(1 + 0.4 / cw, 3), oh = general(1 + 0.4 / ch, 3);
    for (size_t iy = ny; iy-- > 0;) {  // top row first
      put(o, "<g transform='translate(0 ", std::to_string(ny - 1 - iy), ")'>\n");
      for (size_t ix = 0; ix < nx; ++ix)
        put(o, "<rect x='", std::to_string(ix), "' width='", ow, "' height='", oh, "' fill='",
            color(value(ix, iy)), "'/>\n");
      o += "</g>\n";
    }
    o += "</g>\n";

    // Tick labels are the grid coordinates of a few evenly spread cells.
    const auto spread = [](size_t n, double pixels, double spacing) {
      const size_t k = std::min(n, std::max<size_t>(2, static_cast<size_t>(pixels / spacing)));
      std::vector<size_t> idx;
      for (size_t j = 0; j < k && n > 0; ++j) {
        const size_t i = n == 1 ? 0 : (j * (n - 1) + (k - 1) / 2) / (k - 1);
        if (idx.empty() || idx.back() != i) idx.push_back(i);
      }
      return idx;
    };
    std::string marks;
    put(o, "<g class='ticks' font-size='10' fill='#333'>\n");
    for (size_t i : spread(nx, f.w, 70)) {
      const double x = f.x + (i + 0.5) * cw;
      put(marks, "M", px(x), " ", px(f.y + f.h), "v5");
      text(o, x, f.y + f.h + 17, " text-anchor='middle'", esc(general(h.xs[i], 4)));
    }
    for (size_t i : spread(ny, f.h, 40)) {
      const double y = f.y + f.h - (i + 0.5) * ch;
      put(marks, "M", px(f.x), " ", px(y), "h-5");
      text(o, f.x - 7, y + 3.5, " text-anchor='end'", esc(general(h.ys[i], 4)));
    }
    put(o, "<path fill='none' stroke='#888' d='", marks, "'/>\n</g>\n");
  }
  put(o, "<rect x='", px(f.x), "' y='", px(f.y), "' width='", px(f.w), "' height='", px(f.h),
      "' fill='none' stroke='#888'/>\n");

  // Colour bar: 64 bands (a gradient would need an id, which clashes when reports inline plots).
  const double bx = f.x + f.w + 16, bw = 16;
  put(o, "<g class='colorbar' font-size='10' fill='#333'>\n");
  for (int c = 0; c < 64; ++c)
    put(o, "<rect x='", px(bx), "' y='", px(f.y + f.h - (c + 1) * f.h / 64), "' width='", px(bw),
        "' height='", px(f.h / 64 + 0.3), "' fill='", ramp(stops, c / 63.0), "'/>\n");
  put(o, "<rect x='", px(bx), "' y='", px(f.y), "' width='", px(bw), "' height='", px(f.h),
      "' fill='none' stroke='#888'/>\n");
  const Ticks t = axisTicks(cs, f.h, 40);
  std::string marks;
  for (const auto& [a, label] : t.major) {
    const double y = f.y + f.h * (1 - cs.unit(a));
    put(marks, "M", px(bx + bw), " ", px(y), "h4");
    text(o, bx + bw + 7, y + 3.5, "", label);
  }
  for (double a : t.minor)
    put(marks, "M", px(bx + bw), " ", px(f.y + f.h * (1 - cs.unit(a))), "h2");
  if (!marks.empty()) put(o, "<path fill='none' stroke='#888' d='", marks, "'/>\n");
  if (missing) {
    put(o, "<rect x='", px(bx), "' y='", px(f.y + f.h + 8), "' width='10' height='10' fill='",
        kMissing, "'/>\n");
    text(o, bx + 14, f.y + f.h + 17, "", "not finite");
  }
  if (!h.value_label.empty()) {
    const double x = W - 8, y = f.y + f.h / 2;
    put(o, "<text x='", px(x), "' y='", px(y), "' transform='rotate(-90 ", px(x), " ", px(y),
        ")' text-anchor='middle' font-size='12'>", esc(h.value_label), "</text>\n");
  }
  o += "</g>\n</svg>\n";
  return o;
}

std::string formatNumber(double v, int significant) {
  return general(v, std::clamp(significant, 1, 17));
}

bool writeTextFile(const std::string& path, const std::string& text, std::string* error) {
  namespace fs = std::filesystem;
  const auto fail = [&](const std::string& message) {
    if (error) *error = message;
    return false;
  };
  if (path.empty()) return fail("empty output path");
  const fs::path p(path);
  if (p.has_parent_path()) {
    std::error_code ec;
    fs::create_directories(p.parent_path(), ec);
    if (ec)
      return fail("cannot create directory '" + p.parent_path().string() + "': " + ec.message());
  }
  std::ofstream out(p, std::ios::binary | std::ios::trunc);
  if (!out) return fail("cannot open '" + path + "' for writing");
  out.write(text.data(), static_cast<std::streamsize>(text.size()));
  out.close();
  if (!out) return fail("error writing '" + path + "'");
  return true;
}

}  // namespace lgp::plot
