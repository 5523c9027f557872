// The SQLite BLE store: schema versions and migration, exact round trips, replace rules, failures that leave the
// file as it was, and the data fingerprint. The fits here are built by hand (no fitting is run): the store must
// keep whatever it is given, so the comparisons are against the values put in, bit for bit.
#include <doctest/doctest.h>
#include <unistd.h>

#include <bit>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <limits>
#include <numbers>
#include <sstream>

#include "blt/ble/store.hpp"
#include "blt/core/error.hpp"
#include "raw_db.hpp"

using namespace blt;
using ble::BleStore;
using ble::StoredFit;

namespace {

// A fresh path in the temp directory (any old file of that name, and SQLite's side files, removed). The process id
// keeps two test runs at once (two build directories) off each other's files.
std::string freshPath(const std::string& name) {
  const auto path = (std::filesystem::temp_directory_path() /
                     ("blt_store_test_" + std::to_string(::getpid()) + "_" + name)).string();
  for (const char* suffix : {"", "-journal", "-wal", "-shm"}) std::filesystem::remove(path + suffix);
  return path;
}

// doctest::Contains takes doctest's own String.
doctest::Contains contains(const std::string& text) { return doctest::Contains(text.c_str()); }

// True when every character of text matches the pattern: 'd' a digit, 'x' a lower-case hex digit, else itself.
bool matchesShape(const std::string& text, const std::string& shape) {
  if (text.size() != shape.size()) return false;
  for (size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    const bool digit = c >= '0' && c <= '9';
    if (shape[i] == 'd' ? !digit : shape[i] == 'x' ? !(digit || (c >= 'a' && c <= 'f')) : c != shape[i]) return false;
  }
  return true;
}

bool sameBits(double a, double b) { return std::bit_cast<std::uint64_t>(a) == std::bit_cast<std::uint64_t>(b); }

ble::ImpactPoint point(double dMm, double vKmS, double angleDeg, bool perforated, double density, std::string source,
                       std::string origin) {
  ble::ImpactPoint p;
  p.diameter = dMm * 1e-3;
  p.velocity = vKmS * 1e3;
  p.angle = angleDeg * std::numbers::pi / 180.0;
  p.perforated = perforated;
  p.projectileDensity = density;
  p.source = std::move(source);
  p.origin = std::move(origin);
  return p;
}

// A fit with a value in every field that differs from its default, and doubles that have no short decimal form.
StoredFit handMadeFit(const std::string& name) {
  StoredFit f;
  f.name = name;
  f.family = "christiansen";
  f.options.method = ble::FitMethod::Classify;
  f.options.defaultProjectileDensity = 2796.5;
  f.options.bounds.lower.VL = 1234.5;
  f.options.bounds.lower.SL = -1.0 / 3.0;
  f.options.bounds.upper.CH = std::numeric_limits<double>::infinity();  // written to JSON as "inf"
  f.options.bounds.upper.XH = std::nextafter(3.0, 4.0);
  f.options.angleExponentStart = {0.1, 0.2, 1.0 / 3.0, 0.7};
  f.options.crossValidationFolds = 5;
  f.options.globalEvaluations = 1234;
  f.options.minimumTransitionWidth = 250.0 + 1.0 / 3.0;
  f.options.wrongSideWeight = std::nextafter(10.0, 11.0);
  f.options.wrongSideMargin = 0.02e-3 / 3.0;
  f.result.method = ble::FitMethod::Classify;
  f.result.coefficients = {std::nextafter(5100.0, 9e9), 6950.0 + 1.0 / 7.0, 2.0 / 3.0 * 1e-3, 0.1 + 0.2,
                           0.132,  0.45 / 7.0, std::sqrt(2.0) / 2.0, -0.0125 / 3.0};
  for (int i = 0; i < 64; ++i) f.result.covariance[i] = (i % 3 == 0 ? -1.0 : 1.0) * (i + 1) / 7.0 * 1e-9;
  // The BLOB keeps what REAL columns cannot: the sign of zero, NaN, a subnormal.
  f.result.covariance[61] = -0.0;
  f.result.covariance[62] = std::numeric_limits<double>::quiet_NaN();
  f.result.covariance[63] = std::numeric_limits<double>::denorm_min();
  f.result.covarianceAvailable = true;
  f.result.covarianceNote = "stage 2 block only; \"quoted\", comma, ünïcode";
  f.result.scatter = 0.123456789012345678;
  f.result.meanSquareError = 1.461e-8 / 3.0;
  f.result.misclassified = 3;
  f.result.pointCount = 4;
  f.result.crossValidatedAccuracy = 0.8125 + 1e-17;
  f.points = {point(1.0, 2.51, 0, false, 0, "seed000 Table 1, test 01", "table1.csv:2"),
              point(1.4, 3.02, 0, true, 0, "test \"03\"", "table1.csv:4"),
              point(2.0 / 3.0, 6.5, 45, true, 2796.5, "", "table7.csv:9"),
              point(1.1, 7.0 + 1e-12, 60, false, 2700.0, "mpm ü", "table7.csv:10")};
  f.dataOrigin = "data/seed/seed000_table1_tests.csv + data/seed/seed000_table7_mpm.csv (angle_deg=45)";
  f.dataHash = ble::hashPoints(f.points);
  f.toolVersion = "0.1.0-test";
  f.createdUtc = "2024-02-29T23:59:59Z";
  return f;
}

void checkSameFit(const StoredFit& a, const StoredFit& b) {
  CHECK(a.name == b.name);
  CHECK(a.family == b.family);
  CHECK((a.options.method == b.options.method));  // (FitMethod has no doctest printer)
  CHECK(sameBits(a.options.defaultProjectileDensity, b.options.defaultProjectileDensity));
  for (int i = 0; i < ble::ChristiansenCoefficients::kCount; ++i) {
    CAPTURE(i);
    CHECK(sameBits(a.options.bounds.lower.toArray()[i], b.options.bounds.lower.toArray()[i]));
    CHECK(sameBits(a.options.bounds.upper.toArray()[i], b.options.bounds.upper.toArray()[i]));
    CHECK(sameBits(a.result.coefficients.toArray()[i], b.result.coefficients.toArray()[i]));
  }
  for (int i = 0; i < 4; ++i) CHECK(sameBits(a.options.angleExponentStart[i], b.options.angleExponentStart[i]));
  CHECK(a.options.crossValidationFolds == b.options.crossValidationFolds);
  CHECK(a.options.globalEvaluations == b.options.globalEvaluations);
  CHECK(sameBits(a.options.minimumTransitionWidth, b.options.minimumTransitionWidth));
  CHECK(sameBits(a.options.wrongSideWeight, b.options.wrongSideWeight));
  CHECK(sameBits(a.options.wrongSideMargin, b.options.wrongSideMargin));
  CHECK((a.result.method == b.result.method));
  for (int i = 0; i < 64; ++i) {
    CAPTURE(i);
    CHECK(sameBits(a.result.covariance[i], b.result.covariance[i]));
  }
  CHECK(a.result.covarianceAvailable == b.result.covarianceAvailable);
  CHECK(a.result.covarianceNote == b.result.covarianceNote);
  CHECK(sameBits(a.result.scatter, b.result.scatter));
  CHECK(sameBits(a.result.meanSquareError, b.result.meanSquareError));
  CHECK(a.result.misclassified == b.result.misclassified);
  CHECK(a.result.pointCount == b.result.pointCount);
  REQUIRE(a.result.crossValidatedAccuracy.has_value() == b.result.crossValidatedAccuracy.has_value());
  if (a.result.crossValidatedAccuracy)
    CHECK(sameBits(*a.result.crossValidatedAccuracy, *b.result.crossValidatedAccuracy));
  REQUIRE(a.points.size() == b.points.size());
  for (size_t i = 0; i < a.points.size(); ++i) {
    CAPTURE(i);
    CHECK(sameBits(a.points[i].diameter, b.points[i].diameter));
    CHECK(sameBits(a.points[i].velocity, b.points[i].velocity));
    CHECK(sameBits(a.points[i].angle, b.points[i].angle));
    CHECK(a.points[i].perforated == b.points[i].perforated);
    CHECK(sameBits(a.points[i].projectileDensity, b.points[i].projectileDensity));
    CHECK(a.points[i].source == b.points[i].source);
    CHECK(a.points[i].origin == b.points[i].origin);
  }
  CHECK(a.dataOrigin == b.dataOrigin);
  CHECK(a.dataHash == b.dataHash);
  CHECK(a.toolVersion == b.toolVersion);
  CHECK(a.createdUtc == b.createdUtc);
}

std::string fileText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

}  // namespace

