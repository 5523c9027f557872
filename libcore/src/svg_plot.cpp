// Self-drawn SVG figures (no plotting library: the figures are simple and a dependency for them would cost more
// than this file).
#include "blt/core/svg_plot.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <sstream>

#include "blt/core/error.hpp"

namespace blt::svg {

namespace {

std::string number(double value, const char* format) {
  char buf[48];
  std::snprintf(buf, sizeof buf, format, value);
  return buf;
}

std::string coord(double v) { return number(v, "%.2f"); }

constexpr std::array<const char*, 8> kPalette{"#0072B2", "#D55E00", "#009E73", "#CC79A7",
                                              "#E69F00", "#56B4E9", "#000000", "#F0E442"};

// An axis and its ticks. Linear: 1, 2 or 5 times a power of ten. Logarithmic: the decades, with 2 and 5
// between them when there are few decades.
struct Axis {
  bool log = false;
  double lo = 0, hi = 1;
  std::vector<double> ticks;
  int decimals = 1;  // linear tick labels
  double map(double v, double from, double to) const {
    const double f = log ? (std::log10(v) - std::log10(lo)) / (std::log10(hi) - std::log10(lo)) : (v - lo) / (hi - lo);
    return from + f * (to - from);
  }
};

Axis linearAxis(double lo, double hi, int targetTicks, bool clampAtZero) {
  if (!(hi > lo)) {
    const double pad = lo != 0.0 ? std::abs(lo) * 0.1 : 1.0;
    lo -= pad;
    hi += pad;
  }
  const double raw = (hi - lo) / targetTicks;
  const double magnitude = std::pow(10.0, std::floor(std::log10(raw)));
  const double normalized = raw / magnitude;
  const double factor = normalized < 1.5 ? 1.0 : normalized < 3.0 ? 2.0 : normalized < 7.0 ? 5.0 : 10.0;
  const double step = factor * magnitude;
  Axis a;
  // Small tolerance so that a bound sitting on a tick (1 km/s, 10 km/s) does not get an extra empty step.
  a.lo = std::floor(lo / step + 1e-9) * step;
  a.hi = std::ceil(hi / step - 1e-9) * step;
  if (clampAtZero && a.lo < 0.0) a.lo = 0.0;
  for (double t = std::ceil(a.lo / step - 1e-9) * step; t <= a.hi + 1e-9 * step; t += step)
    a.ticks.push_back(std::abs(t) < 1e-12 * step ? 0.0 : t);
  a.decimals = std::max(0, static_cast<int>(std::ceil(-std::log10(step) - 1e-9)));
  return a;
}

Axis logAxis(double lo, double hi) {
  if (!(lo > 0)) lo = hi > 0 ? hi / 10 : 1.0;
  if (!(hi > lo)) hi = lo * 10;
  Axis a;
  a.log = true;
  a.lo = std::pow(10.0, std::floor(std::log10(lo) + 1e-9));
  a.hi = std::pow(10.0, std::ceil(std::log10(hi) - 1e-9));
  const double decades = std::log10(a.hi / a.lo);
  const std::vector<double> mantissas = decades <= 2.5 ? std::vector<double>{1, 2, 5} : std::vector<double>{1};
  for (int e = static_cast<int>(std::floor(std::log10(a.lo))) - 1; e <= std::ceil(std::log10(a.hi)); ++e)
    for (double m : mantissas) {
      const double t = m * std::pow(10.0, e);
      if (t >= a.lo * (1 - 1e-9) && t <= a.hi * (1 + 1e-9)) a.ticks.push_back(t);
    }
  return a;
}

std::string tickLabel(const Axis& a, double value) {
  if (a.log) return number(value, "%g");
  char fmt[16];
  std::snprintf(fmt, sizeof fmt, "%%.%df", a.decimals);
  return number(value, fmt);
}

bool usable(double v, bool log) { return std::isfinite(v) && (!log || v > 0); }

struct Range {
  double lo = std::numeric_limits<double>::infinity(), hi = -std::numeric_limits<double>::infinity();
  void add(double v) {
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  }
  bool empty() const { return !(hi >= lo); }
};

}  // namespace

const char* paletteColour(std::size_t k) { return kPalette[k % kPalette.size()]; }

std::string xmlEscape(const std::string& text) {
  std::string out;
  out.reserve(text.size());
  for (char ch : text) {
    switch (ch) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      case '\'': out += "&apos;"; break;
      default:
        // Control characters other than tab/newline are not allowed in XML 1.0.
        if (static_cast<unsigned char>(ch) < 0x20 && ch != '\t' && ch != '\n') break;
        out += ch;
    }
  }
  return out;
}

