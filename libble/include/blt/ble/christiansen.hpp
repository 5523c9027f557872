#pragma once
// The generalized Christiansen ballistic limit equation (seed 000 Eq. 12; REFERENCE §1): the critical
// projectile diameter d_c as a function of impact velocity V, angle from the target normal θ and projectile
// density ρ, in three regimes (ballistic below V1, shatter above V2, a linear blend between):
//
//   V1 = V_L / (cos θ)^S_L,   V2 = V_H / (cos θ)^S_H
//   V <= V1:  d_c = C_L / (ρ^½ V^⅔ (cos θ)^X)
//   V >= V2:  d_c = C_H / (ρ^½ V^⅔ (cos θ)^X_H)
//   between:  the two branch values at V1 and V2, interpolated linearly in V.
//
// Units are SI throughout: ρ in kg/m³, V in m/s, d_c in m, so C_L and C_H are in kg^½ s^-⅔ m^⅙. (The seed quotes
// V_L and V_H in km/s; that conversion happens at the edges.) Christiansen's EMU form (seed 000 Eq. 11) is the
// special case S_L = 0.132, S_H = 0.45, X_H = 0.45, V_L = 5.1 km/s, V_H = 6.95 km/s.
//
// The evaluation is a template so that Ceres can differentiate it with Jets.

#include <array>
#include <cmath>
#include <string>

namespace blt::ble {

// The eight coefficients, SI (velocities in m/s).
struct ChristiansenCoefficients {
  double VL = 0, VH = 0;  // regime boundaries at normal incidence, m/s
  double CL = 0, CH = 0;  // ballistic and shatter constants, kg^½ s^-⅔ m^⅙
  double SL = 0, SH = 0;  // angle exponents of the regime boundaries
  double X = 0, XH = 0;   // angle exponents of the ballistic and shatter branches

  static constexpr int kCount = 8;
  static constexpr std::array<const char*, kCount> kNames{"VL", "VH", "CL", "CH", "SL", "SH", "X", "XH"};
  std::array<double, kCount> toArray() const { return {VL, VH, CL, CH, SL, SH, X, XH}; }
  static ChristiansenCoefficients fromArray(const double* p) { return {p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7]}; }

  // Seed 000 Table 8 (the fabric-coated aluminium plate, 2A12 projectile).
  static ChristiansenCoefficients seed000Table8();
  // Christiansen's EMU form, seed 000 Eq. 11, with the given C_L, C_H, X.
  static ChristiansenCoefficients emu(double CL, double CH, double X);
};

// d_c for coefficients p[0..7] = (VL, VH, CL, CH, SL, SH, X, XH) in SI. T is double or a ceres::Jet.
template <typename T>
T christiansenCriticalDiameter(const T* p, double velocity, double angle, double projectileDensity) {
  using std::pow;
  const double cosTheta = std::cos(angle);
  const T& VL = p[0];
  const T& VH = p[1];
  const T& CL = p[2];
  const T& CH = p[3];
  const T& SL = p[4];
  const T& SH = p[5];
  const T& X = p[6];
  const T& XH = p[7];
  const double sqrtRho = std::sqrt(projectileDensity);
  const T V1 = VL / pow(cosTheta, SL);
  const T V2 = VH / pow(cosTheta, SH);
  if (velocity <= V1) return CL / (sqrtRho * std::cbrt(velocity * velocity) * pow(cosTheta, X));
  if (velocity >= V2) return CH / (sqrtRho * std::cbrt(velocity * velocity) * pow(cosTheta, XH));
  // Branch values at the regime boundaries, blended linearly in V.
  const T dAtV1 = CL / (sqrtRho * pow(V1, 2.0 / 3.0) * pow(cosTheta, X));
  const T dAtV2 = CH / (sqrtRho * pow(V2, 2.0 / 3.0) * pow(cosTheta, XH));
  const T w = (velocity - V1) / (V2 - V1);
  return dAtV2 * w + dAtV1 * (1.0 - w);
}

inline double criticalDiameter(const ChristiansenCoefficients& c, double velocity, double angle,
                               double projectileDensity) {
  const auto p = c.toArray();
  return christiansenCriticalDiameter(p.data(), velocity, angle, projectileDensity);
}

// The margin of a shot against the curve, ln(d / d_c): positive above the curve (perforation expected), negative
// below (the target should stop it). A binary data point is on the right side when its margin has the sign of its
// outcome.
inline double margin(const ChristiansenCoefficients& c, double diameter, double velocity, double angle,
                     double projectileDensity) {
  return std::log(diameter / criticalDiameter(c, velocity, angle, projectileDensity));
}

}  // namespace blt::ble