TEST_CASE("ble store: a new file gets the current schema version and a blt application id") {
  const auto path = freshPath("new.db");
  {
    BleStore store(path);
    CHECK(store.schemaVersion() == BleStore::kSchemaVersion);
    CHECK(store.listFits().empty());
    CHECK_FALSE(store.hasFit("anything"));
  }
  RawDb raw(path);
  CHECK(raw.integer("PRAGMA user_version") == BleStore::kSchemaVersion);
  CHECK(raw.integer("PRAGMA application_id") == 0x424C5442);
  CHECK(raw.integer("SELECT count(*) FROM sqlite_master WHERE type = 'table' AND name IN ('data_sets', 'points', 'fits')") == 3);
}

TEST_CASE("ble store: a fit comes back exactly as saved, after the file is closed and reopened") {
  const auto path = freshPath("roundtrip.db");
  const StoredFit saved = handMadeFit("whipple-classify");
  StoredFit noCv = handMadeFit("eq11-joint");
  noCv.result.crossValidatedAccuracy.reset();
  noCv.result.method = ble::FitMethod::Joint;
  noCv.options.method = ble::FitMethod::Joint;
  noCv.result.covarianceAvailable = false;
  {
    BleStore store(path);
    store.saveFit(saved, false);
    store.saveFit(noCv, false);
  }
  BleStore store(path);
  REQUIRE(store.hasFit("whipple-classify"));
  checkSameFit(store.loadFit("whipple-classify"), saved);
  const StoredFit loadedNoCv = store.loadFit("eq11-joint");
  CHECK_FALSE(loadedNoCv.result.crossValidatedAccuracy.has_value());
  checkSameFit(loadedNoCv, noCv);
  // The absent accuracy is NULL in the file, not 0.
  RawDb raw(path);
  CHECK(raw.integer("SELECT count(*) FROM fits WHERE cv_accuracy IS NULL") == 1);
  // The options JSON names the transition width and the hinge with their SI units.
  CHECK(raw.integer("SELECT count(*) FROM fits WHERE json_extract(options, '$.minimum_transition_width_m_s') > 250.33 "
                    "AND json_extract(options, '$.wrong_side_weight') > 10 "
                    "AND json_extract(options, '$.wrong_side_margin_m') BETWEEN 6.6e-6 AND 6.7e-6") == 2);
}

