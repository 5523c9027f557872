#include "blt/ble/nasa.hpp"

#include <algorithm>
#include <cmath>

#include "blt/core/units.hpp"

namespace blt::ble {

double singleWallCriticalDiameter(const SingleWallTarget& wall, double projectileDensity, double velocity, double angle) {
  const double t = units::toUnit(wall.thickness, "cm");
  const double densityRatio = projectileDensity / wall.density;
  const double densityExponent = densityRatio >= 1.5 ? 2.0 / 3.0 : 0.5;
  const double vn = units::toUnit(velocity * std::cos(angle), "km/s");
  const double ct = units::toUnit(wall.soundSpeed, "km/s");
  // t = 1.8 * 5.24 d^(19/18) BHN^-1/4 (ρp/ρt)^e (Vn/ct)^(2/3), solved for d.
  const double perUnitDiameter =
      1.8 * 5.24 * std::pow(wall.brinellHardness, -0.25) * std::pow(densityRatio, densityExponent) * std::cbrt(vn / ct * vn / ct);
  return units::fromUnit(std::pow(t / perUnitDiameter, 18.0 / 19.0), "cm");
}

double whippleCriticalDiameter(const WhippleShield& shield, double projectileDensity, double velocity, double angle) {
  const double theta = std::min(angle, units::fromUnit(65.0, "deg"));
  const double c = std::cos(theta);
  const double tw = units::toUnit(shield.wallThickness, "cm");
  const double tb = units::toUnit(shield.bumperThickness, "cm");
  const double S = units::toUnit(shield.standoff, "cm");
  const double sigma = units::toUnit(shield.wallYieldStress, "ksi");
  const double rhoP = units::toUnit(projectileDensity, "g/cm3");
  const double rhoB = units::toUnit(shield.bumperDensity, "g/cm3");
  const double V = units::toUnit(velocity, "km/s");
  const double vn = V * c;

  const double wallAndBumper = tw * std::sqrt(sigma / 40.0) + tb;
  const double shatterTerm = std::pow(tw, 2.0 / 3.0) * std::pow(rhoP, -1.0 / 3.0) * std::pow(rhoB, -1.0 / 9.0) *
                             std::cbrt(S) * std::cbrt(sigma / 70.0);
  double dc;  // cm
  if (vn <= 3.0) {
    dc = std::pow(wallAndBumper / (0.6 * std::pow(c, 5.0 / 3.0) * std::sqrt(rhoP) * std::cbrt(V * V)), 18.0 / 19.0);
  } else if (vn >= 7.0) {
    dc = 3.918 * shatterTerm / std::cbrt(vn * vn);
  } else {
    // The two regime formulas evaluated at Vn = 3 and Vn = 7, blended linearly in Vn.
    dc = std::pow(wallAndBumper / (1.248 * std::sqrt(rhoP) * c), 18.0 / 19.0) * (1.75 - vn / 4.0) +
         1.071 * shatterTerm * (vn / 4.0 - 0.75);
  }
  return units::fromUnit(dc, "cm");
}

}  // namespace blt::ble
