// Ballistic limit curves as CSV and as a self-drawn SVG figure (no plotting library: the figure is simple and a
// dependency for it would cost more than these few hundred lines).
#include "blt/ble/curve.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <numbers>
#include <sstream>

#include "blt/core/error.hpp"
#include "blt/core/units.hpp"

namespace blt::ble {

namespace {

// Options come from the CLI's flags; errors name those flags so the user knows what to change.
void checkOptions(const CurveOptions& o) {
  if (o.angles.empty()) throw InputError(InputLocation::flag("--angles"), "no angle given", "e.g. --angles 0,45,60");
  for (double a : o.angles) {
    if (!(a >= 0.0 && a < std::numbers::pi / 2))
      throw InputError(InputLocation::flag("--angles"),
                       "angle " + units::format(a, "deg") + " is outside the range", "0 <= angle < 90 deg");
  }
  if (!(o.projectileDensity > 0.0) || !std::isfinite(o.projectileDensity))
    throw InputError(InputLocation::flag("--density"), "the projectile density must be positive",
                     "a density > 0, e.g. 2770 kg/m3");
  if (!(o.velocityMin > 0.0) || !std::isfinite(o.velocityMin))
    throw InputError(InputLocation::flag("--vmin"),
                     "the lowest velocity must be positive, got " + units::format(o.velocityMin, "km/s"),
                     "a velocity > 0, e.g. 1 km/s");
  if (!(o.velocityMax > o.velocityMin) || !std::isfinite(o.velocityMax))
    throw InputError(InputLocation::flag("--vmax"),
                     "the highest velocity (" + units::format(o.velocityMax, "km/s") +
                         ") must exceed the lowest (" + units::format(o.velocityMin, "km/s") + ")",
                     "--vmax > --vmin");
  if (o.samples < 2) throw InputError(InputLocation::flag("--samples"), "at least 2 samples per curve are needed", ">= 2");
  if (!(o.bandLevel > 0.0 && o.bandLevel < 1.0))
    throw InputError(InputLocation::flag("--level"), "the band level must lie strictly between 0 and 1",
                     "0 < level < 1, e.g. 0.9");
}

double sampleVelocity(const CurveOptions& o, int i) {
  return o.velocityMin + (o.velocityMax - o.velocityMin) * i / (o.samples - 1);
}

std::string number(double value, const char* format = "%.10g") {
  char buf[48];
  std::snprintf(buf, sizeof buf, format, value);
  return buf;
}

// Opens for writing; the error names the path, the usual causes being a missing folder or no permission.
std::ofstream openForWriting(const std::string& path) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out)
    throw InputError(InputLocation::file(path), "cannot open the file for writing",
                     "a writable path in an existing folder");
  return out;
}

void finish(std::ofstream& out, const std::string& path) {
  out.flush();
  if (!out) throw InputError(InputLocation::file(path), "writing the file failed", "a writable path with free space");
}

// ---- SVG helpers -----------------------------------------------------------------------------------------

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

std::string coord(double v) { return number(v, "%.2f"); }

// An axis with "nice" ticks (1, 2 or 5 times a power of ten) covering [lo, hi].
struct Axis {
  double lo = 0, hi = 1, step = 0.1;
  int decimals = 1;
};

Axis niceAxis(double lo, double hi, int targetTicks, bool clampAtZero) {
  if (!(hi > lo)) {
    const double pad = lo != 0.0 ? std::abs(lo) * 0.1 : 1.0;
    lo -= pad;
    hi += pad;
  }
  const double raw = (hi - lo) / targetTicks;
  const double magnitude = std::pow(10.0, std::floor(std::log10(raw)));
  const double normalized = raw / magnitude;
  const double factor = normalized < 1.5 ? 1.0 : normalized < 3.0 ? 2.0 : normalized < 7.0 ? 5.0 : 10.0;
  Axis a;
  a.step = factor * magnitude;
  // Small tolerance so that a bound sitting on a tick (1 km/s, 10 km/s) does not get an extra empty step.
  a.lo = std::floor(lo / a.step + 1e-9) * a.step;
  a.hi = std::ceil(hi / a.step - 1e-9) * a.step;
  if (clampAtZero && a.lo < 0.0) a.lo = 0.0;
  a.decimals = std::max(0, static_cast<int>(std::ceil(-std::log10(a.step) - 1e-9)));
  return a;
}

