// The BLE store on SQLite. Every value goes in through a bound parameter of a prepared statement; the only SQL
// built from text is the schema and the PRAGMAs, whose numbers are constants of this file.
#include "blt/ble/store.hpp"

#include <sqlite3.h>

#include <algorithm>
#include <bit>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <iterator>
#include <nlohmann/json.hpp>
#include <optional>
#include <string_view>
#include <utility>

#include "blt/core/clock.hpp"
#include "blt/core/error.hpp"
#include "blt/core/sqlite.hpp"

namespace blt::ble {

namespace {

// PRAGMA application_id of a blt BLE store ("BLTB"), so an SQLite file of another program is not taken for one.
constexpr int kApplicationId = 0x424C5442;

// ---- Schema and migrations -------------------------------------------------------------------------------------

// Schema version 1. Coefficients are SI: V_L, V_H in m/s; C_L, C_H in kg^½ s^-⅔ m^⅙; the exponents are pure numbers.
// The covariance is 64 IEEE doubles, row-major, little-endian (512 bytes), whatever the machine.
constexpr const char* kSchemaV1 = R"sql(
CREATE TABLE data_sets (
  id INTEGER PRIMARY KEY,
  origin TEXT NOT NULL,
  hash TEXT NOT NULL,
  point_count INTEGER NOT NULL,
  created_utc TEXT NOT NULL
);
CREATE TABLE points (
  data_set_id INTEGER NOT NULL REFERENCES data_sets(id) ON DELETE CASCADE,
  idx INTEGER NOT NULL,
  diameter_m REAL NOT NULL,
  velocity_m_s REAL NOT NULL,
  angle_rad REAL NOT NULL,
  perforated INTEGER NOT NULL CHECK (perforated IN (0, 1)),
  projectile_density_kg_m3 REAL NOT NULL,
  source TEXT NOT NULL,
  origin TEXT NOT NULL,
  PRIMARY KEY (data_set_id, idx)
);
CREATE TABLE fits (
  id INTEGER PRIMARY KEY,
  name TEXT NOT NULL UNIQUE,
  family TEXT NOT NULL,
  method TEXT NOT NULL,
  data_set_id INTEGER NOT NULL REFERENCES data_sets(id),
  vl_m_s REAL NOT NULL,
  vh_m_s REAL NOT NULL,
  cl REAL NOT NULL,
  ch REAL NOT NULL,
  sl REAL NOT NULL,
  sh REAL NOT NULL,
  x REAL NOT NULL,
  xh REAL NOT NULL,
  covariance BLOB NOT NULL,
  covariance_available INTEGER NOT NULL,
  covariance_note TEXT NOT NULL,
  scatter REAL NOT NULL,
  mse_m2 REAL NOT NULL,
  misclassified INTEGER NOT NULL,
  point_count INTEGER NOT NULL,
  cv_accuracy REAL,
  options TEXT NOT NULL,
  data_hash TEXT NOT NULL,
  tool_version TEXT NOT NULL,
  created_utc TEXT NOT NULL
);
)sql";

// A migration step takes a file from version k (its index in kMigrations) to k + 1.
using MigrationStep = void (*)(sqlite3* db, const std::string& path);

// Version 0 is the pre-release layout: the same three tables, no cross-validated accuracy and no application id.
void migrate0to1(sqlite3* db, const std::string& path) {
  sql::exec(db, path, "ALTER TABLE fits ADD COLUMN cv_accuracy REAL", "adding fits.cv_accuracy (schema 0 -> 1)");
}

constexpr MigrationStep kMigrations[] = {migrate0to1};
static_assert(static_cast<int>(std::size(kMigrations)) == BleStore::kSchemaVersion, "one migration step per schema version");

void setVersion(sqlite3* db, const std::string& path, int version) {
  // PRAGMAs take no bound parameters; both numbers are constants of this file.
  const std::string pragmas = "PRAGMA user_version = " + std::to_string(version) +
                              "; PRAGMA application_id = " + std::to_string(kApplicationId) + ";";
  sql::exec(db, path, pragmas, "setting the schema version");
}

std::vector<std::string> tableNames(sqlite3* db, const std::string& path) {
  sql::Statement s(db, path, "SELECT name FROM sqlite_master WHERE type = 'table' AND name NOT LIKE 'sqlite_%' ORDER BY name",
              "listing tables");
  std::vector<std::string> names;
  while (s.step()) names.push_back(s.text(0));
  return names;
}

std::string joined(const std::vector<std::string>& items) {
  std::string text;
  for (const auto& item : items) text += (text.empty() ? "" : ", ") + item;
  return text;
}

bool isLegacyLayout(const std::vector<std::string>& tables) {
  auto has = [&tables](const char* t) { return std::find(tables.begin(), tables.end(), t) != tables.end(); };
  return has("data_sets") && has("points") && has("fits");
}

// Refuses a file that is not a store this blt can read; true when it needs creating or migrating.
bool needsSchemaWork(sqlite3* db, const std::string& path) {
  const std::string notAStore = "an SQLite file written by blt (a BLE store), or the name of a new file";
  const int version = sql::pragmaInt(db, path, "user_version");
  const int appId = sql::pragmaInt(db, path, "application_id");
  if (appId != 0 && appId != kApplicationId)
    throw InputError(InputLocation::file(path), "is an SQLite database of another program, not a blt BLE store",
                     notAStore);
  if (version > BleStore::kSchemaVersion)
    throw InputError(InputLocation::file(path),
                     "was written by a newer blt (store schema version " + std::to_string(version) +
                         "; this blt reads versions up to " + std::to_string(BleStore::kSchemaVersion) + ")",
                     "upgrade blt to read it");
  if (version == BleStore::kSchemaVersion) {
    if (appId != kApplicationId)
      throw InputError(InputLocation::file(path), "is an SQLite database but not a blt BLE store", notAStore);
    return false;
  }
  if (version == 0) {
    const auto tables = tableNames(db, path);
    if (!tables.empty() && !(appId == 0 && isLegacyLayout(tables)))
      throw InputError(InputLocation::file(path),
                       "is an SQLite database but not a blt BLE store (its tables: " + joined(tables) + ")", notAStore);
  }
  return true;
}

// Brings the file to kSchemaVersion, or refuses it. Creating or migrating is one transaction, so a failed migration
// changes nothing; a file already at the current version is only read, so opening a store to read it takes no lock.
void prepareSchema(sqlite3* db, const std::string& path) {
  if (!needsSchemaWork(db, path)) return;
  sql::WriteTransaction tx(db, path);
  // Checked again under the write lock: another blt may have created or migrated the file meanwhile.
  if (!needsSchemaWork(db, path)) return;
  const int version = sql::pragmaInt(db, path, "user_version");
  if (version == 0 && tableNames(db, path).empty()) {
    sql::exec(db, path, kSchemaV1, "creating the store schema");
  } else {
    for (int v = version; v < BleStore::kSchemaVersion; ++v) kMigrations[v](db, path);
  }
  setVersion(db, path, BleStore::kSchemaVersion);
  tx.commit();
}

// ---- Values in and out -----------------------------------------------------------------------------------------

std::string methodKey(FitMethod m) {
  switch (m) {
    case FitMethod::TwoStage: return "two-stage";
    case FitMethod::Joint: return "joint";
    case FitMethod::Classify: return "classify";
  }
  return "two-stage";
}

FitMethod methodFromKey(const std::string& key, const InputLocation& where) {
  for (FitMethod m : {FitMethod::TwoStage, FitMethod::Joint, FitMethod::Classify})
    if (methodKey(m) == key) return m;
  throw InputError(where, "unknown fit method '" + key + "'", "two-stage, joint, classify");
}

// Little-endian bytes of the IEEE doubles, so a store moves between machines unchanged.
std::string encodeCovariance(const std::array<double, 64>& c) {
  std::string bytes(c.size() * 8, '\0');
  for (size_t i = 0; i < c.size(); ++i) {
    const auto bits = std::bit_cast<std::uint64_t>(c[i]);
    for (int b = 0; b < 8; ++b) bytes[i * 8 + b] = static_cast<char>((bits >> (8 * b)) & 0xFFu);
  }
  return bytes;
}

std::array<double, 64> decodeCovariance(const std::string& bytes, const InputLocation& where) {
  std::array<double, 64> c{};
  if (bytes.size() != c.size() * 8)
    throw InputError(where, "holds " + std::to_string(bytes.size()) + " bytes", "512 bytes (64 doubles)");
  for (size_t i = 0; i < c.size(); ++i) {
    std::uint64_t bits = 0;
    for (int b = 0; b < 8; ++b) bits |= std::uint64_t(static_cast<unsigned char>(bytes[i * 8 + b])) << (8 * b);
    c[i] = std::bit_cast<double>(bits);
  }
  return c;
}

// JSON has no inf or NaN; a bound may well be infinite, so non-finite numbers are written as strings.
nlohmann::json jsonNumber(double v) {
  if (std::isfinite(v)) return v;
  if (std::isnan(v)) return "nan";
  return v > 0 ? "inf" : "-inf";
}

double numberFromJson(const nlohmann::json& j, const InputLocation& where) {
  if (j.is_number()) return j.get<double>();
  if (j.is_string()) {
    const auto s = j.get<std::string>();
    if (s == "inf") return HUGE_VAL;
    if (s == "-inf") return -HUGE_VAL;
    if (s == "nan") return std::nan("");
  }
  throw InputError(where, "'" + j.dump() + "' is not a number", "a JSON number, \"inf\", \"-inf\" or \"nan\"");
}

nlohmann::json coefficientsJson(const ChristiansenCoefficients& c) {
  const auto values = c.toArray();
  nlohmann::json j = nlohmann::json::object();
  for (int i = 0; i < ChristiansenCoefficients::kCount; ++i) j[ChristiansenCoefficients::kNames[i]] = jsonNumber(values[i]);
  return j;
}

ChristiansenCoefficients coefficientsFromJson(const nlohmann::json& j, const ChristiansenCoefficients& fallback,
                                              const InputLocation& where) {
  auto values = fallback.toArray();
  for (int i = 0; i < ChristiansenCoefficients::kCount; ++i) {
    const char* key = ChristiansenCoefficients::kNames[i];
    if (j.contains(key)) values[i] = numberFromJson(j[key], where.withField(where.field + "." + key));
  }
  return ChristiansenCoefficients::fromArray(values.data());
}

// Everything in FitOptions, SI (the coefficients named as in ChristiansenCoefficients::kNames).
std::string optionsJson(const FitOptions& o) {
  nlohmann::json j;
  j["method"] = methodKey(o.method);
  j["default_projectile_density_kg_m3"] = jsonNumber(o.defaultProjectileDensity);
  j["bounds"] = {{"lower", coefficientsJson(o.bounds.lower)}, {"upper", coefficientsJson(o.bounds.upper)}};
  j["angle_exponent_start"] = nlohmann::json::array();
  for (double v : o.angleExponentStart) j["angle_exponent_start"].push_back(jsonNumber(v));
  j["cross_validation_folds"] = o.crossValidationFolds;
  j["global_evaluations"] = o.globalEvaluations;
  j["minimum_transition_width_m_s"] = jsonNumber(o.minimumTransitionWidth);
  j["wrong_side_weight"] = jsonNumber(o.wrongSideWeight);
  j["wrong_side_margin_m"] = jsonNumber(o.wrongSideMargin);
  return j.dump();
}

// A key that is absent takes the value that reproduces what the fit did before the option existed: the FitOptions
// default, except for the wrong-side hinge, which came later with a default that changes the fit; rows without it
// were plain least squares (weight 0, margin 0).
FitOptions optionsFromJson(const std::string& text, const InputLocation& where) {
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(text);
  } catch (const nlohmann::json::exception& e) {
    throw InputError(where, std::string("is not valid JSON: ") + e.what(), "the JSON object blt writes");
  }
  if (!j.is_object()) throw InputError(where, "is not a JSON object", "the JSON object blt writes");
  FitOptions o;
  auto at = [&where](const std::string& key) { return where.withField(where.field + "." + key); };
  try {
    if (j.contains("method")) o.method = methodFromKey(j["method"].get<std::string>(), at("method"));
    if (j.contains("default_projectile_density_kg_m3"))
      o.defaultProjectileDensity = numberFromJson(j["default_projectile_density_kg_m3"], at("default_projectile_density_kg_m3"));
    if (j.contains("bounds")) {
      const auto& b = j["bounds"];
      if (b.contains("lower")) o.bounds.lower = coefficientsFromJson(b["lower"], o.bounds.lower, at("bounds.lower"));
      if (b.contains("upper")) o.bounds.upper = coefficientsFromJson(b["upper"], o.bounds.upper, at("bounds.upper"));
    }
    if (j.contains("angle_exponent_start")) {
      const auto& a = j["angle_exponent_start"];
      if (!a.is_array() || a.size() != o.angleExponentStart.size())
        throw InputError(at("angle_exponent_start"), "'" + a.dump() + "' is not four numbers", "[S_L, S_H, X, X_H]");
      for (size_t i = 0; i < a.size(); ++i) o.angleExponentStart[i] = numberFromJson(a[i], at("angle_exponent_start"));
    }
    if (j.contains("cross_validation_folds")) o.crossValidationFolds = j["cross_validation_folds"].get<int>();
    if (j.contains("global_evaluations")) o.globalEvaluations = j["global_evaluations"].get<int>();
    if (j.contains("minimum_transition_width_m_s"))
      o.minimumTransitionWidth = numberFromJson(j["minimum_transition_width_m_s"], at("minimum_transition_width_m_s"));
    o.wrongSideWeight =
        j.contains("wrong_side_weight") ? numberFromJson(j["wrong_side_weight"], at("wrong_side_weight")) : 0.0;
    o.wrongSideMargin =
        j.contains("wrong_side_margin_m") ? numberFromJson(j["wrong_side_margin_m"], at("wrong_side_margin_m")) : 0.0;
  } catch (const nlohmann::json::exception& e) {
    throw InputError(where, std::string("has a value of the wrong type: ") + e.what(), "the JSON object blt writes");
  }
  return o;
}