TEST_CASE("ble store: listFits gives summaries ordered by name, saveFit sets the time when none is given") {
  const auto path = freshPath("list.db");
  BleStore store(path);
  StoredFit b = handMadeFit("bravo");
  StoredFit a = handMadeFit("Alpha");
  a.createdUtc.clear();
  a.result.misclassified = 7;
  a.points.pop_back();
  a.dataHash.clear();  // saveFit computes it
  store.saveFit(b, false);
  store.saveFit(a, false);
  const auto list = store.listFits();
  REQUIRE(list.size() == 2);
  CHECK(list[0].name == "Alpha");  // SQLite's default (binary) order: upper case first
  CHECK(list[1].name == "bravo");
  CHECK(list[0].misclassified == 7);
  CHECK(list[0].method == "classify");
  CHECK(list[0].family == "christiansen");
  CHECK(list[0].dataHash == ble::hashPoints(a.points));
  CHECK(list[1].dataHash == b.dataHash);
  CHECK(list[1].pointCount == b.result.pointCount);
  CHECK(sameBits(list[1].meanSquareError, b.result.meanSquareError));
  CHECK(list[1].createdUtc == "2024-02-29T23:59:59Z");
  CHECK(matchesShape(list[0].createdUtc, "dddd-dd-ddTdd:dd:ddZ"));
}

TEST_CASE("ble store: an existing name needs replace, replacing drops the old data set") {
  const auto path = freshPath("replace.db");
  BleStore store(path);
  const StoredFit first = handMadeFit("fit-a");
  store.saveFit(first, false);
  StoredFit second = handMadeFit("fit-a");
  second.points.resize(2);
  second.dataHash = ble::hashPoints(second.points);
  second.result.scatter = 0.5;
  CHECK_THROWS_WITH_AS(store.saveFit(second, false),
                       contains("file " + path + ": fit 'fit-a' exists; use --replace to overwrite"),
                       InputError);
  checkSameFit(store.loadFit("fit-a"), first);

  store.saveFit(second, true);
  checkSameFit(store.loadFit("fit-a"), second);
  CHECK(store.listFits().size() == 1);
  RawDb raw(path);
  CHECK(raw.integer("SELECT count(*) FROM data_sets") == 1);
  CHECK(raw.integer("SELECT count(*) FROM points") == 2);
}

