// BLE curves written as CSV and SVG. The fit is made by hand (seed 000 Table 8 coefficients, a covariance set
// here), so these tests check the writers, not the fitting.
#include <doctest/doctest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "approx.hpp"
#include "blt/ble/curve.hpp"
#include "blt/core/csv.hpp"
#include "blt/core/error.hpp"
#include "blt/core/units.hpp"
#include "svg_check.hpp"

using namespace blt;

namespace {

std::string tempPath(const std::string& name) { return (std::filesystem::temp_directory_path() / name).string(); }

std::string readAll(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

ble::FitResult seedFit() {
  ble::FitResult fit;
  fit.coefficients = ble::ChristiansenCoefficients::seed000Table8();
  fit.pointCount = 63;
  return fit;
}

// Options that put the samples exactly on REFERENCE §1's grid: 2, 3, ..., 9 km/s at 0, 45, 60 deg.
ble::CurveOptions referenceGrid() {
  ble::CurveOptions o;
  o.angles = {0.0, units::fromUnit(45, "deg"), units::fromUnit(60, "deg")};
  o.velocityMin = units::fromUnit(2, "km/s");
  o.velocityMax = units::fromUnit(9, "km/s");
  o.samples = 8;
  o.projectileDensity = 2770.0;  // 2A12, seed 000 Table 3
  return o;
}

std::vector<ble::ImpactPoint> seedPoints() {
  std::vector<ble::ImpactPoint> points;
  for (const char* file : {"seed000_table1_tests.csv", "seed000_table6_mpm.csv", "seed000_table7_mpm.csv"}) {
    const auto read = ble::readImpactCsv(std::string(BLT_DATA_DIR) + "/seed/" + file);
    points.insert(points.end(), read.begin(), read.end());
  }
  return points;
}

}  // namespace

TEST_CASE("ble curve: CSV rows reproduce REFERENCE §1's d_c table for the seed 000 Table 8 coefficients") {
  const std::string path = tempPath("blt_curve_reference.csv");
  const auto fit = seedFit();  // no covariance: the band collapses onto the curve
  const auto options = referenceGrid();
  ble::writeCurveCsv(path, fit, options);

  const auto t = csv::Table::read(path);
  CHECK(t.header() ==
        std::vector<std::string>{"angle_deg", "velocity_km_s", "critical_diameter_mm", "band_low_mm", "band_high_mm"});
  REQUIRE(t.rowCount() == 24);
  // REFERENCE §1 (computed from seed 000 Eq. 12 with Table 8's coefficients), mm, rows 0/45/60 deg, 2..9 km/s.
  const double expectedMm[3][8] = {
      {1.5560, 1.1875, 0.9802, 0.8912, 0.9455, 0.9346, 0.8550, 0.7904},
      {1.8377, 1.4024, 1.1577, 1.0079, 1.0218, 1.0122, 0.9260, 0.8560},
      {2.1703, 1.6562, 1.3672, 1.1782, 1.1277, 1.0940, 1.0028, 0.9271},
  };
  const double anglesDeg[3] = {0, 45, 60};
  for (size_t row = 0; row < t.rowCount(); ++row) {
    const size_t a = row / 8, v = row % 8;
    CAPTURE(row);
    CHECK(t.number(row, t.column("angle_deg")) == doctest::Approx(anglesDeg[a]));
    CHECK(t.number(row, t.column("velocity_km_s")) == relApprox(2.0 + v, 1e-9));
    const double dcMm = t.number(row, t.column("critical_diameter_mm"));
    CHECK(std::abs(dcMm - expectedMm[a][v]) < 1e-4);
    const double direct = ble::criticalDiameter(fit.coefficients, units::fromUnit(2.0 + v, "km/s"),
                                                units::fromUnit(anglesDeg[a], "deg"), 2770.0);
    CHECK(units::fromUnit(dcMm, "mm") == relApprox(direct, 1e-9));
    // No covariance: low = high = d_c (fit.hpp's contract for criticalDiameterBand).
    CHECK(t.number(row, t.column("band_low_mm")) == relApprox(dcMm, 1e-12));
    CHECK(t.number(row, t.column("band_high_mm")) == relApprox(dcMm, 1e-12));
  }
}

TEST_CASE("ble curve: CSV band columns follow the covariance (hand-made: C_L only)") {
  auto fit = seedFit();
  // Only C_L uncertain, σ(C_L) = 0.5. Below V1 (ballistic branch) d_c ∝ C_L, so by hand the delta method on ln d_c
  // gives σ(ln d_c) = σ(C_L)/C_L and the 90 % band d_c exp(±1.6448536 σ/C_L). Above V2 (shatter branch) d_c does
  // not depend on C_L at all, so the band has zero width there.
  const double sigmaCL = 0.5;
  fit.covariance[2 * 8 + 2] = sigmaCL * sigmaCL;
  fit.covarianceAvailable = true;
  const auto options = referenceGrid();
  const std::string path = tempPath("blt_curve_band.csv");
  ble::writeCurveCsv(path, fit, options);
  const auto t = csv::Table::read(path);
  REQUIRE(t.rowCount() == 24);
  const double z90 = 1.6448536269514722;  // standard normal quantile at 0.95
  for (size_t row = 0; row < t.rowCount(); ++row) {
    CAPTURE(row);
    const double velocityKmS = t.number(row, t.column("velocity_km_s"));
    const double angle = units::fromUnit(t.number(row, t.column("angle_deg")), "deg");
    const double dc = units::fromUnit(t.number(row, t.column("critical_diameter_mm")), "mm");
    const double low = units::fromUnit(t.number(row, t.column("band_low_mm")), "mm");
    const double high = units::fromUnit(t.number(row, t.column("band_high_mm")), "mm");
    // What the CSV promises: criticalDiameterBand's numbers.
    const auto band = ble::criticalDiameterBand(fit, units::fromUnit(velocityKmS, "km/s"), angle, 2770.0, 0.90);
    CHECK(low == relApprox(band.low, 1e-9));
    CHECK(high == relApprox(band.high, 1e-9));
    // The regime boundaries of seed 000 Eq. 12 at this angle decide which branch (and so which C) d_c uses.
    const auto& c = fit.coefficients;
    const double velocity = units::fromUnit(velocityKmS, "km/s");
    const double v1 = c.VL / std::pow(std::cos(angle), c.SL), v2 = c.VH / std::pow(std::cos(angle), c.SH);
    if (velocity <= v1) {
      CHECK(low == relApprox(dc * std::exp(-z90 * sigmaCL / c.CL), 1e-7));
      CHECK(high == relApprox(dc * std::exp(z90 * sigmaCL / c.CL), 1e-7));
    } else if (velocity >= v2) {
      CHECK(low == relApprox(dc, 1e-9));
      CHECK(high == relApprox(dc, 1e-9));
    } else {
      CHECK(low < dc);
      CHECK(high > dc);
    }
  }
}

TEST_CASE("ble curve: the SVG is well-formed with one curve per angle, one marker per point and labelled axes") {
  auto fit = seedFit();
  fit.covariance[2 * 8 + 2] = 0.25;
  fit.covariance[3 * 8 + 3] = 0.25;
  fit.covarianceAvailable = true;
  const auto points = seedPoints();
  REQUIRE(points.size() == 73);  // 13 tests + 16 Table 6 rows + 44 Table 7 rows
  auto options = referenceGrid();
  options.velocityMin = units::fromUnit(1, "km/s");
  options.velocityMax = units::fromUnit(10, "km/s");
  options.samples = 91;
  options.title = "Fit <seed000> & 'Table 8'";
  const std::string path = tempPath("blt_curve.svg");
  ble::writeCurveSvg(path, fit, points, options);
  const std::string svg = readAll(path);

  std::string problem;
  CHECK_MESSAGE(wellFormed(svg, problem), problem);
  CHECK(svg.rfind("<?xml", 0) == 0);
  CHECK(countOf(svg, "<svg ") == 1);
  CHECK(countOf(svg, "<path class=\"curve\"") == 3);
  CHECK(countOf(svg, "<polygon class=\"band\"") == 3);
  CHECK(countOf(svg, "<circle class=\"point\"") == points.size());
  // Filled markers for perforated points, open (white) ones for stopped: as many of each as the data have.
  size_t perforated = 0;
  for (const auto& p : points) perforated += p.perforated;
  size_t openMarkers = 0;
  for (size_t pos = svg.find("<circle class=\"point\""); pos != std::string::npos;
       pos = svg.find("<circle class=\"point\"", pos + 1))
    openMarkers += svg.substr(pos, svg.find('>', pos) - pos).find("fill=\"white\"") != std::string::npos;
  CHECK(perforated > 0);
  CHECK(openMarkers == points.size() - perforated);
  CHECK(svg.find(">Impact velocity V (km/s)</text>") != std::string::npos);
  CHECK(svg.find(">Critical diameter d_c (mm)</text>") != std::string::npos);
  CHECK(svg.find(">perforated</text>") != std::string::npos);
  CHECK(svg.find(">stopped</text>") != std::string::npos);
  // Legend entries per angle, title escaped.
  CHECK(svg.find("\xCE\xB8 = 45\xC2\xB0") != std::string::npos);
  CHECK(svg.find("Fit &lt;seed000&gt; &amp; &apos;Table 8&apos;") != std::string::npos);
  CHECK(svg.find("<seed000>") == std::string::npos);
}

TEST_CASE("ble curve: no band without covariance, points at other angles are drawn grey") {
  const auto fit = seedFit();
  auto options = referenceGrid();
  options.angles = {0.0};
  ble::ImpactPoint at30;
  at30.diameter = 1.2e-3;
  at30.velocity = 5000;
  at30.angle = units::fromUnit(30, "deg");
  at30.perforated = true;
  const std::string path = tempPath("blt_curve_grey.svg");
  ble::writeCurveSvg(path, fit, {at30}, options);
  const std::string svg = readAll(path);
  std::string problem;
  CHECK_MESSAGE(wellFormed(svg, problem), problem);
  CHECK(countOf(svg, "<polygon class=\"band\"") == 0);
  CHECK(countOf(svg, "<path class=\"curve\"") == 1);
  CHECK(svg.find("<circle class=\"point\" cx=\"") != std::string::npos);
  CHECK(svg.find("fill=\"#8c8c8c\" stroke=\"#8c8c8c\"") != std::string::npos);
  CHECK(svg.find(">other angle</text>") != std::string::npos);
}

TEST_CASE("ble curve: errors name the path or the option and what is allowed") {
  const auto fit = seedFit();
  auto options = referenceGrid();
  const std::string missingDir = tempPath("blt_no_such_dir") + "/curve.csv";
  CHECK_THROWS_WITH_AS(ble::writeCurveCsv(missingDir, fit, options),
                       doctest::Contains(("file " + missingDir + ": cannot open the file for writing").c_str()), InputError);
  CHECK_THROWS_WITH_AS(ble::writeCurveSvg(tempPath("blt_no_such_dir") + "/curve.svg", fit, {}, options),
                       doctest::Contains("blt_no_such_dir/curve.svg: cannot open the file for writing"), InputError);
  options.projectileDensity = 0;
  CHECK_THROWS_WITH_AS(ble::writeCurveCsv(tempPath("blt_curve_err.csv"), fit, options),
                       doctest::Contains("flag --density: the projectile density must be positive (allowed: a density > 0"),
                       InputError);
  options = referenceGrid();
  options.velocityMax = options.velocityMin;
  CHECK_THROWS_WITH_AS(ble::writeCurveSvg(tempPath("blt_curve_err.svg"), fit, {}, options),
                       doctest::Contains("flag --vmax: the highest velocity (2 km/s) must exceed the lowest (2 km/s)"),
                       InputError);
  options = referenceGrid();
  options.angles = {units::fromUnit(90, "deg")};
  CHECK_THROWS_WITH_AS(ble::writeCurveCsv(tempPath("blt_curve_err.csv"), fit, options),
                       doctest::Contains("flag --angles: angle 90 deg is outside the range (allowed: 0 <= angle < 90 deg)"),
                       InputError);
}
