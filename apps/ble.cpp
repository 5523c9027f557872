// blt ble: fit generalized Christiansen BLEs to binary impact data, keep them in a store, query them, draw their
// curves, and evaluate NASA's reference BLEs.
#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>
#include <sstream>

#include "blt/ble/christiansen.hpp"
#include "blt/campaign/database.hpp"
#include "blt/ble/curve.hpp"
#include "blt/ble/fit.hpp"
#include "blt/ble/impact_data.hpp"
#include "blt/ble/nasa.hpp"
#include "blt/ble/store.hpp"
#include "cli_support.hpp"
#include "commands.hpp"

namespace blt::cli {

namespace {

using ble::ChristiansenCoefficients;

std::string plain(double value, const char* format = "%.6g") {
  char buf[48];
  std::snprintf(buf, sizeof buf, format, value);
  return buf;
}

// A mean square error of diameters, m² -> mm².
double mm2(double squareMetres) { return squareMetres * 1e6; }

// The store must exist for every subcommand except fit: opening a missing path would silently create an empty one.
void requireExistingStore(const std::string& path) {
  if (!std::filesystem::exists(path))
    throw InputError(InputLocation::flag("--db"), "no such file '" + path + "'",
                     "an existing BLE store, made by 'blt ble fit DATA.csv --db FILE --name NAME'");
}

double checkedLevel(double level) {
  if (!(level > 0.0 && level < 1.0))
    throw InputError(InputLocation::flag("--level"), "'" + plain(level) + "' is not a probability level",
                     "0 < level < 1, e.g. 0.9");
  return level;
}

// The density given on the command line, else the fit's default; one of them is needed.
double densityFor(const CLI::App& cmd, double flagValue, const ble::StoredFit& fit) {
  const double density = cmd.count("--density") ? flagValue : fit.options.defaultProjectileDensity;
  if (!(density > 0.0))
    throw InputError(InputLocation::flag("--density"),
                     cmd.count("--density") ? "the projectile density must be positive, got " + units::format(density, "kg/m3")
                                            : "fit '" + fit.name + "' has no default projectile density",
                     "a density > 0, e.g. --density 2770kg/m3");
  return density;
}

// Display unit of each coefficient: the velocities in km/s as the seed quotes them, the rest as stored (SI).
struct CoefficientDisplay {
  const char* jsonKey;
  const char* label;
  const char* unit;  // for units::toUnit; nullptr = shown as stored
  const char* unitText;
};
constexpr std::array<CoefficientDisplay, ChristiansenCoefficients::kCount> kCoefficientDisplay{{
    {"VL_km_s", "V_L", "km/s", "km/s"},
    {"VH_km_s", "V_H", "km/s", "km/s"},
    {"CL", "C_L", nullptr, "kg^1/2 s^-2/3 m^1/6"},
    {"CH", "C_H", nullptr, "kg^1/2 s^-2/3 m^1/6"},
    {"SL", "S_L", nullptr, ""},
    {"SH", "S_H", nullptr, ""},
    {"X", "X", nullptr, ""},
    {"XH", "X_H", nullptr, ""},
}};

double displayValue(size_t i, double si) {
  return kCoefficientDisplay[i].unit ? units::toUnit(si, kCoefficientDisplay[i].unit) : si;
}

// Standard error of coefficient i from the covariance diagonal, in the display unit; nullopt when not available.
std::optional<double> standardError(const ble::FitResult& r, size_t i) {
  if (!r.covarianceAvailable) return std::nullopt;
  const double variance = r.covariance[i * ChristiansenCoefficients::kCount + i];
  if (!(variance > 0.0) || !std::isfinite(variance)) return std::nullopt;
  return displayValue(i, std::sqrt(variance));
}

// ---- blt ble fit -------------------------------------------------------------------------------------------

struct FitCommandOptions {
  std::vector<std::string> dataFiles;
  std::string db, name, method = "two-stage", pyblossum;
  std::vector<std::string> where, campaigns;
  std::string campaignDb;
  double density = 0;
  int folds = 0;
  // Defaults from FitOptions, so that the help shows them.
  double minimumTransition = ble::FitOptions{}.minimumTransitionWidth;   // m/s
  double wrongSideWeight = ble::FitOptions{}.wrongSideWeight;            // dimensionless
  double wrongSideMargin = ble::FitOptions{}.wrongSideMargin;            // m
  bool replace = false, json = false;
};

void runFit(const CLI::App& cmd, const FitCommandOptions& o) {
  ble::FitOptions options;
  try {
    options.method = ble::fitMethodFromString(o.method);
  } catch (const InputError& e) {
    throw InputError(InputLocation::flag("--method"), e.problem(), "two-stage, joint, classify");
  }
  if (cmd.count("--density")) {
    if (!(o.density > 0.0))
      throw InputError(InputLocation::flag("--density"),
                       "the projectile density must be positive, got " + units::format(o.density, "kg/m3"),
                       "a density > 0, e.g. 2770kg/m3");
    options.defaultProjectileDensity = o.density;
  }
  if (cmd.count("--cv")) {
    if (o.folds < 2)
      throw InputError(InputLocation::flag("--cv"), "'" + std::to_string(o.folds) + "' folds cannot cross-validate",
                       "an integer >= 2, e.g. --cv 10");
    options.crossValidationFolds = o.folds;
  }
  if (!(std::isfinite(o.minimumTransition) && o.minimumTransition > 0.0))
    throw InputError(InputLocation::flag("--min-transition"),
                     "the minimum V_H - V_L must be positive, got " + units::format(o.minimumTransition, "m/s"),
                     "a velocity > 0, e.g. --min-transition 100m/s");
  options.minimumTransitionWidth = o.minimumTransition;
  if (!(std::isfinite(o.wrongSideWeight) && o.wrongSideWeight >= 0.0))
    throw InputError(InputLocation::flag("--wrong-side-weight"), "'" + plain(o.wrongSideWeight) + "' is not a weight",
                     "a number >= 0 (0 = plain least squares), e.g. --wrong-side-weight 10");
  options.wrongSideWeight = o.wrongSideWeight;
  if (!(std::isfinite(o.wrongSideMargin) && o.wrongSideMargin >= 0.0))
    throw InputError(InputLocation::flag("--wrong-side-margin"),
                     "the margin must not be negative, got " + units::format(o.wrongSideMargin, "mm"),
                     "a length >= 0, e.g. --wrong-side-margin 0.02mm");
  options.wrongSideMargin = o.wrongSideMargin;
  if (!o.where.empty() && o.pyblossum.empty())
    throw InputError(InputLocation::flag("--where"), "--where filters a pyBLOSSUM database, but none is given",
                     "--pyblossum FILE --where column=value");
  if (!o.campaigns.empty() && o.campaignDb.empty())
    throw InputError(InputLocation::flag("--campaign"), "--campaign needs the run database it is in",
                     "--campaign NAME --campaign-db FILE (--db is the BLE store the fit goes to)");
  if (o.dataFiles.empty() && o.pyblossum.empty() && o.campaigns.empty())
    throw InputError(InputLocation{{}, std::nullopt, "DATA"}, "no impact data given",
                     "one or more impact CSV files, --pyblossum FILE and/or --campaign NAME --campaign-db FILE");

  // Refuse an existing name before the (possibly long) fit; the store itself checks again when saving.
  if (!o.replace && std::filesystem::exists(o.db)) {
    const ble::BleStore existing(o.db);
    if (existing.hasFit(o.name))
      throw InputError(InputLocation::flag("--name"), "a fit named '" + o.name + "' already exists in " + o.db,
                       "another --name, or --replace to overwrite it");
  }

  std::vector<ble::ImpactPoint> points;
  std::string origin;
  for (const auto& file : o.dataFiles) {
    const auto read = ble::readImpactCsv(file);
    points.insert(points.end(), read.begin(), read.end());
    origin += (origin.empty() ? "" : "; ") + file;
  }
  if (!o.pyblossum.empty()) {
    std::vector<ble::ColumnCondition> conditions;
    std::string filter;
    for (const auto& w : o.where) {
      conditions.push_back(ble::ColumnCondition::parse(w, "--where"));
      filter += (filter.empty() ? " where " : ", ") + w;
    }
    const auto read = ble::readPyblossum(o.pyblossum, conditions);
    points.insert(points.end(), read.begin(), read.end());
    origin += (origin.empty() ? "" : "; ") + ("pyBLOSSUM " + o.pyblossum + filter);
  }

  if (!o.campaigns.empty()) {
    if (!std::filesystem::exists(o.campaignDb))
      throw InputError(InputLocation::flag("--campaign-db"), "no such file '" + o.campaignDb + "'",
                       "a run database made by blt campaign run");
    const campaign::RunDatabase runs(o.campaignDb);
    for (const auto& name : o.campaigns) {
      const auto read = campaign::campaignImpactPoints(runs, name);
      points.insert(points.end(), read.begin(), read.end());
      origin += (origin.empty() ? "" : "; ") + ("campaign " + name + " in " + o.campaignDb);
    }
  }

  // Fit first: a failed fit must leave the store untouched.
  const ble::FitResult result = ble::fitChristiansen(points, options);

  const ble::StoredFit stored = ble::storedFit(o.name, options, result, points, origin);
  ble::BleStore store(o.db);
  store.saveFit(stored, o.replace);

  const auto values = result.coefficients.toArray();
  if (o.json) {
    nlohmann::json coefficients = nlohmann::json::object(), errors = nlohmann::json::object();
    for (size_t i = 0; i < values.size(); ++i) {
      coefficients[kCoefficientDisplay[i].jsonKey] = displayValue(i, values[i]);
      const auto se = standardError(result, i);
      errors[kCoefficientDisplay[i].jsonKey] = se ? nlohmann::json(*se) : nlohmann::json(nullptr);
    }
    nlohmann::json doc = {
        {"name", o.name},
        {"method", ble::toString(result.method)},
        {"db", o.db},
        {"coefficients", coefficients},
        {"stderr", errors},
        {"mse_mm2", mm2(result.meanSquareError)},
        {"misclassified", result.misclassified},
        {"n_points", result.pointCount},
        {"default_projectile_density_kg_m3", options.defaultProjectileDensity},
        {"minimum_transition_width_m_s", options.minimumTransitionWidth},
        {"data_hash", stored.dataHash},
        {"covariance_available", result.covarianceAvailable},
    };
    if (!result.covarianceNote.empty()) doc["covariance_note"] = result.covarianceNote;
    if (result.method == ble::FitMethod::Classify) {
      doc["scatter_ln_d"] = result.scatter;
    } else {
      doc["wrong_side_weight"] = options.wrongSideWeight;
      doc["wrong_side_margin_m"] = options.wrongSideMargin;
    }
    if (result.crossValidatedAccuracy) {
      doc["cv_accuracy"] = *result.crossValidatedAccuracy;
      doc["cv_folds"] = options.crossValidationFolds;
    }
    printJson(doc);
    return;
  }

  std::ostringstream out;
  out << "Fit '" << o.name << "' (" << ble::toString(result.method) << ", " << result.pointCount << " points";
  if (options.defaultProjectileDensity > 0)
    out << ", projectile density " << units::format(options.defaultProjectileDensity, "kg/m3", 5) << " unless given";
  out << ") saved to " << o.db << "\n";
  if (result.method != ble::FitMethod::Classify) {
    if (options.wrongSideWeight > 0)
      out << "  wrong-side hinge: weight " << plain(options.wrongSideWeight) << ", margin "
          << units::format(options.wrongSideMargin, "mm", 4) << "\n";
    else
      out << "  plain least squares on d (no wrong-side hinge)\n";
  }
  for (size_t i = 0; i < values.size(); ++i) {
    const auto& d = kCoefficientDisplay[i];
    const auto se = standardError(result, i);
    char line[160];
    std::snprintf(line, sizeof line, "  %-4s = %-10.5g %s %-8s %s", d.label, displayValue(i, values[i]),
                  se ? "\xC2\xB1" : " ", se ? plain(*se, "%.3g").c_str() : "", d.unitText);
    std::string text = line;
    text.erase(text.find_last_not_of(' ') + 1);
    out << text << "\n";
  }
  if (!result.covarianceAvailable) out << "  (no standard errors: " << result.covarianceNote << ")\n";
  else if (!result.covarianceNote.empty()) out << "  (standard errors: " << result.covarianceNote << ")\n";
  out << "  mean square error of d: " << plain(mm2(result.meanSquareError), "%.5g")
      << " mm\xC2\xB2\n";
  if (result.method == ble::FitMethod::Classify)
    out << "  scatter of ln(d/d_c): " << plain(result.scatter, "%.4g") << "\n";
  out << "  misclassified: " << result.misclassified << " of " << result.pointCount << " points\n";
  if (result.crossValidatedAccuracy)
    out << "  cross-validated accuracy (" << options.crossValidationFolds
        << " folds): " << plain(*result.crossValidatedAccuracy * 100, "%.1f") << " %\n";
  std::cout << out.str();
}

// ---- blt ble query -----------------------------------------------------------------------------------------

struct QueryOptions {
  std::string db, name;
  double velocity = 0, angle = 0, density = 0, level = 0.90;
  double diameter = 0;  // m; > 0 asks for the shot's margin ln(d/d_c)
  bool json = false;
};

void runQuery(const CLI::App& cmd, const QueryOptions& o) {
  if (!(o.velocity > 0.0))
    throw InputError(InputLocation::flag("--velocity"), "the velocity must be positive, got " + units::format(o.velocity, "km/s"),
                     "a velocity > 0, e.g. 7km/s");
  if (!(o.angle >= 0.0 && o.angle < units::fromUnit(90.0, "deg")))
    throw InputError(InputLocation::flag("--angle"), "angle " + units::format(o.angle, "deg") + " is outside the range",
                     "0 <= angle < 90 deg");
  const double level = checkedLevel(o.level);
  requireExistingStore(o.db);
  const ble::BleStore store(o.db);
  const ble::StoredFit fit = store.loadFit(o.name);
  const double density = densityFor(cmd, o.density, fit);
  const ble::DiameterBand band = ble::criticalDiameterBand(fit.result, o.velocity, o.angle, density, level);
  if (cmd.count("--diameter") && !(o.diameter > 0.0))
    throw InputError(InputLocation::flag("--diameter"), "the diameter must be positive, got " + units::format(o.diameter, "mm"),
                     "a diameter > 0, e.g. 1.2mm");
  const bool hasShot = o.diameter > 0.0;
  const double margin = hasShot ? ble::margin(fit.result.coefficients, o.diameter, o.velocity, o.angle, density) : 0.0;

  // Flag a query outside the velocities and angles the fit has seen: the BLE is then an extrapolation.
  bool extrapolated = false;
  if (!fit.points.empty()) {
    const auto [vMin, vMax] = std::minmax_element(fit.points.begin(), fit.points.end(),
                                                  [](const auto& a, const auto& b) { return a.velocity < b.velocity; });
    const auto [aMin, aMax] = std::minmax_element(fit.points.begin(), fit.points.end(),
                                                  [](const auto& a, const auto& b) { return a.angle < b.angle; });
    extrapolated = o.velocity < vMin->velocity || o.velocity > vMax->velocity || o.angle < aMin->angle - 1e-9 ||
                   o.angle > aMax->angle + 1e-9;
  }

  if (o.json) {
    nlohmann::json doc{{"name", fit.name},
               {"method", ble::toString(fit.result.method)},
               {"velocity_m_s", o.velocity},
               {"angle_rad", o.angle},
               {"projectile_density_kg_m3", density},
               {"level", level},
               {"critical_diameter_m", band.criticalDiameter},
               {"band_low_m", band.low},
               {"band_high_m", band.high},
               {"band_available", fit.result.covarianceAvailable},
               {"extrapolated", extrapolated}};
    if (hasShot) {
      doc["diameter_m"] = o.diameter;
      doc["margin"] = margin;
      doc["perforation_expected"] = margin > 0.0;
    }
    printJson(doc);
    return;
  }
  std::ostringstream out;
  out << "d_c = " << units::format(band.criticalDiameter, "mm", 4);
  if (fit.result.covarianceAvailable)
    out << "  (" << plain(level * 100, "%.4g") << " % band " << plain(units::toUnit(band.low, "mm"), "%.4g") << " to "
        << units::format(band.high, "mm", 4) << ")";
  else
    out << "  (no band: the fit has no covariance)";
  out << "\n  at " << units::format(o.velocity, "km/s", 4) << ", " << units::format(o.angle, "deg", 4) << ", "
      << units::format(density, "kg/m3", 5) << "; fit '" << fit.name << "' (" << ble::toString(fit.result.method)
      << ")\n";
  if (hasShot)
    out << "  shot of " << units::format(o.diameter, "mm", 4) << ": margin ln(d/d_c) = " << plain(margin, "%.4g") << ", "
        << (margin > 0.0 ? "perforation expected" : "the target should stop it") << "\n";
  if (extrapolated) out << "  note: outside the velocities/angles of the fit's data, an extrapolation\n";
  std::cout << out.str();
}

// ---- blt ble curve -----------------------------------------------------------------------------------------

// "0,45,60" (degrees) or "0deg,0.785rad": each item a bare number in degrees or a value with an angle unit.
std::vector<double> parseAngleList(const std::string& text) {
  const auto where = InputLocation::flag("--angles");
  std::vector<double> angles;
  std::stringstream items(text);
  std::string item;
  while (std::getline(items, item, ',')) {
    const auto first = item.find_first_not_of(" \t"), last = item.find_last_not_of(" \t");
    if (first == std::string::npos)
      throw InputError(where, "empty item in '" + text + "'", "a comma list of angles, e.g. 0,45,60 or 0deg,45deg");
    item = item.substr(first, last - first + 1);
    double degrees = 0;
    const auto [end, ec] = std::from_chars(item.data(), item.data() + item.size(), degrees);
    const double angle = (ec == std::errc() && end == item.data() + item.size())
                             ? units::fromUnit(degrees, "deg")
                             : units::parse(item, units::angle, where);
    if (!(angle >= 0.0 && angle < units::fromUnit(90.0, "deg")))
      throw InputError(where, "angle '" + item + "' is outside the range", "0 <= angle < 90 deg");
    angles.push_back(angle);
  }
  if (angles.empty()) throw InputError(where, "no angle given", "a comma list of angles, e.g. 0,45,60");
  return angles;
}

struct CurveCommandOptions {
  std::string db, name, angles = "0", out, title;
  double vmin = 1000.0, vmax = 10000.0, density = 0, level = 0.90;
  int samples = 181;
  bool json = false;
};

void runCurve(const CLI::App& cmd, const CurveCommandOptions& o) {
  std::string extension = std::filesystem::path(o.out).extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (extension != ".svg" && extension != ".csv")
    throw InputError(InputLocation::flag("--out"),
                     "'" + o.out + "' has " + (extension.empty() ? "no extension" : "the extension '" + extension + "'") +
                         "; the format is chosen by it",
                     ".svg (figure) or .csv (table)");
  ble::CurveOptions options;
  options.angles = parseAngleList(o.angles);
  options.velocityMin = o.vmin;
  options.velocityMax = o.vmax;
  options.samples = o.samples;
  options.bandLevel = checkedLevel(o.level);
  requireExistingStore(o.db);
  const ble::BleStore store(o.db);
  const ble::StoredFit fit = store.loadFit(o.name);
  options.projectileDensity = densityFor(cmd, o.density, fit);
  options.title = o.title.empty() ? "Ballistic limit curves of fit '" + fit.name + "'" : o.title;

  if (extension == ".svg")
    ble::writeCurveSvg(o.out, fit.result, fit.points, options);
  else
    ble::writeCurveCsv(o.out, fit.result, options);

  std::vector<double> anglesDeg;
  for (double a : options.angles) anglesDeg.push_back(units::toUnit(a, "deg"));
  if (o.json) {
    printJson({{"name", fit.name},
               {"out", o.out},
               {"format", extension.substr(1)},
               {"angles_rad", options.angles},
               {"velocity_min_m_s", options.velocityMin},
               {"velocity_max_m_s", options.velocityMax},
               {"samples", options.samples},
               {"projectile_density_kg_m3", options.projectileDensity},
               {"level", options.bandLevel},
               {"points_drawn", extension == ".svg" ? fit.points.size() : 0}});
    return;
  }
  std::cout << "Wrote " << o.out << ": fit '" << fit.name << "', " << options.angles.size() << " curve(s) at ";
  for (size_t i = 0; i < anglesDeg.size(); ++i) std::cout << (i ? ", " : "") << plain(anglesDeg[i], "%.4g");
  std::cout << " deg, " << units::format(options.velocityMin, "km/s", 4) << " to "
            << units::format(options.velocityMax, "km/s", 4) << ", " << units::format(options.projectileDensity, "kg/m3", 5);
  if (extension == ".svg") std::cout << ", " << fit.points.size() << " data points";
  std::cout << "\n";
}

// ---- blt ble list ------------------------------------------------------------------------------------------

struct ListOptions {
  std::string db;
  bool json = false;
};

void runList(const ListOptions& o) {
  requireExistingStore(o.db);
  const ble::BleStore store(o.db);
  const auto fits = store.listFits();
  if (o.json) {
    nlohmann::json rows = nlohmann::json::array();
    for (const auto& f : fits)
      rows.push_back({{"name", f.name},
                      {"family", f.family},
                      {"method", f.method},
                      {"n_points", f.pointCount},
                      {"mse_mm2", mm2(f.meanSquareError)},
                      {"misclassified", f.misclassified},
                      {"created_utc", f.createdUtc},
                      {"data_hash", f.dataHash}});
    printJson({{"db", o.db}, {"fits", rows}});
    return;
  }
  if (fits.empty()) {
    std::cout << "No fits in " << o.db << "\n";
    return;
  }
  size_t nameWidth = 4;
  for (const auto& f : fits) nameWidth = std::max(nameWidth, f.name.size());
  char line[512];
  std::snprintf(line, sizeof line, "%-*s  %-10s  %8s  %11s  %13s  %s\n", static_cast<int>(nameWidth), "name", "method",
                "n points", "MSE mm\xC2\xB2", "misclassified", "created (UTC)");
  std::cout << line;
  for (const auto& f : fits) {
    std::snprintf(line, sizeof line, "%-*s  %-10s  %8d  %10.5g  %13d  %s\n", static_cast<int>(nameWidth),
                  f.name.c_str(), f.method.c_str(), f.pointCount, mm2(f.meanSquareError),
                  f.misclassified, f.createdUtc.c_str());
    std::cout << line;
  }
}

// ---- blt ble eval ------------------------------------------------------------------------------------------

struct EvalOptions {
  std::string family;
  ble::WhippleShield whipple;
  ble::SingleWallTarget wall;
  double projectileDensity = 0, velocity = 0, angle = 0;
  bool json = false;
};

const std::vector<std::string> kWhippleFlags{"--bumper-thickness", "--bumper-density", "--wall-thickness",
                                             "--wall-yield", "--standoff"};
const std::vector<std::string> kSingleWallFlags{"--thickness", "--density", "--brinell", "--sound-speed"};

// `unit` is how the value is shown back in the message ("" for a plain number).
void requirePositive(const CLI::App& cmd, const std::string& flag, double value, const std::string& example,
                     const std::string& unit) {
  if (!cmd.count(flag))
    throw InputError(InputLocation::flag(flag), "required for this --family", "e.g. " + flag + " " + example);
  if (!(value > 0.0) || !std::isfinite(value))
    throw InputError(InputLocation::flag(flag),
                     "must be positive, got " + (unit.empty() ? plain(value) : units::format(value, unit)),
                     "a value > 0, e.g. " + example);
}

void runEval(const CLI::App& cmd, const EvalOptions& o) {
  const bool whipple = o.family == "whipple";
  // A flag of the other family is most likely a mix-up; say so rather than ignore it.
  for (const auto& flag : whipple ? kSingleWallFlags : kWhippleFlags)
    if (cmd.count(flag))
      throw InputError(InputLocation::flag(flag), "does not apply to --family " + o.family,
                       whipple ? "for whipple: --bumper-thickness --bumper-density --wall-thickness --wall-yield --standoff"
                               : "for single-wall: --thickness --density --brinell --sound-speed");
  requirePositive(cmd, "--projectile-density", o.projectileDensity, "2796kg/m3", "kg/m3");
  requirePositive(cmd, "--velocity", o.velocity, "6.5km/s", "km/s");
  if (!(o.angle >= 0.0 && o.angle < units::fromUnit(90.0, "deg")))
    throw InputError(InputLocation::flag("--angle"), "angle " + units::format(o.angle, "deg") + " is outside the range",
                     "0 <= angle < 90 deg");

  double dc = 0;
  nlohmann::json inputs;
  std::string description;
  if (whipple) {
    requirePositive(cmd, "--bumper-thickness", o.whipple.bumperThickness, "1.6mm", "mm");
    requirePositive(cmd, "--bumper-density", o.whipple.bumperDensity, "2713kg/m3", "kg/m3");
    requirePositive(cmd, "--wall-thickness", o.whipple.wallThickness, "3.18mm", "mm");
    requirePositive(cmd, "--wall-yield", o.whipple.wallYieldStress, "469MPa", "MPa");
    requirePositive(cmd, "--standoff", o.whipple.standoff, "10.16cm", "cm");
    dc = ble::whippleCriticalDiameter(o.whipple, o.projectileDensity, o.velocity, o.angle);
    inputs = {{"bumper_thickness_m", o.whipple.bumperThickness}, {"bumper_density_kg_m3", o.whipple.bumperDensity},
              {"wall_thickness_m", o.whipple.wallThickness},     {"wall_yield_Pa", o.whipple.wallYieldStress},
              {"standoff_m", o.whipple.standoff}};
    description = "NASA Whipple BLE (Christiansen 1993): bumper " + units::format(o.whipple.bumperThickness, "mm", 4) +
                  ", wall " + units::format(o.whipple.wallThickness, "mm", 4) + " (" +
                  units::format(o.whipple.wallYieldStress, "MPa", 4) + "), standoff " +
                  units::format(o.whipple.standoff, "cm", 4);
  } else {
    requirePositive(cmd, "--thickness", o.wall.thickness, "3.175mm", "mm");
    requirePositive(cmd, "--density", o.wall.density, "2713kg/m3", "kg/m3");
    requirePositive(cmd, "--brinell", o.wall.brinellHardness, "95", "");
    requirePositive(cmd, "--sound-speed", o.wall.soundSpeed, "5.1km/s", "km/s");
    dc = ble::singleWallCriticalDiameter(o.wall, o.projectileDensity, o.velocity, o.angle);
    inputs = {{"thickness_m", o.wall.thickness},
              {"density_kg_m3", o.wall.density},
              {"brinell_hardness", o.wall.brinellHardness},
              {"sound_speed_m_s", o.wall.soundSpeed}};
    description = "NASA single-wall BLE (Cour-Palais): wall " + units::format(o.wall.thickness, "mm", 4) + ", " +
                  units::format(o.wall.density, "kg/m3", 5) + ", BHN " + plain(o.wall.brinellHardness, "%.4g");
  }
  if (o.json) {
    inputs["projectile_density_kg_m3"] = o.projectileDensity;
    inputs["velocity_m_s"] = o.velocity;
    inputs["angle_rad"] = o.angle;
    printJson({{"family", o.family}, {"critical_diameter_m", dc}, {"inputs", inputs}});
    return;
  }
  std::cout << "d_c = " << units::format(dc, "mm", 4) << "\n  " << description << "\n  projectile "
            << units::format(o.projectileDensity, "kg/m3", 5) << " at " << units::format(o.velocity, "km/s", 4) << ", "
            << units::format(o.angle, "deg", 4) << "\n";
}

}  // namespace

void registerBleCommand(CLI::App& app) {
  auto* ble = app.add_subcommand(
      "ble",
      "Ballistic limit equations: fit the generalized Christiansen BLE to binary impact data (kept in a SQLite store), "
      "query it, draw its curves; evaluate NASA's reference BLEs");
  ble->require_subcommand(1);

  // fit
  {
    auto* cmd = ble->add_subcommand(
        "fit",
        "Fit the generalized Christiansen BLE (seed 000 Eq. 12) to binary impact data and save it in the store.\n"
        "Input CSV columns: diameter_mm, velocity_km_s, angle_deg, perforated, source [, projectile_density_kg_m3].\n"
        "The fit is run first; nothing is written when it fails.\n"
        "two-stage and joint fit least squares on d plus a hinge on points that do not clear the curve on their "
        "own side (--wrong-side-weight, --wrong-side-margin); --wrong-side-weight 0 is the seed's plain least "
        "squares.\n"
        "Example: blt ble fit data/seed/seed000_table1_tests.csv data/seed/seed000_table6_mpm.csv "
        "data/seed/seed000_table7_mpm.csv --db fits.db --name seed000 --density 2770kg/m3\n"
        "Example: blt ble fit data/seed/seed000_table1_tests.csv data/seed/seed000_table7_mpm.csv --db fits.db "
        "--name plain --density 2770kg/m3 --wrong-side-weight 0 --min-transition 200m/s");
    auto o = std::make_shared<FitCommandOptions>();
    cmd->add_option("data", o->dataFiles, "Impact CSV files (binary outcome per shot)");
    cmd->add_option("--db", o->db, "BLE store (SQLite file; created when missing)")->required();
    cmd->add_option("--name", o->name, "Name of the fit in the store (unique)")->required();
    cmd->add_option("--method", o->method,
                    "two-stage (seed 000 §6: V_L, V_H, C_L, C_H on the 0 deg points, then the angle exponents), "
                    "joint (all eight at once), classify (probit likelihood of the outcomes)")
        ->capture_default_str();
    addQuantity(*cmd, "--density", o->density, units::density,
                "projectile density for points whose data do not give one");
    cmd->add_option("--cv", o->folds, "K-fold cross-validated classification accuracy (K >= 2)");
    addQuantity(*cmd, "--min-transition", o->minimumTransition, units::velocity,
                "smallest V_H - V_L the fit may reach, which is how V_L < V_H is kept (default " +
                    units::format(o->minimumTransition, "m/s") + ")");
    cmd->add_option("--wrong-side-weight", o->wrongSideWeight,
                    "two-stage and joint: each point adds (W v)^2 to the squared residuals of d, v = how far it falls "
                    "short of lying the margin on its own side of the curve (perforated above, stopped below); a "
                    "large W makes the outcomes constraints, 0 is plain least squares (the seed's method); "
                    "ignored by classify")
        ->capture_default_str();
    addQuantity(*cmd, "--wrong-side-margin", o->wrongSideMargin, units::length,
                "how far a point must clear the curve on its own side before the hinge is off, about half the "
                "data's diameter resolution (default " +
                    units::format(o->wrongSideMargin, "mm") + ")");
    cmd->add_option("--pyblossum", o->pyblossum, "A pyBLOSSUM database CSV to take shots from");
    cmd->add_option("--where", o->where,
                    "Filter on a pyBLOSSUM column, repeatable: column=value with or without unit "
                    "(e.g. --where wall_thick=0.318cm --where bumper_mat=AA6061-T6)")
        ->allow_extra_args(false);
    cmd->add_flag("--replace", o->replace, "Overwrite a fit of the same name");
    cmd->add_option("--campaign", o->campaigns,
                    "Take every completed run of this campaign as a data point (repeatable; with --campaign-db)");
    cmd->add_option("--campaign-db", o->campaignDb, "Run database of blt campaign run that holds the --campaign runs");
    addJsonFlag(*cmd, o->json);
    cmd->callback([cmd, o] { runFit(*cmd, *o); });
  }

  // query
  {
    auto* cmd = ble->add_subcommand(
        "query",
        "Critical diameter d_c of a stored fit at one velocity and angle, with its band (delta method on the fit's "
        "covariance). Text output in mm, JSON in m.\n"
        "Example: blt ble query --db fits.db --name seed000 --velocity 7km/s --angle 45deg");
    auto o = std::make_shared<QueryOptions>();
    cmd->add_option("--db", o->db, "BLE store (SQLite file)")->required();
    cmd->add_option("--name", o->name, "Name of the fit")->required();
    addQuantity(*cmd, "--velocity", o->velocity, units::velocity, "impact velocity")->required();
    addQuantity(*cmd, "--angle", o->angle, units::angle, "impact angle from the target normal (default 0 deg)");
    addQuantity(*cmd, "--density", o->density, units::density,
                "projectile density (default: the fit's default density)");
    addQuantity(*cmd, "--diameter", o->diameter, units::length,
                "a projectile diameter: also print its margin ln(d/d_c) and the expected outcome");
    cmd->add_option("--level", o->level, "two-sided probability of the band, 0 < level < 1")->capture_default_str();
    addJsonFlag(*cmd, o->json);
    cmd->callback([cmd, o] { runQuery(*cmd, *o); });
  }

  // curve
  {
    auto* cmd = ble->add_subcommand(
        "curve",
        "Write the d_c(V) curves of a stored fit at several angles: an SVG figure (curves, bands, the fitted points) "
        "or a CSV table (angle_deg, velocity_km_s, critical_diameter_mm, band_low_mm, band_high_mm), chosen by the "
        "extension of --out.\n"
        "Example: blt ble curve --db fits.db --name seed000 --angles 0,45,60 --out curve.svg");
    auto o = std::make_shared<CurveCommandOptions>();
    cmd->add_option("--db", o->db, "BLE store (SQLite file)")->required();
    cmd->add_option("--name", o->name, "Name of the fit")->required();
    cmd->add_option("--angles", o->angles,
                    "Comma list of angles from the target normal; bare numbers are degrees (0,45,60), or give units "
                    "(0deg,45deg,1rad)")
        ->capture_default_str();
    cmd->add_option("--out", o->out, "Output file: .svg or .csv")->required();
    addQuantity(*cmd, "--vmin", o->vmin, units::velocity, "lowest velocity of the curves (default 1 km/s)");
    addQuantity(*cmd, "--vmax", o->vmax, units::velocity, "highest velocity of the curves (default 10 km/s)");
    addQuantity(*cmd, "--density", o->density, units::density,
                "projectile density (default: the fit's default density)");
    cmd->add_option("--level", o->level, "two-sided probability of the band, 0 < level < 1")->capture_default_str();
    cmd->add_option("--samples", o->samples, "points along each curve")->capture_default_str();
    cmd->add_option("--title", o->title, "figure title (SVG)");
    addJsonFlag(*cmd, o->json);
    cmd->callback([cmd, o] { runCurve(*cmd, *o); });
  }

  // list
  {
    auto* cmd = ble->add_subcommand("list",
                                    "List the fits in a store: name, method, points, MSE (mm²), misclassified, "
                                    "creation time.\nExample: blt ble list --db fits.db");
    auto o = std::make_shared<ListOptions>();
    cmd->add_option("--db", o->db, "BLE store (SQLite file)")->required();
    addJsonFlag(*cmd, o->json);
    cmd->callback([o] { runList(*o); });
  }

  // eval
  {
    auto* cmd = ble->add_subcommand(
        "eval",
        "Critical diameter from NASA's reference BLEs (Christiansen 1993; NASA/TM-2009-214785).\n"
        "whipple: --bumper-thickness --bumper-density --wall-thickness --wall-yield --standoff\n"
        "single-wall (Cour-Palais): --thickness --density --brinell --sound-speed\n"
        "both: --projectile-density --velocity [--angle, default 0 deg]\n"
        "Example: blt ble eval --family whipple --bumper-thickness 1.6mm --bumper-density 2713kg/m3 "
        "--wall-thickness 3.18mm --wall-yield 469MPa --standoff 10.16cm --projectile-density 2796kg/m3 "
        "--velocity 6.5km/s --angle 30deg");
    auto o = std::make_shared<EvalOptions>();
    cmd->add_option("--family", o->family, "whipple or single-wall")
        ->required()
        ->check(CLI::IsMember({"whipple", "single-wall"}));
    addQuantity(*cmd, "--bumper-thickness", o->whipple.bumperThickness, units::length, "Whipple bumper thickness");
    addQuantity(*cmd, "--bumper-density", o->whipple.bumperDensity, units::density, "Whipple bumper density");
    addQuantity(*cmd, "--wall-thickness", o->whipple.wallThickness, units::length, "Whipple rear wall thickness");
    addQuantity(*cmd, "--wall-yield", o->whipple.wallYieldStress, units::pressure, "Whipple rear wall yield stress");
    addQuantity(*cmd, "--standoff", o->whipple.standoff, units::length, "Whipple bumper-to-wall spacing");
    addQuantity(*cmd, "--thickness", o->wall.thickness, units::length, "single wall thickness");
    addQuantity(*cmd, "--density", o->wall.density, units::density, "single wall density");
    addQuantity(*cmd, "--brinell", o->wall.brinellHardness, units::dimensionless, "single wall Brinell hardness (BHN)");
    addQuantity(*cmd, "--sound-speed", o->wall.soundSpeed, units::velocity, "speed of sound in the single wall");
    addQuantity(*cmd, "--projectile-density", o->projectileDensity, units::density, "projectile density");
    addQuantity(*cmd, "--velocity", o->velocity, units::velocity, "impact velocity");
    addQuantity(*cmd, "--angle", o->angle, units::angle, "impact angle from the target normal (default 0 deg)");
    addJsonFlag(*cmd, o->json);
    cmd->callback([cmd, o] { runEval(*cmd, *o); });
  }
}

}  // namespace blt::cli