TEST_CASE("ble store: an unknown fit name lists the names present") {
  const auto path = freshPath("unknown.db");
  BleStore store(path);
  CHECK_THROWS_WITH_AS(store.loadFit("nope"),
                       contains("file " + path + ": there is no fit named 'nope' (allowed: none; the store holds no fits yet)"),
                       InputError);
  store.saveFit(handMadeFit("zeta"), false);
  store.saveFit(handMadeFit("beta"), false);
  CHECK_THROWS_WITH_AS(store.loadFit("alpha"),
                       doctest::Contains("there is no fit named 'alpha' (allowed: one of: beta, zeta)"), InputError);
}

TEST_CASE("ble store: a save that fails midway leaves the file as it was") {
  const auto path = freshPath("rollback.db");
  BleStore store(path);
  const StoredFit kept = handMadeFit("kept");
  store.saveFit(kept, false);
  store.saveFit(handMadeFit("other"), false);
  const auto before = store.listFits();

  // Replacing 'kept' with data whose third point is NaN: the old fit and its data set are deleted and two points
  // written before the NaN is met, so only a rollback can bring them back.
  StoredFit bad = handMadeFit("kept");
  bad.points[2].velocity = std::numeric_limits<double>::quiet_NaN();
  bad.dataHash.clear();
  CHECK_THROWS_WITH_AS(store.saveFit(bad, true),
                       doctest::Contains("fit 'kept', point 3 (table7.csv:9): velocity is NaN"), InputError);
  // A new name that fails on a NaN coefficient, after its data set and points are in.
  StoredFit badCoefficient = handMadeFit("new");
  badCoefficient.result.coefficients.CH = std::nan("");
  CHECK_THROWS_WITH_AS(store.saveFit(badCoefficient, false),
                       doctest::Contains("fit 'new': coefficient CH is NaN"), InputError);

  const auto after = store.listFits();
  REQUIRE(after.size() == before.size());
  for (size_t i = 0; i < after.size(); ++i) {
    CHECK(after[i].name == before[i].name);
    CHECK(after[i].dataHash == before[i].dataHash);
  }
  checkSameFit(store.loadFit("kept"), kept);
  RawDb raw(path);
  CHECK(raw.integer("SELECT count(*) FROM data_sets") == 2);
  CHECK(raw.integer("SELECT count(*) FROM points") == 2 * static_cast<std::int64_t>(kept.points.size()));
  // The store still takes writes: the failed transactions were closed.
  store.saveFit(handMadeFit("third"), false);
  CHECK(store.listFits().size() == 3);
}

TEST_CASE("ble store: a hash that does not belong to the points is refused") {
  const auto path = freshPath("hash.db");
  BleStore store(path);
  StoredFit f = handMadeFit("h");
  f.dataHash = "0123456789abcdef";
  CHECK_THROWS_WITH_AS(store.saveFit(f, false),
                       contains("field 'data_hash': fit 'h' carries data hash 0123456789abcdef but its points hash to " +
                                         ble::hashPoints(f.points)),
                       InputError);
  CHECK(store.listFits().empty());
}

TEST_CASE("ble store: a file written by a newer blt is refused") {
  const auto path = freshPath("newer.db");
  {
    BleStore store(path);
    store.saveFit(handMadeFit("x"), false);
  }
  RawDb(path).exec("PRAGMA user_version = " + std::to_string(BleStore::kSchemaVersion + 1));
  CHECK_THROWS_WITH_AS(BleStore{path},
                       contains("file " + path + ": was written by a newer blt (store schema version " +
                                         std::to_string(BleStore::kSchemaVersion + 1) + "; this blt reads versions up to " +
                                         std::to_string(BleStore::kSchemaVersion) + ") (allowed: upgrade blt to read it)"),
                       InputError);
  CHECK(RawDb(path).integer("SELECT count(*) FROM fits") == 1);  // refused, not touched
}