std::string renderSvg(const Plot& plot) {
  const PlotOptions& o = plot.options;

  // ---- axis ranges from the data unless fixed ----
  Range xr, yr;
  for (const Series& s : plot.series)
    for (std::size_t i = 0; i < std::min(s.x.size(), s.y.size()); ++i)
      if (usable(s.x[i], o.logX) && usable(s.y[i], o.logY)) {
        xr.add(s.x[i]);
        yr.add(s.y[i]);
      }
  for (const Band& b : plot.bands)
    for (std::size_t i = 0; i < b.x.size(); ++i) {
      if (!usable(b.x[i], o.logX)) continue;
      xr.add(b.x[i]);
      if (usable(b.low[i], o.logY)) yr.add(b.low[i]);
      if (usable(b.high[i], o.logY)) yr.add(b.high[i]);
    }
  if (xr.empty()) xr = {o.logX ? 1.0 : 0.0, o.logX ? 10.0 : 1.0};
  if (yr.empty()) yr = {o.logY ? 1.0 : 0.0, o.logY ? 10.0 : 1.0};
  if (o.identityLine) {  // both axes cover both ranges, so y = x runs corner to corner
    const double lo = std::min(xr.lo, yr.lo), hi = std::max(xr.hi, yr.hi);
    xr = yr = {lo, hi};
  }
  const bool nonNegative = xr.lo >= 0 && yr.lo >= 0;
  double xLo = o.xMin.value_or(xr.lo), xHi = o.xMax.value_or(xr.hi);
  double yLo = o.yMin.value_or(yr.lo), yHi = o.yMax.value_or(yr.hi);
  if (!o.logY && !o.yMin && !o.yMax) {
    const double pad = 0.05 * (yHi - yLo);
    yLo -= pad;
    yHi += pad;
  }
  const Axis xAxis = o.logX ? logAxis(xLo, xHi) : linearAxis(xLo, xHi, 9, nonNegative);
  const Axis yAxis = o.logY ? logAxis(yLo, yHi) : linearAxis(yLo, yHi, 6, nonNegative);

  // ---- layout (px) ----
  const double width = o.width, height = o.height;
  const double left = 80, right = width - 210, top = 70, bottom = height - 80;  // the plot frame
  auto px = [&](double x) { return xAxis.map(x, left, right); };
  auto py = [&](double y) { return yAxis.map(y, bottom, top); };
  auto colourOf = [](const std::string& given, std::size_t k) { return given.empty() ? std::string(paletteColour(k)) : given; };

  std::ostringstream svg;
  svg << "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
      << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << width << "\" height=\"" << height
      << "\" viewBox=\"0 0 " << width << ' ' << height << "\" font-family=\"DejaVu Sans, Arial, Helvetica, sans-serif\">\n"
      << "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n"
      << "<defs><clipPath id=\"plot-area\"><rect x=\"" << left << "\" y=\"" << top << "\" width=\"" << right - left
      << "\" height=\"" << bottom - top << "\"/></clipPath></defs>\n";
  svg << "<text class=\"title\" x=\"" << coord((left + right) / 2) << "\" y=\"30\" text-anchor=\"middle\" "
      << "font-size=\"17\" font-weight=\"bold\">" << xmlEscape(o.title) << "</text>\n";
  if (!o.subtitle.empty())
    svg << "<text class=\"subtitle\" x=\"" << coord((left + right) / 2) << "\" y=\"52\" text-anchor=\"middle\" "
        << "font-size=\"12\" fill=\"#444\">" << xmlEscape(o.subtitle) << "</text>\n";

  svg << "<g class=\"grid\" stroke=\"#e6e6e6\" stroke-width=\"1\">\n";
  for (double t : xAxis.ticks)
    svg << "<line x1=\"" << coord(px(t)) << "\" y1=\"" << top << "\" x2=\"" << coord(px(t)) << "\" y2=\"" << bottom << "\"/>\n";
  for (double t : yAxis.ticks)
    svg << "<line x1=\"" << left << "\" y1=\"" << coord(py(t)) << "\" x2=\"" << right << "\" y2=\"" << coord(py(t)) << "\"/>\n";
  svg << "</g>\n";

  // Bands beneath everything, then y = x, lines, markers.
  svg << "<g clip-path=\"url(#plot-area)\">\n";
  for (std::size_t k = 0; k < plot.bands.size(); ++k) {
    const Band& b = plot.bands[k];
    std::vector<std::size_t> keep;
    for (std::size_t i = 0; i < b.x.size(); ++i)
      if (usable(b.x[i], o.logX) && usable(b.low[i], o.logY) && usable(b.high[i], o.logY)) keep.push_back(i);
    if (keep.empty()) continue;  // a legend-only entry
    svg << "<polygon class=\"" << b.cssClass << "\" fill=\"" << colourOf(b.colour, k)
        << "\" fill-opacity=\"0.15\" stroke=\"none\" points=\"";
    for (std::size_t i : keep) svg << coord(px(b.x[i])) << ',' << coord(py(b.high[i])) << ' ';
    for (std::size_t j = keep.size(); j-- > 0;)
      svg << coord(px(b.x[keep[j]])) << ',' << coord(py(b.low[keep[j]])) << (j ? " " : "");
    svg << "\"/>\n";
  }
  if (o.identityLine) {
    const double lo = std::max(xAxis.lo, yAxis.lo), hi = std::min(xAxis.hi, yAxis.hi);
    svg << "<line class=\"identity\" x1=\"" << coord(px(lo)) << "\" y1=\"" << coord(py(lo)) << "\" x2=\""
        << coord(px(hi)) << "\" y2=\"" << coord(py(hi)) << "\" stroke=\"#888\" stroke-width=\"1\" "
        << "stroke-dasharray=\"5,4\"/>\n";
  }
  for (std::size_t k = 0; k < plot.series.size(); ++k) {
    const Series& s = plot.series[k];
    const std::string colour = colourOf(s.colour, k);
    const std::size_t n = std::min(s.x.size(), s.y.size());
    if (s.style == Style::line) {
      svg << "<path class=\"" << (s.cssClass.empty() ? "curve" : s.cssClass) << "\" fill=\"none\" stroke=\""
          << colour << "\" stroke-width=\"2\" stroke-linejoin=\"round\"" << (s.dashed ? " stroke-dasharray=\"6,4\"" : "")
          << " d=\"";
      bool pen = false;  // a gap (non-finite point) lifts the pen
      for (std::size_t i = 0; i < n; ++i) {
        if (!usable(s.x[i], o.logX) || !usable(s.y[i], o.logY)) {
          pen = false;
          continue;
        }
        svg << (pen ? " L" : (i ? " M" : "M")) << coord(px(s.x[i])) << ',' << coord(py(s.y[i]));
        pen = true;
      }
      svg << "\"/>\n";
      continue;
    }
    for (std::size_t i = 0; i < n; ++i) {
      if (!usable(s.x[i], o.logX) || !usable(s.y[i], o.logY)) continue;
      const bool open = i < s.open.size() ? s.open[i] : s.style == Style::openPoints;
      svg << "<circle class=\"" << (s.cssClass.empty() ? "point" : s.cssClass) << "\" cx=\"" << coord(px(s.x[i]))
          << "\" cy=\"" << coord(py(s.y[i])) << "\" r=\"4\" fill=\"" << (open ? std::string("white") : colour)
          << "\" stroke=\"" << colour << "\" stroke-width=\"1.5\">";
      if (i < s.tooltips.size()) svg << "<title>" << xmlEscape(s.tooltips[i]) << "</title>";
      svg << "</circle>\n";
    }
  }
  svg << "</g>\n";

  // Frame, tick marks and labels.
  svg << "<rect x=\"" << left << "\" y=\"" << top << "\" width=\"" << right - left << "\" height=\"" << bottom - top
      << "\" fill=\"none\" stroke=\"#333\" stroke-width=\"1\"/>\n";
  svg << "<g class=\"ticks\" stroke=\"#333\" stroke-width=\"1\">\n";
  for (double t : xAxis.ticks)
    svg << "<line x1=\"" << coord(px(t)) << "\" y1=\"" << bottom << "\" x2=\"" << coord(px(t)) << "\" y2=\"" << bottom + 5
        << "\"/>\n";
  for (double t : yAxis.ticks)
    svg << "<line x1=\"" << left - 5 << "\" y1=\"" << coord(py(t)) << "\" x2=\"" << left << "\" y2=\"" << coord(py(t))
        << "\"/>\n";
  svg << "</g>\n<g class=\"tick-labels\" font-size=\"12\" fill=\"#222\">\n";
  for (double t : xAxis.ticks)
    svg << "<text x=\"" << coord(px(t)) << "\" y=\"" << bottom + 20 << "\" text-anchor=\"middle\">"
        << tickLabel(xAxis, t) << "</text>\n";
  for (double t : yAxis.ticks)
    svg << "<text x=\"" << left - 9 << "\" y=\"" << coord(py(t) + 4) << "\" text-anchor=\"end\">" << tickLabel(yAxis, t)
        << "</text>\n";
  svg << "</g>\n";
  svg << "<text class=\"axis-label\" x=\"" << coord((left + right) / 2) << "\" y=\"" << bottom + 45
      << "\" text-anchor=\"middle\" font-size=\"14\">" << xmlEscape(o.xLabel) << "</text>\n"
      << "<text class=\"axis-label\" x=\"0\" y=\"0\" transform=\"translate(" << left - 52 << ' '
      << coord((top + bottom) / 2) << ") rotate(-90)\" text-anchor=\"middle\" font-size=\"14\">" << xmlEscape(o.yLabel)
      << "</text>\n";

  // Legend, right of the frame.
  const double lx = right + 22;
  double ly = top + 8;
  svg << "<g class=\"legend\" font-size=\"12\" fill=\"#222\">\n";
  auto label = [&](const std::string& text) {
    svg << "<text x=\"" << lx + 34 << "\" y=\"" << ly + 4 << "\">" << xmlEscape(text) << "</text>\n";
    ly += 22;
  };
  auto marker = [&](const std::string& fill, const std::string& stroke) {
    svg << "<circle class=\"legend-marker\" cx=\"" << lx + 13 << "\" cy=\"" << ly << "\" r=\"4\" fill=\"" << fill
        << "\" stroke=\"" << stroke << "\" stroke-width=\"1.5\"/>\n";
  };
  for (std::size_t k = 0; k < plot.series.size(); ++k) {
    const Series& s = plot.series[k];
    if (s.label.empty()) continue;
    const std::string colour = colourOf(s.colour, k);
    if (s.style == Style::line)
      svg << "<line x1=\"" << lx << "\" y1=\"" << ly << "\" x2=\"" << lx + 26 << "\" y2=\"" << ly << "\" stroke=\""
          << colour << "\" stroke-width=\"2\"" << (s.dashed ? " stroke-dasharray=\"6,4\"" : "") << "/>\n";
    else
      marker(s.style == Style::openPoints ? "white" : colour, colour);
    label(s.label);
  }
  for (std::size_t k = 0; k < plot.bands.size(); ++k) {
    if (plot.bands[k].label.empty()) continue;
    svg << "<rect x=\"" << lx << "\" y=\"" << ly - 7 << "\" width=\"26\" height=\"14\" fill=\""
        << colourOf(plot.bands[k].colour, k) << "\" fill-opacity=\"0.2\"/>\n";
    label(plot.bands[k].label);
  }
  if (!o.markerLegend.empty()) ly += 6;
  for (const LegendMarker& m : o.markerLegend) {
    marker(m.fill, m.stroke);
    label(m.label);
  }
  svg << "</g>\n</svg>\n";
  return svg.str();
}

void writeSvg(const std::string& path, const Plot& plot) {
  const std::string text = renderSvg(plot);  // before opening: a failure leaves no half-written file
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out)
    throw InputError(InputLocation::file(path), "cannot open the file for writing",
                     "a writable path in an existing folder");
  out << text;
  out.flush();
  if (!out) throw InputError(InputLocation::file(path), "writing the file failed", "a writable path with free space");
}

void writePlot(const std::string& path, const std::vector<Series>& series, const PlotOptions& options) {
  writeSvg(path, Plot{{}, series, options});
}

}  // namespace blt::svg
