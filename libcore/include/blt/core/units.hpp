#pragma once
// Units at the edges: text such as "1.2 mm", "6.5 km/s", "45 deg", "2770 kg/m3", "490 MPa", "0.197 kg" is
// parsed into SI here, and SI values are printed back with a named unit. Inside the code everything is SI
// (m, kg, s, K, rad, Pa, J).
//
// Unit expressions: factors separated by '*', '.' or ' ', each optionally raised to an integer power
// ("m3", "m^3", "s^-1"); '/' divides by the next factor ("J/kg/K" = J kg^-1 K^-1; "1/s" is a rate).
// Symbols: SI base and derived units with SI prefixes (mm, km, um, MPa, GPa, kJ, ms, us, g, mg, ...), and
// deg, rad, min, h, K, ksi, psi, in, ft, lbf, bar. Angles have their own dimension so "45 mm" is rejected
// where an angle is expected; "45 rad" and "45 deg" are both accepted.

#include <cstdint>
#include <string>
#include <string_view>

#include "blt/core/error.hpp"

namespace blt::units {

// Exponents of mass, length, time, temperature and plane angle.
struct Dimension {
  int8_t mass = 0, length = 0, time = 0, temperature = 0, angle = 0;
  friend bool operator==(const Dimension&, const Dimension&) = default;
  Dimension operator*(const Dimension& o) const;
  Dimension operator/(const Dimension& o) const;
  Dimension pow(int p) const;
};

inline constexpr Dimension dimensionless{};
inline constexpr Dimension length{0, 1, 0, 0, 0};
inline constexpr Dimension mass{1, 0, 0, 0, 0};
inline constexpr Dimension time{0, 0, 1, 0, 0};
inline constexpr Dimension temperature{0, 0, 0, 1, 0};
inline constexpr Dimension angle{0, 0, 0, 0, 1};
inline constexpr Dimension velocity{0, 1, -1, 0, 0};
inline constexpr Dimension density{1, -3, 0, 0, 0};
inline constexpr Dimension pressure{1, -1, -2, 0, 0};  // stress, modulus
inline constexpr Dimension energy{1, 2, -2, 0, 0};
inline constexpr Dimension rate{0, 0, -1, 0, 0};       // strain rate, frequency
inline constexpr Dimension specificHeat{0, 2, -2, -1, 0};
inline constexpr Dimension arealDensity{1, -2, 0, 0, 0};

// A human name for a dimension ("velocity", "pressure") or its exponents ("kg m^-1 s^-2").
std::string describe(const Dimension& d);
// An example of a value with that dimension, for error messages ("6.5 km/s").
std::string example(const Dimension& d);

struct Quantity {
  double si = 0.0;  // value in SI units (radians for angles)
  Dimension dimension;
};

// The SI factor and dimension of a unit expression such as "km/s". Throws InputError (at `where`) for an
// unknown unit.
Quantity parseUnit(std::string_view unit, const InputLocation& where = {});

// A number followed by a unit, with or without space ("6.5 km/s", "6.5km/s", "1e-3 m"). A bare number is
// dimensionless. Throws InputError naming `where` for malformed text or an unknown unit.
Quantity parseQuantity(std::string_view text, const InputLocation& where = {});

// Parses and checks the dimension; returns SI. A bare number where a dimension is required is an error
// ("a unit is required"), as is a wrong dimension. For dimensionless quantities a bare number is accepted.
double parse(std::string_view text, const Dimension& expected, const InputLocation& where = {});

// SI value expressed in `unit` (e.g. toUnit(6500, "km/s") == 6.5). Throws std::invalid_argument for a bad
// unit (a programming error: units in code are literals).
double toUnit(double si, std::string_view unit);
// SI value converted from `unit` (fromUnit(6.5, "km/s") == 6500).
double fromUnit(double value, std::string_view unit);
// "6.5 km/s": the SI value printed in `unit` with up to `digits` significant digits.
std::string format(double si, std::string_view unit, int digits = 6);

}  // namespace blt::units
