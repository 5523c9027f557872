#pragma once
// Measured data for calibration: the shots (cases) and what was measured in each, whichever of these the file
// holds: the outcome (perforated or not), the residual velocity, and the hole size per layer.
//
// One CSV (read with libcore's reader), one row per measurement or per shot, columns named with their unit:
//   case                      optional: an id; rows with the same id are one shot (their d, V, theta must agree)
//   scenario                  optional: the shot's target as a scenario file (relative to the measured file's
//                             folder), for data on several targets (seed 003's four plates); empty: the
//                             calibration's --scenario. Solver model only.
//   diameter_mm               projectile diameter (required by the solver model unless the file has a scenario
//                             column, where an empty cell means the scenario's diameter; ignored by analytical
//                             models)
//   velocity_km_s | velocity_m_s | impact_velocity_m_s   impact velocity (one of them, required)
//   angle_deg                 optional, from the target normal, 0 <= theta < 90 (default 0)
//   perforated                optional: 1/0, Y/N, yes/no, true/false; empty cell: not measured
//   residual_velocity_m_s     optional: >= 0 (0: stopped); empty cell: not measured
//   layer, hole_h_mm, hole_v_mm   optional: the hole D_h x D_v in the named layer (a scenario layer's name or
//                             1-based number); empty cells: not measured
// A row must measure something. Errors name the file, the line and the column.

#include <string>
#include <vector>

#include "blt/core/csv.hpp"

namespace blt::calibrate {

enum class ObservationKind { outcome, residualVelocity, holeHorizontal, holeVertical };
// "outcome", "residual_velocity", "hole_h", "hole_v": JSON keys and report headings.
const char* toString(ObservationKind kind);
// A hole extent, either of the two.
inline bool isHole(ObservationKind kind) {
  return kind == ObservationKind::holeHorizontal || kind == ObservationKind::holeVertical;
}
// SI unit and the unit shown in reports: "" for outcomes, "m/s" for velocities, "mm" for holes.
const char* displayUnit(ObservationKind kind);

struct MeasuredCase {
  std::string id;
  std::string scenario; // the scenario file's path (resolved against the measured file's folder); empty: none given
  double diameter = 0;  // m; 0 when not given
  double velocity = 0;  // m/s
  double angle = 0;     // rad
  int line = 0;         // first line of the case in the file
};

struct Observation {
  std::size_t caseIndex = 0;
  ObservationKind kind = ObservationKind::outcome;
  double value = 0;   // outcome: 1 perforated, 0 not; residual velocity in m/s; hole size in m
  std::string layer;  // holes only: as written in the file
  int line = 0;
};

struct MeasuredData {
  std::string source;
  std::vector<MeasuredCase> cases;
  std::vector<Observation> observations;
  bool hasDiameters = false;
  bool hasScenarios = false;  // the file has a scenario column

  bool has(ObservationKind kind) const;
};

MeasuredData measuredDataFromTable(const csv::Table& table);
// Throws InputError naming the file, line and column.
MeasuredData readMeasuredData(const std::string& path);

}  // namespace blt::calibrate