// SQLite stores a NaN as NULL, so a NaN could not come back as itself; refuse it with a message that says where.
void requireNotNaN(double v, const std::string& path, const std::string& what) {
  if (std::isnan(v))
    throw InputError(InputLocation::file(path), what + " is NaN, which the store cannot keep", "a number (not NaN)");
}

std::string fitsPresent(sqlite3* db, const std::string& path) {
  sql::Statement s(db, path, "SELECT name FROM fits ORDER BY name", "listing fits");
  std::vector<std::string> names;
  while (s.step()) names.push_back(s.text(0));
  return names.empty() ? "none; the store holds no fits yet" : "one of: " + joined(names);
}

}  // namespace

// ---- BleStore --------------------------------------------------------------------------------------------------

BleStore::BleStore(const std::string& path) : path_(path) {
  const int rc = sqlite3_open_v2(path.c_str(), &db_, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE, nullptr);
  try {
    if (rc != SQLITE_OK)
      throw InputError(InputLocation::file(path), std::string("cannot open the BLE store: ") +
                                                      (db_ ? sqlite3_errmsg(db_) : sqlite3_errstr(rc)));
    sqlite3_extended_result_codes(db_, 1);
    // Another blt may be writing the same file; wait for it rather than failing at once.
    sqlite3_busy_timeout(db_, 5000);
    // A file that is not SQLite fails at its first read; say so plainly rather than with SQLite's wording alone.
    if (sqlite3_exec(db_, "SELECT count(*) FROM sqlite_master", nullptr, nullptr, nullptr) != SQLITE_OK)
      throw InputError(InputLocation::file(path),
                       std::string("is not a blt BLE store (SQLite: ") + sqlite3_errmsg(db_) + ")",
                       "an SQLite file written by blt (a BLE store), or the name of a new file");
    sql::exec(db_, path_, "PRAGMA foreign_keys = ON", "enabling foreign keys");
    prepareSchema(db_, path_);
  } catch (...) {
    sqlite3_close_v2(db_);
    db_ = nullptr;
    throw;
  }
}

