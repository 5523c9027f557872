// Ballistic limit curves as CSV and as an SVG figure (drawn by blt/core/svg_plot).
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
#include "blt/core/svg_plot.hpp"
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

std::string angleLabel(double angleRad) {
  return "\xCE\xB8 = " + number(units::toUnit(angleRad, "deg"), "%.4g") + "\xC2\xB0";  // θ = 45°
}

constexpr const char* kOtherAngleColour = "#8c8c8c";

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

  svg::Plot plot;
  svg::PlotOptions& po = plot.options;
  double yLo = std::numeric_limits<double>::infinity(), yHi = -yLo;
  for (size_t k = 0; k < options.angles.size(); ++k) {
    const CurveSamples c = sampleCurve(fit, options.angles[k], options);
    svg::Series curve;
    curve.label = angleLabel(options.angles[k]);
    curve.x = c.velocityKmS;
    curve.y = c.dcMm;
    curve.style = svg::Style::line;
    curve.colour = svg::paletteColour(k);
    plot.series.push_back(curve);
    if (fit.covarianceAvailable)
      plot.bands.push_back(svg::Band{"", c.velocityKmS, c.lowMm, c.highMm, svg::paletteColour(k)});
    for (double d : c.dcMm) {
      yLo = std::min(yLo, d);
      yHi = std::max(yHi, d);
    }
  }
  // A wide band (poorly determined coefficients) is drawn but clipped: letting it set the range would flatten
  // the curves themselves.
  const double curveLo = yLo, curveHi = yHi;
  for (const svg::Band& b : plot.bands)
    for (size_t i = 0; i < b.x.size(); ++i) {
      yLo = std::min(yLo, std::max(b.low[i], 0.5 * curveLo));
      yHi = std::max(yHi, std::min(b.high[i], 2.0 * curveHi));
    }
  if (fit.covarianceAvailable)
    plot.bands.push_back(svg::Band{number(options.bandLevel * 100, "%.4g") + " % band", {}, {}, {}, "#777"});

  // Points coloured by the curve of their angle (one series each), grey for other angles.
  double xLo = units::toUnit(options.velocityMin, "km/s"), xHi = units::toUnit(options.velocityMax, "km/s");
  std::vector<svg::Series> markers(options.angles.size() + 1);
  for (size_t k = 0; k < markers.size(); ++k)
    markers[k].colour = k < options.angles.size() ? svg::paletteColour(k) : kOtherAngleColour;
  for (const auto& p : points) {
    const double v = units::toUnit(p.velocity, "km/s"), d = units::toUnit(p.diameter, "mm");
    if (!std::isfinite(v) || !std::isfinite(d)) continue;
    xLo = std::min(xLo, v);
    xHi = std::max(xHi, v);
    yLo = std::min(yLo, d);
    yHi = std::max(yHi, d);
    const int k = curveIndexFor(p, options.angles);
    svg::Series& s = markers[k < 0 ? options.angles.size() : static_cast<size_t>(k)];
    s.x.push_back(v);
    s.y.push_back(d);
    s.open.push_back(!p.perforated);
    s.tooltips.push_back((p.source.empty() ? std::string() : p.source + ": ") + number(d, "%.4g") + " mm at " +
                         number(v, "%.4g") + " km/s, " + number(units::toUnit(p.angle, "deg"), "%.4g") + " deg, " +
                         (p.perforated ? "perforated" : "stopped"));
  }
  for (auto& s : markers) plot.series.push_back(std::move(s));

  const double yPad = 0.05 * (yHi - yLo);
  po.xMin = xLo;
  po.xMax = xHi;
  po.yMin = yLo - yPad;
  po.yMax = yHi + yPad;
  po.title = options.title.empty() ? "Ballistic limit: critical diameter against impact velocity" : options.title;
  po.subtitle = "Christiansen BLE, " + toString(fit.method) + " fit to " + std::to_string(fit.pointCount) +
                " points; projectile density " + number(options.projectileDensity, "%.6g") + " kg/m\xC2\xB3";
  po.subtitle += fit.covarianceAvailable ? "; band: " + number(options.bandLevel * 100, "%.4g") + " % interval"
                                         : "; no band (no covariance)";
  po.xLabel = "Impact velocity V (km/s)";
  po.yLabel = "Critical diameter d_c (mm)";
  if (!points.empty()) {
    po.markerLegend.push_back({"perforated", "#333", "#333"});
    po.markerLegend.push_back({"stopped", "white", "#333"});
  }
  const bool anyOtherAngle = !plot.series.back().x.empty();
  if (anyOtherAngle) po.markerLegend.push_back({"other angle", kOtherAngleColour, kOtherAngleColour});
  svg::writeSvg(path, plot);
}

}  // namespace blt::ble