TEST_CASE("ble store: a file that is not a blt store is refused, naming it, and left alone") {
  SUBCASE("a text file") {
    const auto path = freshPath("not_sqlite.csv");
    const std::string text = "diameter_mm,velocity_km_s,angle_deg,perforated\n1.0,3.0,0,1\n";
    std::ofstream(path) << text;
    CHECK_THROWS_WITH_AS(BleStore{path}, contains("file " + path + ": is not a blt BLE store (SQLite: file is not a database)"),
                         InputError);
    CHECK(fileText(path) == text);
  }
  SUBCASE("an SQLite file of something else") {
    const auto path = freshPath("other_app.db");
    RawDb(path).exec("CREATE TABLE customers (id INTEGER, name TEXT); CREATE TABLE orders (id INTEGER)");
    CHECK_THROWS_WITH_AS(BleStore{path},
                         doctest::Contains("is an SQLite database but not a blt BLE store (its tables: customers, orders)"),
                         InputError);
    CHECK(RawDb(path).integer("PRAGMA user_version") == 0);
  }
  SUBCASE("an SQLite file with another program's application id") {
    const auto path = freshPath("other_id.db");
    RawDb(path).exec("PRAGMA application_id = 1234; CREATE TABLE t (x)");
    CHECK_THROWS_WITH_AS(BleStore{path}, doctest::Contains("is an SQLite database of another program"), InputError);
  }
  SUBCASE("a directory that does not exist") {
    const auto path = freshPath("no_such_dir") + "/store.db";
    CHECK_THROWS_WITH_AS(BleStore{path}, contains("file " + path + ": cannot open the BLE store"), InputError);
  }
}

TEST_CASE("ble store: a pre-release (schema 0) store is migrated and keeps its fits") {
  // The layout blt wrote before the store was versioned: version 1 without fits.cv_accuracy, no application id.
  // Written here from its own DDL, so the test does not share the store's code for it.
  const auto path = freshPath("legacy_v0.db");
  {
    RawDb raw(path);
    raw.exec(R"sql(
      CREATE TABLE data_sets (id INTEGER PRIMARY KEY, origin TEXT NOT NULL, hash TEXT NOT NULL,
        point_count INTEGER NOT NULL, created_utc TEXT NOT NULL);
      CREATE TABLE points (data_set_id INTEGER NOT NULL REFERENCES data_sets(id) ON DELETE CASCADE,
        idx INTEGER NOT NULL, diameter_m REAL NOT NULL, velocity_m_s REAL NOT NULL, angle_rad REAL NOT NULL,
        perforated INTEGER NOT NULL, projectile_density_kg_m3 REAL NOT NULL, source TEXT NOT NULL,
        origin TEXT NOT NULL, PRIMARY KEY (data_set_id, idx));
      CREATE TABLE fits (id INTEGER PRIMARY KEY, name TEXT NOT NULL UNIQUE, family TEXT NOT NULL,
        method TEXT NOT NULL, data_set_id INTEGER NOT NULL REFERENCES data_sets(id),
        vl_m_s REAL NOT NULL, vh_m_s REAL NOT NULL, cl REAL NOT NULL, ch REAL NOT NULL, sl REAL NOT NULL,
        sh REAL NOT NULL, x REAL NOT NULL, xh REAL NOT NULL, covariance BLOB NOT NULL,
        covariance_available INTEGER NOT NULL, covariance_note TEXT NOT NULL, scatter REAL NOT NULL,
        mse_m2 REAL NOT NULL, misclassified INTEGER NOT NULL, point_count INTEGER NOT NULL,
        options TEXT NOT NULL, data_hash TEXT NOT NULL, tool_version TEXT NOT NULL, created_utc TEXT NOT NULL);
      INSERT INTO data_sets VALUES (1, 'old.csv', 'feedbeef', 2, '2023-01-01T00:00:00Z');
      INSERT INTO points VALUES (1, 0, 0.001, 2510.0, 0.0, 0, 2796.0, 'T1-01', 'old.csv:2');
      INSERT INTO points VALUES (1, 1, 0.0014, 3020.0, 0.0, 1, 2796.0, 'T1-03', 'old.csv:4');
      INSERT INTO fits VALUES (1, 'legacy', 'christiansen', 'joint', 1, 5100.0, 6950.0, 0.0025, 0.0045,
        0.132, 0.45, 0.5, 0.45, zeroblob(512), 0, 'not computed', 0.0, 1.5e-8, 1, 2,
        '{"method":"joint","default_projectile_density_kg_m3":2796.0,"cross_validation_folds":0,"global_evaluations":100}',
        'feedbeef', '0.0.9', '2023-01-01T00:00:00Z');
    )sql");
    CHECK(raw.integer("PRAGMA user_version") == 0);
  }
  {
    BleStore store(path);
    CHECK(store.schemaVersion() == BleStore::kSchemaVersion);
    const StoredFit f = store.loadFit("legacy");
    CHECK((f.result.method == ble::FitMethod::Joint));
    CHECK(f.result.coefficients.VL == 5100.0);
    CHECK(f.result.coefficients.CH == 0.0045);
    CHECK(f.result.meanSquareError == 1.5e-8);
    CHECK_FALSE(f.result.crossValidatedAccuracy.has_value());
    CHECK(f.result.covariance[0] == 0.0);
    CHECK(f.options.defaultProjectileDensity == 2796.0);
    CHECK(f.options.globalEvaluations == 100);
    // Keys the old JSON lacks keep FitOptions' defaults, except the wrong-side hinge: it came later with a default
    // that changes the fit, and a row without it was fitted by plain least squares.
    const ble::FitOptions defaults;
    CHECK(f.options.angleExponentStart == defaults.angleExponentStart);
    CHECK(f.options.bounds.upper.VH == defaults.bounds.upper.VH);
    CHECK(f.options.minimumTransitionWidth == defaults.minimumTransitionWidth);
    CHECK(defaults.wrongSideWeight != 0.0);
    CHECK(f.options.wrongSideWeight == 0.0);
    CHECK(f.options.wrongSideMargin == 0.0);
    REQUIRE(f.points.size() == 2);
    CHECK(f.points[1].diameter == 0.0014);
    CHECK(f.points[1].perforated);
    CHECK(f.points[1].source == "T1-03");
    CHECK(f.dataHash == "feedbeef");
    // The migrated file takes a fit with the new column.
    store.saveFit(handMadeFit("new"), false);
    checkSameFit(store.loadFit("new"), handMadeFit("new"));
  }
  RawDb raw(path);
  CHECK(raw.integer("PRAGMA user_version") == BleStore::kSchemaVersion);
  CHECK(raw.integer("PRAGMA application_id") == 0x424C5442);
  CHECK(raw.integer("SELECT count(*) FROM pragma_table_info('fits') WHERE name = 'cv_accuracy'") == 1);
}

