#pragma once
// Simple x-y figures as self-contained SVG: lines, filled or open markers, shaded bands, an optional y = x
// line for predicted-against-measured plots, labelled axes with "nice" ticks (linear or logarithmic) and a
// legend. The BLE curves, the validation report and the calibration report all draw with it.

#include <optional>
#include <string>
#include <vector>

namespace blt::svg {

enum class Style { line, points, openPoints };

struct Series {
  std::string label;  // legend entry; empty: none
  std::vector<double> x, y;
  Style style = Style::points;
  std::string colour;    // empty: the palette's colour for the series' index
  std::string cssClass;  // class attribute of its elements; empty: "curve" for lines, "point" for markers
  // Per point, optional (empty, or one per point): a tooltip, and whether the marker is open (white inside)
  // whatever the style says, so one series can mix outcomes (perforated filled, stopped open).
  std::vector<std::string> tooltips;
  std::vector<bool> open;
  bool dashed = false;  // lines only
};

// A shaded region between low(x) and high(x), drawn beneath the series; one without points is a legend entry
// only (several bands explained once).
struct Band {
  std::string label;  // legend entry; empty: none
  std::vector<double> x, low, high;
  std::string colour;  // empty: the palette's colour for the band's index
  std::string cssClass = "band";
};

// A legend entry that explains a marker convention rather than a series (e.g. "stopped": an open marker).
struct LegendMarker {
  std::string label;
  std::string fill = "#333", stroke = "#333";
};

struct PlotOptions {
  std::string title, subtitle, xLabel, yLabel;
  bool logX = false, logY = false;
  bool identityLine = false;  // a dashed y = x (same units on both axes)
  // The ranges the axes cover, rounded out to ticks; unset: the data's range, padded by 5 % on a linear y.
  // Anything outside is clipped. Linear axes never reach below zero when all the data are non-negative.
  std::optional<double> xMin, xMax, yMin, yMax;
  std::vector<LegendMarker> markerLegend;  // after the series' and bands' entries
  double width = 860, height = 560;
};

struct Plot {
  std::vector<Band> bands;
  std::vector<Series> series;
  PlotOptions options;
};

// The figure as SVG text. Non-finite points are skipped (and points outside a log axis's positive range).
std::string renderSvg(const Plot& plot);
// Writes renderSvg(plot) to `path`; throws InputError naming the path when it cannot be written.
void writeSvg(const std::string& path, const Plot& plot);
// Shorthand for a figure without bands.
void writePlot(const std::string& path, const std::vector<Series>& series, const PlotOptions& options);

// Colour k of the palette (Okabe-Ito order: distinguishable in most colour-vision deficiencies), cycling.
const char* paletteColour(std::size_t k);
std::string xmlEscape(const std::string& text);

}  // namespace blt::svg
