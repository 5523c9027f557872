#pragma once
// NASA's reference ballistic limit equations (REFERENCE §2; Christiansen 1993, NASA/TM-2009-214785), kept as
// built-in families to compare fitted BLEs against. The equations are empirical fits in cm, g/cm³, km/s and
// ksi; the functions take and return SI and convert at their boundary.
//
// Single wall (Cour-Palais): penetration depth P = 5.24 d^(19/18) BHN^-¼ (ρp/ρt)^e (V cos θ / c_t)^⅔ with
// e = ½ (e = ⅔ when ρp/ρt >= 1.5); the wall is perforated when t < 1.8 P, so d_c solves t = 1.8 P.
//
// Whipple (Christiansen 1993), normal velocity Vn = V cos θ with θ capped at 65°: a ballistic regime
// (Vn <= 3 km/s), a shatter/melt regime (Vn >= 7 km/s) and a linear blend between.

namespace blt::ble {

struct SingleWallTarget {
  double thickness = 0;        // m
  double density = 0;          // kg/m³
  double brinellHardness = 0;  // BHN, dimensionless
  double soundSpeed = 0;       // m/s, speed of sound in the wall
};

// Critical diameter (m) for a projectile of density ρp (kg/m³) at V (m/s) and θ (rad).
double singleWallCriticalDiameter(const SingleWallTarget& wall, double projectileDensity, double velocity, double angle);

struct WhippleShield {
  double bumperThickness = 0;  // m
  double bumperDensity = 0;    // kg/m³
  double wallThickness = 0;    // m (rear wall)
  double wallYieldStress = 0;  // Pa (rear wall)
  double standoff = 0;         // m, bumper to rear wall
};

// Critical diameter (m) for a projectile of density ρp (kg/m³) at V (m/s) and θ (rad).
double whippleCriticalDiameter(const WhippleShield& shield, double projectileDensity, double velocity, double angle);

}  // namespace blt::ble
