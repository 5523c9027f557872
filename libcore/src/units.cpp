#include "blt/core/units.hpp"

#include <array>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>

namespace blt::units {

Dimension Dimension::operator*(const Dimension& o) const {
  return {int8_t(mass + o.mass), int8_t(length + o.length), int8_t(time + o.time),
          int8_t(temperature + o.temperature), int8_t(angle + o.angle)};
}
Dimension Dimension::operator/(const Dimension& o) const { return *this * o.pow(-1); }
Dimension Dimension::pow(int p) const {
  return {int8_t(mass * p), int8_t(length * p), int8_t(time * p), int8_t(temperature * p), int8_t(angle * p)};
}

namespace {

struct NamedDimension {
  Dimension dim;
  const char* name;
  const char* example;
};
constexpr std::array<NamedDimension, 13> kNamedDimensions{{
    {dimensionless, "dimensionless", "0.3"},
    {length, "length", "1.2 mm"},
    {mass, "mass", "0.197 kg"},
    {time, "time", "10 us"},
    {temperature, "temperature", "293 K"},
    {angle, "angle", "45 deg"},
    {velocity, "velocity", "6.5 km/s"},
    {density, "density", "2770 kg/m3"},
    {pressure, "pressure or stress", "490 MPa"},
    {energy, "energy", "1.5 J"},
    {rate, "rate", "1 1/s"},
    {specificHeat, "specific heat", "904 J/kg/K"},
    {arealDensity, "areal density", "2.7 kg/m2"},
}};

struct UnitSymbol {
  const char* symbol;
  double factor;
  Dimension dim;
  bool prefixable;
};
// Symbols tried as written first, then as an SI prefix followed by a prefixable symbol.
constexpr double kPi = 3.14159265358979323846;
const std::array<UnitSymbol, 22> kSymbols{{
    {"m", 1.0, length, true},
    {"g", 1e-3, mass, true},
    {"s", 1.0, time, true},
    {"K", 1.0, temperature, false},
    {"rad", 1.0, angle, false},
    {"deg", kPi / 180.0, angle, false},
    {"Pa", 1.0, pressure, true},
    {"N", 1.0, Dimension{1, 1, -2, 0, 0}, true},
    {"J", 1.0, energy, true},
    {"W", 1.0, Dimension{1, 2, -3, 0, 0}, true},
    {"Hz", 1.0, rate, true},
    {"bar", 1e5, pressure, false},
    {"min", 60.0, time, false},
    {"h", 3600.0, time, false},
    {"in", 0.0254, length, false},
    {"ft", 0.3048, length, false},
    {"psi", 6894.757293168361, pressure, false},
    {"ksi", 6894757.293168361, pressure, false},
    {"lbf", 4.4482216152605, Dimension{1, 1, -2, 0, 0}, false},
    {"lb", 0.45359237, mass, false},
    {"t", 1000.0, mass, false},
    {"1", 1.0, dimensionless, false},
}};

struct Prefix {
  const char* text;
  double factor;
};
constexpr std::array<Prefix, 13> kPrefixes{{
    {"T", 1e12}, {"G", 1e9}, {"M", 1e6}, {"k", 1e3}, {"h", 1e2}, {"c", 1e-2}, {"m", 1e-3},
    {"u", 1e-6}, {"\xC2\xB5", 1e-6}, {"\xCE\xBC", 1e-6}, {"n", 1e-9}, {"p", 1e-12}, {"d", 1e-1},
}};

const std::string kAllowedUnits =
    "SI units with prefixes (m, mm, um, km, g, kg, s, ms, us, Pa, MPa, GPa, N, J, W, Hz), K, deg, rad, min, h, "
    "in, ft, psi, ksi, lbf, lb, bar; combined with '/', '*' and powers, e.g. km/s, kg/m3, J/kg/K, 1/s";

bool lookupSymbol(std::string_view sym, Quantity& out) {
  for (const auto& u : kSymbols) {
    if (sym == u.symbol) {
      out = {u.factor, u.dim};
      return true;
    }
  }
  for (const auto& p : kPrefixes) {
    std::string_view pre(p.text);
    if (sym.size() > pre.size() && sym.substr(0, pre.size()) == pre) {
      std::string_view rest = sym.substr(pre.size());
      for (const auto& u : kSymbols) {
        if (u.prefixable && rest == u.symbol) {
          out = {p.factor * u.factor, u.dim};
          return true;
        }
      }
    }
  }
  return false;
}

bool isSymbolChar(unsigned char c) { return std::isalpha(c) || c >= 0x80; }

std::string trim(std::string_view s) {
  size_t b = 0, e = s.size();
  while (b < e && std::isspace(static_cast<unsigned char>(s[b]))) ++b;
  while (e > b && std::isspace(static_cast<unsigned char>(s[e - 1]))) --e;
  return std::string(s.substr(b, e - b));
}

}  // namespace

std::string describe(const Dimension& d) {
  for (const auto& n : kNamedDimensions)
    if (n.dim == d) return n.name;
  std::string text;
  const std::array<std::pair<const char*, int>, 5> parts{
      {{"kg", d.mass}, {"m", d.length}, {"s", d.time}, {"K", d.temperature}, {"rad", d.angle}}};
  for (const auto& [sym, e] : parts) {
    if (e == 0) continue;
    if (!text.empty()) text += ' ';
    text += sym;
    if (e != 1) text += "^" + std::to_string(e);
  }
  return text;
}

std::string example(const Dimension& d) {
  for (const auto& n : kNamedDimensions)
    if (n.dim == d) return n.example;
  return "a value with unit " + describe(d);
}

Quantity parseUnit(std::string_view unitText, const InputLocation& where) {
  const std::string unit = trim(unitText);
  if (unit.empty()) return {1.0, dimensionless};
  Quantity total{1.0, dimensionless};
  size_t i = 0;
  bool divideNext = false;
  bool expectFactor = true;
  auto fail = [&](const std::string& why) -> Quantity {
    throw InputError(where, "unit '" + unit + "' " + why, kAllowedUnits);
  };
  while (i < unit.size()) {
    const unsigned char c = static_cast<unsigned char>(unit[i]);
    if (c == ' ' || c == '*' || c == '.' || c == '\t') {
      ++i;
      continue;
    }
    if (c == '/') {
      if (divideNext) return fail("has two '/' in a row");
      divideNext = true;
      ++i;
      continue;
    }
    // A symbol: letters (or '1' as in "1/s"), then an optional power.
    size_t start = i;
    if (c == '1' && (i + 1 == unit.size() || unit[i + 1] == '/' || unit[i + 1] == ' ')) {
      ++i;
    } else {
      while (i < unit.size() && isSymbolChar(static_cast<unsigned char>(unit[i]))) ++i;
    }
    if (i == start) return fail("has an unexpected character '" + std::string(1, char(c)) + "'");
    std::string_view sym(unit.data() + start, i - start);
    int power = 1;
    if (i < unit.size() && (unit[i] == '^' || unit[i] == '-' || std::isdigit(static_cast<unsigned char>(unit[i])))) {
      if (unit[i] == '^') ++i;
      size_t pstart = i;
      if (i < unit.size() && unit[i] == '-') ++i;
      while (i < unit.size() && std::isdigit(static_cast<unsigned char>(unit[i]))) ++i;
      auto res = std::from_chars(unit.data() + pstart, unit.data() + i, power);
      if (res.ec != std::errc() || res.ptr != unit.data() + i) return fail("has a malformed power");
    }
    Quantity factor;
    if (!lookupSymbol(sym, factor)) return fail("contains the unknown symbol '" + std::string(sym) + "'");
    const int signedPower = divideNext ? -power : power;
    total.si *= std::pow(factor.si, signedPower);
    total.dimension = total.dimension * factor.dimension.pow(signedPower);
    divideNext = false;
    expectFactor = false;
  }
  if (divideNext || expectFactor) return fail("is incomplete");
  return total;
}

Quantity parseQuantity(std::string_view textIn, const InputLocation& where) {
  const std::string text = trim(textIn);
  if (text.empty()) throw InputError(where, "empty value", "a number with a unit, e.g. '6.5 km/s'");
  double value = 0.0;
  const char* begin = text.data();
  const char* end = text.data() + text.size();
  const char* numberStart = begin;
  if (*numberStart == '+') ++numberStart;  // from_chars does not take a leading '+'
  auto res = std::from_chars(numberStart, end, value);
  if (res.ec != std::errc() || !std::isfinite(value)) {
    throw InputError(where, "'" + text + "' does not start with a number", "a number with a unit, e.g. '6.5 km/s'");
  }
  Quantity unit = parseUnit(std::string_view(res.ptr, static_cast<size_t>(end - res.ptr)), where);
  return {value * unit.si, unit.dimension};
}

double parse(std::string_view text, const Dimension& expected, const InputLocation& where) {
  Quantity q = parseQuantity(text, where);
  const std::string trimmed = trim(text);
  if (q.dimension == expected) {
    return q.si;
  }
  const std::string allowed = "a " + describe(expected) + ", e.g. '" + example(expected) + "'";
  if (q.dimension == dimensionless) {
    // A bare number is a silent unit guess waiting to happen: require the unit.
    throw InputError(where, "'" + trimmed + "' has no unit; a unit is required", allowed);
  }
  throw InputError(where, "'" + trimmed + "' is a " + describe(q.dimension) + ", expected a " + describe(expected),
                   allowed);
}

double fromUnit(double value, std::string_view unit) {
  try {
    return value * parseUnit(unit).si;
  } catch (const InputError& e) {
    throw std::invalid_argument(e.what());
  }
}

double toUnit(double si, std::string_view unit) {
  try {
    return si / parseUnit(unit).si;
  } catch (const InputError& e) {
    throw std::invalid_argument(e.what());
  }
}

std::string format(double si, std::string_view unit, int digits) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*g", digits, toUnit(si, unit));
  std::string text(buf);
  if (!unit.empty()) text += " " + std::string(unit);
  return text;
}

}  // namespace blt::units
