#pragma once
// Binary impact data: each point is one shot (test or simulation) with its outcome, perforated or not.
//
// The project's CSV has the columns diameter_mm, velocity_km_s, angle_deg, perforated, source and optionally
// projectile_density_kg_m3; 'perforated' accepts 1/0, Y/N, yes/no, true/false. The pyBLOSSUM databases (a
// header row, then a unit row; one row per shot of many target configurations) are read directly, with a
// filter that picks one configuration.

#include <string>
#include <vector>

namespace blt::ble {

struct ImpactPoint {
  double diameter = 0;           // m
  double velocity = 0;           // m/s
  double angle = 0;              // rad, from the target normal
  bool perforated = false;
  double projectileDensity = 0;  // kg/m³; 0 when the file does not say (the fit's --density applies)
  std::string source;            // provenance of the point ("seed000 Table 1", a shot id, ...)
  std::string origin;            // file and line it came from
};

// Reads the project's binary impact CSV. Throws InputError (file, line, field) for a missing column, a value
// that is not a number, a non-positive diameter or velocity, or an angle outside [0, 90) deg.
std::vector<ImpactPoint> readImpactCsv(const std::string& path);

// One equality condition on a pyBLOSSUM column: "wall_thick=0.318cm" compares in SI (relative 1e-6) when the
// value carries a unit, or as text otherwise ("bumper_mat=AA6061-T6").
struct ColumnCondition {
  std::string column;
  std::string value;
  // Parses "column=value"; throws InputError naming `where` when there is no '='.
  static ColumnCondition parse(const std::string& text, const std::string& where);
};

// Reads a pyBLOSSUM database and keeps the shots that meet every condition. Throws InputError when a condition
// names a column the file lacks, or when no shot is left.
std::vector<ImpactPoint> readPyblossum(const std::string& path, const std::vector<ColumnCondition>& where);

}  // namespace blt::ble