std::string tickLabel(double value, int decimals) {
  if (std::abs(value) < 1e-12) value = 0.0;  // no "-0.0"
  char fmt[16];
  std::snprintf(fmt, sizeof fmt, "%%.%df", decimals);
  return number(value, fmt);
}

// Well separated on white, distinguishable in most colour-vision deficiencies (Okabe-Ito order).
constexpr std::array<const char*, 8> kPalette{"#0072B2", "#D55E00", "#009E73", "#CC79A7",
                                              "#E69F00", "#56B4E9", "#000000", "#F0E442"};
constexpr const char* kOtherAngleColour = "#8c8c8c";

std::string angleLabel(double angleRad) {
  return "\xCE\xB8 = " + number(units::toUnit(angleRad, "deg"), "%.4g") + "\xC2\xB0";  // θ = 45°
}

struct CurveSamples {
  std::vector<double> velocityKmS, dcMm, lowMm, highMm;
};

CurveSamples sampleCurve(const FitResult& fit, double angle, const CurveOptions& o) {
  CurveSamples s;
  for (int i = 0; i < o.samples; ++i) {
    const double v = sampleVelocity(o, i);
    const DiameterBand b = criticalDiameterBand(fit, v, angle, o.projectileDensity, o.bandLevel);
    s.velocityKmS.push_back(units::toUnit(v, "km/s"));
    s.dcMm.push_back(units::toUnit(b.criticalDiameter, "mm"));
    s.lowMm.push_back(units::toUnit(b.low, "mm"));
    s.highMm.push_back(units::toUnit(b.high, "mm"));
  }
  return s;
}

// Index of the curve whose angle is within 1 deg of the point's, or -1.
int curveIndexFor(const ImpactPoint& p, const std::vector<double>& angles) {
  const double tolerance = units::fromUnit(1.0, "deg");
  int best = -1;
  double bestDistance = tolerance;
  for (size_t i = 0; i < angles.size(); ++i) {
    const double d = std::abs(p.angle - angles[i]);
    if (d <= bestDistance) {
      best = static_cast<int>(i);
      bestDistance = d;
    }
  }
  return best;
}

}  // namespace

void writeCurveCsv(const std::string& path, const FitResult& fit, const CurveOptions& options) {
  checkOptions(options);
  // Compute everything before touching the file so that a failure does not leave a half-written one.
  std::ostringstream text;
  text << "# blt ble curve: critical diameter of the fitted Christiansen BLE (" << toString(fit.method)
       << "), projectile density " << number(options.projectileDensity, "%.6g") << " kg/m3; band: "
       << (fit.covarianceAvailable ? number(options.bandLevel * 100, "%.4g") + " % two-sided (delta method)"
                                   : std::string("none, the fit has no covariance (low = high = d_c)"))
       << "\n";
  text << "angle_deg,velocity_km_s,critical_diameter_mm,band_low_mm,band_high_mm\n";
  for (double angle : options.angles) {
    const CurveSamples s = sampleCurve(fit, angle, options);
    const std::string angleDeg = number(units::toUnit(angle, "deg"));
    for (size_t i = 0; i < s.velocityKmS.size(); ++i) {
      text << angleDeg << ',' << number(s.velocityKmS[i]) << ',' << number(s.dcMm[i]) << ',' << number(s.lowMm[i])
           << ',' << number(s.highMm[i]) << '\n';
    }
  }
  std::ofstream out = openForWriting(path);
  out << text.str();
  finish(out, path);
}