BleStore::~BleStore() { sqlite3_close_v2(db_); }

int BleStore::schemaVersion() const { return sql::pragmaInt(db_, path_, "user_version"); }

bool BleStore::hasFit(const std::string& name) const {
  sql::Statement s(db_, path_, "SELECT 1 FROM fits WHERE name = ?1", "looking up a fit");
  s.bind(1, name);
  return s.step();
}

void BleStore::saveFit(const StoredFit& fit, bool replace) {
  if (fit.name.empty())
    throw InputError(InputLocation::file(path_, std::nullopt, "name"), "a fit needs a name", "a non-empty name");
  const std::string hash = hashPoints(fit.points);
  if (!fit.dataHash.empty() && fit.dataHash != hash)
    throw InputError(InputLocation::file(path_, std::nullopt, "data_hash"),
                     "fit '" + fit.name + "' carries data hash " + fit.dataHash + " but its points hash to " + hash,
                     "the hash of the fit's own points (or none)");
  const std::string created = fit.createdUtc.empty() ? nowUtcIso8601() : fit.createdUtc;

  sql::WriteTransaction tx(db_, path_);
  std::optional<std::int64_t> oldDataSet;
  {
    sql::Statement s(db_, path_, "SELECT data_set_id FROM fits WHERE name = ?1", "looking up a fit");
    s.bind(1, fit.name);
    if (s.step()) oldDataSet = s.integer(0);
  }
  if (oldDataSet) {
    if (!replace)
      throw InputError(InputLocation::file(path_), "fit '" + fit.name + "' exists; use --replace to overwrite");
    sql::Statement del(db_, path_, "DELETE FROM fits WHERE name = ?1", "removing the fit being replaced");
    del.bind(1, fit.name).run();
    sql::Statement orphan(db_, path_,
                     "DELETE FROM data_sets WHERE id = ?1 AND NOT EXISTS (SELECT 1 FROM fits WHERE data_set_id = ?1)",
                     "removing the replaced fit's data set");
    orphan.bind(1, *oldDataSet).run();  // its points go with it (ON DELETE CASCADE)
  }

  std::int64_t dataSetId = 0;
  {
    sql::Statement s(db_, path_,
                "INSERT INTO data_sets (origin, hash, point_count, created_utc) VALUES (?1, ?2, ?3, ?4)",
                "saving the data set");
    s.bind(1, fit.dataOrigin).bind(2, hash).bind(3, static_cast<std::int64_t>(fit.points.size())).bind(4, created).run();
    dataSetId = sqlite3_last_insert_rowid(db_);
  }
  {
    sql::Statement s(db_, path_,
                "INSERT INTO points (data_set_id, idx, diameter_m, velocity_m_s, angle_rad, perforated, "
                "projectile_density_kg_m3, source, origin) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9)",
                "saving the points");
    for (size_t i = 0; i < fit.points.size(); ++i) {
      const ImpactPoint& p = fit.points[i];
      const std::string which = "fit '" + fit.name + "', point " + std::to_string(i + 1) + " (" + p.origin + "): ";
      requireNotNaN(p.diameter, path_, which + "diameter");
      requireNotNaN(p.velocity, path_, which + "velocity");
      requireNotNaN(p.angle, path_, which + "angle");
      requireNotNaN(p.projectileDensity, path_, which + "projectile density");
      s.reset();
      s.bind(1, dataSetId).bind(2, static_cast<std::int64_t>(i)).bind(3, p.diameter).bind(4, p.velocity);
      s.bind(5, p.angle).bind(6, p.perforated).bind(7, p.projectileDensity).bind(8, p.source).bind(9, p.origin);
      s.run();
    }
  }

  const FitResult& r = fit.result;
  const auto c = r.coefficients.toArray();
  for (int i = 0; i < ChristiansenCoefficients::kCount; ++i)
    requireNotNaN(c[i], path_, "fit '" + fit.name + "': coefficient " + ChristiansenCoefficients::kNames[i]);
  requireNotNaN(r.scatter, path_, "fit '" + fit.name + "': scatter");
  requireNotNaN(r.meanSquareError, path_, "fit '" + fit.name + "': mean square error");
  if (r.crossValidatedAccuracy) requireNotNaN(*r.crossValidatedAccuracy, path_, "fit '" + fit.name + "': cv accuracy");
  sql::Statement s(db_, path_,
              "INSERT INTO fits (name, family, method, data_set_id, vl_m_s, vh_m_s, cl, ch, sl, sh, x, xh, covariance, "
              "covariance_available, covariance_note, scatter, mse_m2, misclassified, point_count, cv_accuracy, "
              "options, data_hash, tool_version, created_utc) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, "
              "?12, ?13, ?14, ?15, ?16, ?17, ?18, ?19, ?20, ?21, ?22, ?23, ?24)",
              "saving the fit");
  s.bind(1, fit.name).bind(2, fit.family).bind(3, methodKey(r.method)).bind(4, dataSetId);
  for (int i = 0; i < ChristiansenCoefficients::kCount; ++i) s.bind(5 + i, c[i]);
  s.bindBlob(13, encodeCovariance(r.covariance)).bind(14, r.covarianceAvailable).bind(15, r.covarianceNote);
  s.bind(16, r.scatter).bind(17, r.meanSquareError).bind(18, r.misclassified).bind(19, r.pointCount);
  s.bind(20, r.crossValidatedAccuracy).bind(21, optionsJson(fit.options)).bind(22, hash);
  s.bind(23, fit.toolVersion).bind(24, created);
  s.run();
  tx.commit();
}

