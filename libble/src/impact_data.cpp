#include "blt/ble/impact_data.hpp"

#include <cmath>

#include "blt/core/csv.hpp"
#include "blt/core/error.hpp"
#include "blt/core/units.hpp"

namespace blt::ble {

namespace {

void checkPoint(const ImpactPoint& p, const csv::Table& t, size_t row, size_t dCol, size_t vCol, size_t aCol) {
  if (!(p.diameter > 0)) throw InputError(t.where(row, dCol), "'" + t.text(row, dCol) + "' is not a positive diameter", "> 0");
  if (!(p.velocity > 0)) throw InputError(t.where(row, vCol), "'" + t.text(row, vCol) + "' is not a positive velocity", "> 0");
  if (!(p.angle >= 0 && p.angle < units::fromUnit(90.0, "deg")))
    throw InputError(t.where(row, aCol), "angle " + t.text(row, aCol) + " is outside the range", "0 <= angle < 90 deg");
}

std::string originOf(const csv::Table& t, size_t row) { return t.source() + ":" + std::to_string(t.line(row)); }

}  // namespace

std::vector<ImpactPoint> readImpactCsv(const std::string& path) {
  const auto t = csv::Table::read(path);
  const size_t dCol = t.column("diameter_mm");
  const size_t vCol = t.column("velocity_km_s");
  const size_t aCol = t.column("angle_deg");
  const size_t pCol = t.column("perforated");
  const bool hasSource = t.hasColumn("source");
  const bool hasDensity = t.hasColumn("projectile_density_kg_m3");
  std::vector<ImpactPoint> points;
  for (size_t r = 0; r < t.rowCount(); ++r) {
    ImpactPoint p;
    p.diameter = t.quantity(r, dCol, "mm");
    p.velocity = t.quantity(r, vCol, "km/s");
    p.angle = t.quantity(r, aCol, "deg");
    p.perforated = t.flag(r, pCol);
    if (hasDensity) {
      const size_t rhoCol = t.column("projectile_density_kg_m3");
      p.projectileDensity = t.quantity(r, rhoCol, "kg/m3");
      if (!(p.projectileDensity > 0)) throw InputError(t.where(r, rhoCol), "not a positive density", "> 0 kg/m3");
    }
    if (hasSource) p.source = t.text(r, t.column("source"));
    p.origin = originOf(t, r);
    checkPoint(p, t, r, dCol, vCol, aCol);
    points.push_back(std::move(p));
  }
  return points;
}

ColumnCondition ColumnCondition::parse(const std::string& text, const std::string& where) {
  const auto eq = text.find('=');
  if (eq == std::string::npos || eq == 0)
    throw InputError(InputLocation::flag(where), "'" + text + "' is not a condition", "column=value, e.g. wall_thick=0.318cm");
  return {text.substr(0, eq), text.substr(eq + 1)};
}

std::vector<ImpactPoint> readPyblossum(const std::string& path, const std::vector<ColumnCondition>& where) {
  const auto t = csv::Table::read(path, {.unitRow = true});
  struct Test {
    size_t col;
    bool numeric;
    double si;
    std::string text;
  };
  std::vector<Test> tests;
  for (const auto& c : where) {
    Test test{t.column(c.column), false, 0.0, c.value};
    // A condition with a unit (or a plain number on a unitless column) is compared numerically.
    try {
      const auto q = units::parseQuantity(c.value, InputLocation::flag("--where").withField(c.column));
      const auto colUnit = units::parseUnit(t.unitOf(test.col), InputLocation::file(path, 2, c.column));
      if (!(q.dimension == colUnit.dimension))
        throw InputError(InputLocation::flag("--where").withField(c.column),
                         "'" + c.value + "' is a " + units::describe(q.dimension) + ", the column a " +
                             units::describe(colUnit.dimension),
                         "a value in a unit of " + units::describe(colUnit.dimension));
      test.numeric = true;
      test.si = q.si;
    } catch (const InputError& e) {
      if (std::string(e.what()).find("does not start with a number") == std::string::npos) throw;
    }
    tests.push_back(test);
  }
  auto si = [&](size_t r, const char* name) {
    const size_t col = t.column(name);
    return t.quantity(r, col, t.unitOf(col));
  };
  std::vector<ImpactPoint> points;
  for (size_t r = 0; r < t.rowCount(); ++r) {
    bool keep = true;
    for (const auto& test : tests) {
      if (test.numeric) {
        const double v = t.quantity(r, test.col, t.unitOf(test.col));
        keep = keep && std::abs(v - test.si) <= 1e-6 * std::max(std::abs(v), std::abs(test.si));
      } else {
        keep = keep && t.text(r, test.col) == test.text;
      }
    }
    if (!keep) continue;
    ImpactPoint p;
    p.diameter = si(r, "proj_diam");
    p.velocity = si(r, "velocity");
    p.angle = si(r, "angle");
    p.projectileDensity = si(r, "proj_density");
    p.perforated = t.flag(r, t.column("perforated_class"));
    p.source = t.text(r, t.column("source")) + " " + t.text(r, t.column("shotID"));
    p.origin = originOf(t, r);
    checkPoint(p, t, r, t.column("proj_diam"), t.column("velocity"), t.column("angle"));
    points.push_back(std::move(p));
  }
  if (points.empty()) throw InputError(InputLocation::file(path), "no shot meets the --where conditions");
  return points;
}

}  // namespace blt::ble