void writeCurveSvg(const std::string& path, const FitResult& fit, const std::vector<ImpactPoint>& points,
                   const CurveOptions& options) {
  checkOptions(options);

  std::vector<CurveSamples> curves;
  for (double angle : options.angles) curves.push_back(sampleCurve(fit, angle, options));

  // ---- axis ranges: the curves, the points, and the band within reason ----
  double xLo = units::toUnit(options.velocityMin, "km/s"), xHi = units::toUnit(options.velocityMax, "km/s");
  double yLo = std::numeric_limits<double>::infinity(), yHi = -yLo;
  for (const auto& c : curves) {
    for (double d : c.dcMm) {
      yLo = std::min(yLo, d);
      yHi = std::max(yHi, d);
    }
  }
  // A wide band (poorly determined coefficients) is drawn but clipped: letting it set the range would flatten
  // the curves themselves.
  const double curveLo = yLo, curveHi = yHi;
  for (const auto& c : curves) {
    for (size_t i = 0; i < c.dcMm.size(); ++i) {
      yLo = std::min(yLo, std::max(c.lowMm[i], 0.5 * curveLo));
      yHi = std::max(yHi, std::min(c.highMm[i], 2.0 * curveHi));
    }
  }
  for (const auto& p : points) {
    const double v = units::toUnit(p.velocity, "km/s"), d = units::toUnit(p.diameter, "mm");
    if (!std::isfinite(v) || !std::isfinite(d)) continue;
    xLo = std::min(xLo, v);
    xHi = std::max(xHi, v);
    yLo = std::min(yLo, d);
    yHi = std::max(yHi, d);
  }
  const double yPad = 0.05 * (yHi - yLo);
  const Axis xAxis = niceAxis(xLo, xHi, 9, true);
  const Axis yAxis = niceAxis(yLo - yPad, yHi + yPad, 6, true);

  // ---- layout (px) ----
  const double width = 860, height = 560;
  const double left = 80, right = 650, top = 70, bottom = 480;  // the plot frame
  auto px = [&](double vKmS) { return left + (vKmS - xAxis.lo) / (xAxis.hi - xAxis.lo) * (right - left); };
  auto py = [&](double dMm) { return bottom - (dMm - yAxis.lo) / (yAxis.hi - yAxis.lo) * (bottom - top); };

  std::ostringstream svg;
  svg << "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
      << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << width << "\" height=\"" << height
      << "\" viewBox=\"0 0 " << width << ' ' << height << "\" font-family=\"DejaVu Sans, Arial, Helvetica, sans-serif\">\n"
      << "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n"
      << "<defs><clipPath id=\"plot-area\"><rect x=\"" << left << "\" y=\"" << top << "\" width=\"" << right - left
      << "\" height=\"" << bottom - top << "\"/></clipPath></defs>\n";

  // Title and a subtitle saying what the curves are drawn for.
  const std::string title = options.title.empty() ? "Ballistic limit: critical diameter against impact velocity"
                                                  : options.title;
  std::string subtitle = "Christiansen BLE, " + toString(fit.method) + " fit to " + std::to_string(fit.pointCount) +
                         " points; projectile density " + number(options.projectileDensity, "%.6g") +
                         " kg/m\xC2\xB3";
  subtitle += fit.covarianceAvailable ? "; band: " + number(options.bandLevel * 100, "%.4g") + " % interval"
                                      : "; no band (no covariance)";
  svg << "<text class=\"title\" x=\"" << coord((left + right) / 2) << "\" y=\"30\" text-anchor=\"middle\" "
      << "font-size=\"17\" font-weight=\"bold\">" << xmlEscape(title) << "</text>\n"
      << "<text class=\"subtitle\" x=\"" << coord((left + right) / 2) << "\" y=\"52\" text-anchor=\"middle\" "
      << "font-size=\"12\" fill=\"#444\">" << xmlEscape(subtitle) << "</text>\n";

  // Grid and ticks.
  svg << "<g class=\"grid\" stroke=\"#e6e6e6\" stroke-width=\"1\">\n";
  const int nx = static_cast<int>(std::lround((xAxis.hi - xAxis.lo) / xAxis.step));
  const int ny = static_cast<int>(std::lround((yAxis.hi - yAxis.lo) / yAxis.step));
  for (int i = 0; i <= nx; ++i) {
    const double x = px(xAxis.lo + i * xAxis.step);
    svg << "<line x1=\"" << coord(x) << "\" y1=\"" << top << "\" x2=\"" << coord(x) << "\" y2=\"" << bottom << "\"/>\n";
  }
  for (int i = 0; i <= ny; ++i) {
    const double y = py(yAxis.lo + i * yAxis.step);
    svg << "<line x1=\"" << left << "\" y1=\"" << coord(y) << "\" x2=\"" << right << "\" y2=\"" << coord(y) << "\"/>\n";
  }
  svg << "</g>\n";

  // Bands first (under everything), then curves, then points.
  svg << "<g clip-path=\"url(#plot-area)\">\n";
  if (fit.covarianceAvailable) {
    for (size_t k = 0; k < curves.size(); ++k) {
      const auto& c = curves[k];
      svg << "<polygon class=\"band\" fill=\"" << kPalette[k % kPalette.size()]
          << "\" fill-opacity=\"0.15\" stroke=\"none\" points=\"";
      for (size_t i = 0; i < c.velocityKmS.size(); ++i)
        svg << coord(px(c.velocityKmS[i])) << ',' << coord(py(c.highMm[i])) << ' ';
      for (size_t i = c.velocityKmS.size(); i-- > 0;)
        svg << coord(px(c.velocityKmS[i])) << ',' << coord(py(c.lowMm[i])) << (i ? " " : "");
      svg << "\"/>\n";
    }
  }
  for (size_t k = 0; k < curves.size(); ++k) {
    const auto& c = curves[k];
    svg << "<path class=\"curve\" fill=\"none\" stroke=\"" << kPalette[k % kPalette.size()]
        << "\" stroke-width=\"2\" stroke-linejoin=\"round\" d=\"";
    for (size_t i = 0; i < c.velocityKmS.size(); ++i)
      svg << (i ? " L" : "M") << coord(px(c.velocityKmS[i])) << ',' << coord(py(c.dcMm[i]));
    svg << "\"/>\n";
  }
  bool anyOtherAngle = false;
  for (const auto& p : points) {
    const double v = units::toUnit(p.velocity, "km/s"), d = units::toUnit(p.diameter, "mm");
    const int k = curveIndexFor(p, options.angles);
    anyOtherAngle |= k < 0;
    const std::string colour = k < 0 ? kOtherAngleColour : kPalette[static_cast<size_t>(k) % kPalette.size()];
    svg << "<circle class=\"point\" cx=\"" << coord(px(v)) << "\" cy=\"" << coord(py(d)) << "\" r=\"4\" fill=\""
        << (p.perforated ? colour : std::string("white")) << "\" stroke=\"" << colour << "\" stroke-width=\"1.5\">"
        << "<title>" << xmlEscape((p.source.empty() ? std::string() : p.source + ": ") + number(d, "%.4g") + " mm at " +
                                  number(v, "%.4g") + " km/s, " + number(units::toUnit(p.angle, "deg"), "%.4g") +
                                  " deg, " + (p.perforated ? "perforated" : "stopped"))
        << "</title></circle>\n";
  }
  svg << "</g>\n";

  // Frame, tick marks and tick labels.
  svg << "<rect x=\"" << left << "\" y=\"" << top << "\" width=\"" << right - left << "\" height=\"" << bottom - top
      << "\" fill=\"none\" stroke=\"#333\" stroke-width=\"1\"/>\n";
  svg << "<g class=\"ticks\" stroke=\"#333\" stroke-width=\"1\">\n";
  for (int i = 0; i <= nx; ++i) {
    const double x = px(xAxis.lo + i * xAxis.step);
    svg << "<line x1=\"" << coord(x) << "\" y1=\"" << bottom << "\" x2=\"" << coord(x) << "\" y2=\"" << bottom + 5
        << "\"/>\n";
  }
  for (int i = 0; i <= ny; ++i) {
    const double y = py(yAxis.lo + i * yAxis.step);
    svg << "<line x1=\"" << left - 5 << "\" y1=\"" << coord(y) << "\" x2=\"" << left << "\" y2=\"" << coord(y)
        << "\"/>\n";
  }
  svg << "</g>\n<g class=\"tick-labels\" font-size=\"12\" fill=\"#222\">\n";
  for (int i = 0; i <= nx; ++i) {
    const double value = xAxis.lo + i * xAxis.step;
    svg << "<text x=\"" << coord(px(value)) << "\" y=\"" << bottom + 20 << "\" text-anchor=\"middle\">"
        << tickLabel(value, xAxis.decimals) << "</text>\n";
  }
  for (int i = 0; i <= ny; ++i) {
    const double value = yAxis.lo + i * yAxis.step;
    svg << "<text x=\"" << left - 9 << "\" y=\"" << coord(py(value) + 4) << "\" text-anchor=\"end\">"
        << tickLabel(value, yAxis.decimals) << "</text>\n";
  }
  svg << "</g>\n";
  svg << "<text class=\"axis-label\" x=\"" << coord((left + right) / 2) << "\" y=\"" << bottom + 45
      << "\" text-anchor=\"middle\" font-size=\"14\">Impact velocity V (km/s)</text>\n"
      << "<text class=\"axis-label\" x=\"0\" y=\"0\" transform=\"translate(" << left - 52 << ' '
      << coord((top + bottom) / 2) << ") rotate(-90)\" text-anchor=\"middle\" font-size=\"14\">"
      << "Critical diameter d_c (mm)</text>\n";

  // Legend, right of the frame.
  const double lx = right + 22;
  double ly = top + 8;
  svg << "<g class=\"legend\" font-size=\"12\" fill=\"#222\">\n";
  for (size_t k = 0; k < curves.size(); ++k) {
    const char* colour = kPalette[k % kPalette.size()];
    svg << "<line x1=\"" << lx << "\" y1=\"" << ly << "\" x2=\"" << lx + 26 << "\" y2=\"" << ly << "\" stroke=\""
        << colour << "\" stroke-width=\"2\"/>\n"
        << "<text x=\"" << lx + 34 << "\" y=\"" << ly + 4 << "\">" << xmlEscape(angleLabel(options.angles[k]))
        << "</text>\n";
    ly += 22;
  }
  if (fit.covarianceAvailable) {
    svg << "<rect x=\"" << lx << "\" y=\"" << ly - 7 << "\" width=\"26\" height=\"14\" fill=\"#777\" "
        << "fill-opacity=\"0.2\"/>\n"
        << "<text x=\"" << lx + 34 << "\" y=\"" << ly + 4 << "\">" << number(options.bandLevel * 100, "%.4g")
        << " % band</text>\n";
    ly += 22;
  }
  ly += 6;
  auto markerEntry = [&](const char* fill, const char* stroke, const std::string& label) {
    svg << "<circle class=\"legend-marker\" cx=\"" << lx + 13 << "\" cy=\"" << ly << "\" r=\"4\" fill=\"" << fill
        << "\" stroke=\"" << stroke << "\" stroke-width=\"1.5\"/>\n"
        << "<text x=\"" << lx + 34 << "\" y=\"" << ly + 4 << "\">" << xmlEscape(label) << "</text>\n";
    ly += 22;
  };
  if (!points.empty()) {
    markerEntry("#333", "#333", "perforated");
    markerEntry("white", "#333", "stopped");
  }
  if (anyOtherAngle) markerEntry(kOtherAngleColour, kOtherAngleColour, "other angle");
  svg << "</g>\n</svg>\n";

  std::ofstream out = openForWriting(path);
  out << svg.str();
  finish(out, path);
}

}  // namespace blt::ble