StoredFit BleStore::loadFit(const std::string& name) const {
  sql::Statement s(db_, path_,
              "SELECT f.family, f.method, f.vl_m_s, f.vh_m_s, f.cl, f.ch, f.sl, f.sh, f.x, f.xh, f.covariance, "
              "f.covariance_available, f.covariance_note, f.scatter, f.mse_m2, f.misclassified, f.point_count, "
              "f.cv_accuracy, f.options, f.data_hash, f.tool_version, f.created_utc, d.origin, d.id "
              "FROM fits f JOIN data_sets d ON d.id = f.data_set_id WHERE f.name = ?1",
              "loading a fit");
  s.bind(1, name);
  if (!s.step())
    throw InputError(InputLocation::file(path_), "there is no fit named '" + name + "'", fitsPresent(db_, path_));

  const auto where = [this, &name](const std::string& column) {
    return InputLocation::file(path_, std::nullopt, "fit '" + name + "' " + column);
  };
  StoredFit fit;
  fit.name = name;
  fit.family = s.text(0);
  FitResult& r = fit.result;
  r.method = methodFromKey(s.text(1), where("method"));
  double c[ChristiansenCoefficients::kCount];
  for (int i = 0; i < ChristiansenCoefficients::kCount; ++i) c[i] = s.real(2 + i);
  r.coefficients = ChristiansenCoefficients::fromArray(c);
  r.covariance = decodeCovariance(s.blob(10), where("covariance"));
  r.covarianceAvailable = s.integer(11) != 0;
  r.covarianceNote = s.text(12);
  r.scatter = s.real(13);
  r.meanSquareError = s.real(14);
  r.misclassified = static_cast<int>(s.integer(15));
  r.pointCount = static_cast<int>(s.integer(16));
  if (!s.isNull(17)) r.crossValidatedAccuracy = s.real(17);
  fit.options = optionsFromJson(s.text(18), where("options"));
  fit.dataHash = s.text(19);
  fit.toolVersion = s.text(20);
  fit.createdUtc = s.text(21);
  fit.dataOrigin = s.text(22);
  const std::int64_t dataSetId = s.integer(23);

  sql::Statement p(db_, path_,
              "SELECT diameter_m, velocity_m_s, angle_rad, perforated, projectile_density_kg_m3, source, origin "
              "FROM points WHERE data_set_id = ?1 ORDER BY idx",
              "loading the fit's points");
  p.bind(1, dataSetId);
  while (p.step()) {
    ImpactPoint pt;
    pt.diameter = p.real(0);
    pt.velocity = p.real(1);
    pt.angle = p.real(2);
    pt.perforated = p.integer(3) != 0;
    pt.projectileDensity = p.real(4);
    pt.source = p.text(5);
    pt.origin = p.text(6);
    fit.points.push_back(std::move(pt));
  }
  return fit;
}

