#include "blt/calibrate/measured.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <numbers>
#include <optional>

namespace blt::calibrate {

const char* toString(ObservationKind kind) {
  switch (kind) {
    case ObservationKind::outcome: return "outcome";
    case ObservationKind::residualVelocity: return "residual_velocity";
    case ObservationKind::holeHorizontal: return "hole_h";
    case ObservationKind::holeVertical: return "hole_v";
  }
  return "?";
}

const char* displayUnit(ObservationKind kind) {
  switch (kind) {
    case ObservationKind::outcome: return "";
    case ObservationKind::residualVelocity: return "m/s";
    case ObservationKind::holeHorizontal:
    case ObservationKind::holeVertical: return "mm";
  }
  return "";
}

bool MeasuredData::has(ObservationKind kind) const {
  return std::any_of(observations.begin(), observations.end(),
                     [kind](const Observation& o) { return o.kind == kind; });
}

namespace {

// The velocity column: the file may use any one of these (unit in the name).
struct VelocityColumn {
  const char* name;
  const char* unit;
};
constexpr VelocityColumn velocityColumns[] = {
    {"velocity_km_s", "km/s"}, {"velocity_m_s", "m/s"}, {"impact_velocity_m_s", "m/s"}};

std::optional<size_t> optionalColumn(const csv::Table& t, const char* name) {
  if (!t.hasColumn(name)) return std::nullopt;
  return t.column(name);
}

bool empty(const csv::Table& t, size_t row, const std::optional<size_t>& col) {
  return !col || t.text(row, *col).empty();
}

}  // namespace

MeasuredData measuredDataFromTable(const csv::Table& t) {
  MeasuredData data;
  data.source = t.source();
  const auto fileAt = InputLocation::file(t.source());

  std::optional<size_t> velocityCol;
  const char* velocityUnit = nullptr;
  for (const auto& c : velocityColumns) {
    if (!t.hasColumn(c.name)) continue;
    if (velocityCol)
      throw InputError(fileAt.withField(c.name), "the file has more than one impact velocity column",
                       "one of velocity_km_s, velocity_m_s, impact_velocity_m_s");
    velocityCol = t.column(c.name);
    velocityUnit = c.unit;
  }
  if (!velocityCol)
    throw InputError(fileAt.withField("velocity_km_s"), "the impact velocity column is missing",
                     "one of velocity_km_s, velocity_m_s, impact_velocity_m_s");
  const auto caseCol = optionalColumn(t, "case");
  const auto scenarioCol = optionalColumn(t, "scenario");
  const auto diameterCol = optionalColumn(t, "diameter_mm");
  const auto angleCol = optionalColumn(t, "angle_deg");
  const auto perforatedCol = optionalColumn(t, "perforated");
  const auto residualCol = optionalColumn(t, "residual_velocity_m_s");
  const auto layerCol = optionalColumn(t, "layer");
  const auto holeHCol = optionalColumn(t, "hole_h_mm");
  const auto holeVCol = optionalColumn(t, "hole_v_mm");
  if ((holeHCol || holeVCol) && !layerCol)
    throw InputError(fileAt.withField("layer"), "hole sizes need the layer they were measured in",
                     "a 'layer' column beside hole_h_mm / hole_v_mm (a scenario layer's name or number)");
  if (!perforatedCol && !residualCol && !holeHCol && !holeVCol)
    throw InputError(fileAt, "the file measures nothing",
                     "at least one of the columns perforated, residual_velocity_m_s, hole_h_mm, hole_v_mm");
  data.hasDiameters = diameterCol.has_value();
  data.hasScenarios = scenarioCol.has_value();

  std::map<std::string, size_t> caseById;
  for (size_t row = 0; row < t.rowCount(); ++row) {
    MeasuredCase c;
    c.line = t.line(row);
    c.id = caseCol && !t.text(row, *caseCol).empty() ? t.text(row, *caseCol) : "line " + std::to_string(c.line);
    c.velocity = t.quantity(row, *velocityCol, velocityUnit);
    if (!(c.velocity > 0))
      throw InputError(t.where(row, *velocityCol), "the impact velocity " + t.text(row, *velocityCol) + " is not positive",
                       "a velocity above 0");
    if (scenarioCol && !t.text(row, *scenarioCol).empty()) {
      namespace fs = std::filesystem;
      const fs::path written = t.text(row, *scenarioCol);
      const fs::path path = written.is_absolute() ? written : fs::path(t.source()).parent_path() / written;
      if (!fs::is_regular_file(path))
        throw InputError(t.where(row, *scenarioCol), "no scenario file " + path.string(),
                         "a scenario file's path, relative to the measured file's folder");
      c.scenario = path.lexically_normal().string();
    }
    if (diameterCol && !(scenarioCol && t.text(row, *diameterCol).empty())) {
      c.diameter = t.quantity(row, *diameterCol, "mm");
      if (!(c.diameter > 0))
        throw InputError(t.where(row, *diameterCol), "the diameter " + t.text(row, *diameterCol) + " is not positive",
                         "a diameter above 0 mm");
    }
    if (angleCol && !t.text(row, *angleCol).empty()) {
      c.angle = t.quantity(row, *angleCol, "deg");
      if (!(c.angle >= 0 && c.angle < 0.5 * std::numbers::pi))
        throw InputError(t.where(row, *angleCol), "the angle " + t.text(row, *angleCol) + " deg is out of range",
                         "0 <= angle_deg < 90");
    }

    size_t index = 0;
    auto found = caseById.find(c.id);
    if (found == caseById.end()) {
      index = data.cases.size();
      caseById.emplace(c.id, index);
      data.cases.push_back(c);
    } else {
      index = found->second;
      const MeasuredCase& first = data.cases[index];
      const auto differs = [](double a, double b) { return std::abs(a - b) > 1e-9 * std::max(std::abs(a), std::abs(b)); };
      const char* field = differs(first.velocity, c.velocity)   ? t.header()[*velocityCol].c_str()
                          : differs(first.diameter, c.diameter) ? "diameter_mm"
                          : differs(first.angle, c.angle)       ? "angle_deg"
                          : first.scenario != c.scenario        ? "scenario"
                                                                : nullptr;
      if (field)
        throw InputError(InputLocation::file(t.source(), c.line, field),
                         "case '" + c.id + "' has a different " + field + " than on line " + std::to_string(first.line),
                         "the same scenario, diameter, velocity and angle on every row of one case");
    }

    bool measuredSomething = false;
    const auto add = [&](ObservationKind kind, double value, std::string layer = {}) {
      data.observations.push_back({index, kind, value, std::move(layer), c.line});
      measuredSomething = true;
    };
    if (!empty(t, row, perforatedCol)) add(ObservationKind::outcome, t.flag(row, *perforatedCol) ? 1.0 : 0.0);
    if (!empty(t, row, residualCol)) {
      const double vr = t.quantity(row, *residualCol, "m/s");
      if (!(vr >= 0 && vr <= c.velocity))
        throw InputError(t.where(row, *residualCol),
                         "the residual velocity " + t.text(row, *residualCol) + " m/s is outside [0, impact velocity]",
                         "0 <= residual_velocity_m_s <= the impact velocity");
      add(ObservationKind::residualVelocity, vr);
    }
    for (const auto& [col, kind] : {std::pair{holeHCol, ObservationKind::holeHorizontal},
                                    std::pair{holeVCol, ObservationKind::holeVertical}}) {
      if (empty(t, row, col)) continue;
      if (t.text(row, *layerCol).empty())
        throw InputError(t.where(row, *layerCol), "a hole size is given without its layer",
                         "a scenario layer's name or 1-based number");
      const double size = t.quantity(row, *col, "mm");
      if (!(size >= 0))
        throw InputError(t.where(row, *col), "the hole size " + t.text(row, *col) + " mm is negative",
                         "0 mm (no hole) or more");
      add(kind, size, t.text(row, *layerCol));
    }
    if (!measuredSomething)
      throw InputError(InputLocation::file(t.source(), c.line), "the row measures nothing (every measurement cell is empty)",
                       "a value in perforated, residual_velocity_m_s, hole_h_mm or hole_v_mm");
  }
  return data;
}

MeasuredData readMeasuredData(const std::string& path) { return measuredDataFromTable(csv::Table::read(path)); }

}  // namespace blt::calibrate