TEST_CASE("ble store: hashPoints tells any change of data apart, and not a change of file") {
  const StoredFit f = handMadeFit("h");
  const auto& pts = f.points;
  const std::string h = ble::hashPoints(pts);
  CHECK(matchesShape(h, std::string(16, 'x')));
  CHECK(ble::hashPoints(pts) == h);
  CHECK(ble::hashPoints(std::vector<ble::ImpactPoint>(pts)) == h);  // a copy, same values

  auto changed = [&pts](auto edit) {
    auto copy = pts;
    edit(copy[1]);
    return ble::hashPoints(copy);
  };
  // One ulp is enough: 17 significant digits tell every double apart.
  CHECK(changed([](ble::ImpactPoint& p) { p.diameter = std::nextafter(p.diameter, 1.0); }) != h);
  CHECK(changed([](ble::ImpactPoint& p) { p.velocity = std::nextafter(p.velocity, 0.0); }) != h);
  CHECK(changed([](ble::ImpactPoint& p) { p.angle = 1e-300; }) != h);
  CHECK(changed([](ble::ImpactPoint& p) { p.projectileDensity = 2700.0; }) != h);
  CHECK(changed([](ble::ImpactPoint& p) { p.perforated = !p.perforated; }) != h);
  CHECK(changed([](ble::ImpactPoint& p) { p.source += "x"; }) != h);
  // Where a point was read from is provenance, not data.
  CHECK(changed([](ble::ImpactPoint& p) { p.origin = "moved/elsewhere.csv:99"; }) == h);

  auto swapped = pts;
  std::swap(swapped[0], swapped[1]);
  CHECK(ble::hashPoints(swapped) != h);
  auto shorter = pts;
  shorter.pop_back();
  CHECK(ble::hashPoints(shorter) != h);
  CHECK(ble::hashPoints({}) != h);
  // The label is length-prefixed, so text cannot slide from one point's label into the next point's fields.
  auto a = pts, b = pts;
  a[0].source = "ab";
  a[1].source = "c";
  b[0].source = "a";
  b[1].source = "bc";
  CHECK(ble::hashPoints(a) != ble::hashPoints(b));
}