std::vector<FitSummary> BleStore::listFits() const {
  sql::Statement s(db_, path_,
              "SELECT name, family, method, created_utc, data_hash, point_count, mse_m2, misclassified "
              "FROM fits ORDER BY name",
              "listing fits");
  std::vector<FitSummary> fits;
  while (s.step()) {
    FitSummary f;
    f.name = s.text(0);
    f.family = s.text(1);
    f.method = s.text(2);
    f.createdUtc = s.text(3);
    f.dataHash = s.text(4);
    f.pointCount = static_cast<int>(s.integer(5));
    f.meanSquareError = s.real(6);
    f.misclassified = static_cast<int>(s.integer(7));
    fits.push_back(std::move(f));
  }
  return fits;
}

// ---- Fingerprint -----------------------------------------------------------------------------------------------

// FNV-1a (64 bit) over a canonical text: a version tag, the point count, then per point its diameter, velocity,
// angle and density (17 significant digits as with %.17g, but locale-free, so any two doubles differ), its outcome
// and its length-prefixed source label. The origin (file and line it was read from) is left out, so the same data
// read from a copied or moved file hash the same.
StoredFit storedFit(std::string name, const FitOptions& options, FitResult result, std::vector<ImpactPoint> points,
                    std::string dataOrigin) {
  StoredFit stored;
  stored.name = std::move(name);
  stored.options = options;
  stored.result = std::move(result);
  stored.dataHash = hashPoints(points);
  stored.points = std::move(points);
  stored.dataOrigin = std::move(dataOrigin);
  stored.toolVersion = BLT_VERSION;
  return stored;
}

std::string hashPoints(const std::vector<ImpactPoint>& points) {
  std::uint64_t h = 0xcbf29ce484222325ull;
  auto feed = [&h](std::string_view text) {
    for (unsigned char ch : text) {
      h ^= ch;
      h *= 0x100000001b3ull;
    }
  };
  auto feedNumber = [&feed](double v) {
    char buf[40];
    const auto res = std::to_chars(buf, buf + sizeof buf, v, std::chars_format::general, 17);
    feed(std::string_view(buf, static_cast<size_t>(res.ptr - buf)));
    feed(",");
  };
  feed("blt-impact-points-v1\n");
  feed(std::to_string(points.size()) + "\n");
  for (const auto& p : points) {
    feedNumber(p.diameter);
    feedNumber(p.velocity);
    feedNumber(p.angle);
    feedNumber(p.projectileDensity);
    feed(p.perforated ? "Y," : "N,");
    feed(std::to_string(p.source.size()) + ":" + p.source + "\n");
  }
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(h));
  return hex;
}

}  // namespace blt::ble
