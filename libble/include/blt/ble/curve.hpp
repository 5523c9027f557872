#pragma once
// Ballistic limit curves for plotting: d_c against V at several angles (like seed 000 Fig. 20-21), with the fit's
// band and the fitted points (perforated and stopped drawn differently). Written as CSV or as an SVG figure with
// labelled axes in mm and km/s.

#include <string>
#include <vector>

#include "blt/ble/fit.hpp"
#include "blt/ble/impact_data.hpp"

namespace blt::ble {

struct CurveOptions {
  std::vector<double> angles{0.0};  // rad
  double velocityMin = 1000.0;      // m/s
  double velocityMax = 10000.0;     // m/s
  int samples = 181;                // points along each curve
  double projectileDensity = 0.0;   // kg/m³ the curves are drawn for (required > 0)
  double bandLevel = 0.90;          // two-sided band drawn around each curve when the fit has a covariance
  std::string title;                // figure title (SVG)
};

// CSV columns: angle_deg, velocity_km_s, critical_diameter_mm, band_low_mm, band_high_mm.
void writeCurveCsv(const std::string& path, const FitResult& fit, const CurveOptions& options);
// An SVG figure: one curve (and band) per angle, the points (filled = perforated, open = stopped), coloured by
// angle when their angle is one of the curves' (within 1 deg), grey otherwise.
void writeCurveSvg(const std::string& path, const FitResult& fit, const std::vector<ImpactPoint>& points,
                   const CurveOptions& options);

}  // namespace blt::ble
