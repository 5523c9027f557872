// The run database on SQLite. Values go in through bound parameters only; the SQL text built here is the
// schema and PRAGMAs with constants of this file.
#include "blt/campaign/database.hpp"

#include <chrono>
#include <cmath>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <map>

#include "blt/core/clock.hpp"
#include "blt/core/units.hpp"
#include "blt/core/sqlite.hpp"

namespace blt::campaign {

namespace {

// PRAGMA application_id of a run database ("BLTC"), so that a BLE store or another program's file is refused.
constexpr int kApplicationId = 0x424C5443;
// A writer waits this long for another (thread or process) to finish its transaction; a run takes seconds to
// hours, a write milliseconds, so only a stuck process reaches it.
constexpr int kBusyTimeoutMs = 120000;

constexpr const char* kSchemaV1 = R"sql(
CREATE TABLE campaigns (
  id INTEGER PRIMARY KEY,
  name TEXT NOT NULL UNIQUE,
  definition TEXT NOT NULL,
  definition_hash TEXT NOT NULL,
  variable TEXT NOT NULL CHECK (variable IN ('diameter', 'velocity')),
  projectile_density_kg_m3 REAL NOT NULL,
  task_index INTEGER NOT NULL,
  task_count INTEGER NOT NULL,
  created_utc TEXT NOT NULL
);
CREATE TABLE points (
  campaign_id INTEGER NOT NULL REFERENCES campaigns(id),
  idx INTEGER NOT NULL,
  label TEXT NOT NULL,
  velocity_m_s REAL NOT NULL,
  diameter_m REAL NOT NULL,
  angle_rad REAL NOT NULL,
  bracket_lower REAL NOT NULL,
  bracket_upper REAL NOT NULL,
  bracket_origin TEXT NOT NULL,
  state TEXT NOT NULL CHECK (state IN ('pending', 'started', 'resolved', 'unresolved')),
  largest_safe REAL,
  smallest_perforating REAL,
  run_count INTEGER NOT NULL,
  message TEXT NOT NULL,
  updated_utc TEXT NOT NULL,
  PRIMARY KEY (campaign_id, idx)
);
CREATE TABLE runs (
  id INTEGER PRIMARY KEY,
  campaign_id INTEGER NOT NULL REFERENCES campaigns(id),
  point_idx INTEGER NOT NULL,
  value REAL NOT NULL,
  attempt INTEGER NOT NULL,
  settings TEXT NOT NULL,
  scenario_hash TEXT NOT NULL,
  state TEXT NOT NULL CHECK (state IN ('completed', 'failed')),
  perforated INTEGER NOT NULL CHECK (perforated IN (0, 1)),
  settled INTEGER NOT NULL CHECK (settled IN (0, 1)),
  diameter_m REAL NOT NULL,
  velocity_m_s REAL NOT NULL,
  angle_rad REAL NOT NULL,
  residual_velocity_m_s REAL NOT NULL,
  reason TEXT NOT NULL,
  measurements TEXT NOT NULL,
  wall_time_s REAL NOT NULL,
  tool_version TEXT NOT NULL,
  created_utc TEXT NOT NULL,
  UNIQUE (campaign_id, scenario_hash)
);
)sql";

// Schema 2: the runs of calibrations, which belong to no campaign. Created with a new file and added to a file of
// schema 1 when it is opened.
constexpr const char* kSchemaV2 = R"sql(
CREATE TABLE IF NOT EXISTS calibration_runs (
  key TEXT PRIMARY KEY,
  scenario TEXT NOT NULL,
  settings TEXT NOT NULL,
  scenario_hash TEXT NOT NULL,
  state TEXT NOT NULL CHECK (state IN ('completed', 'failed')),
  reason TEXT NOT NULL,
  summary TEXT NOT NULL,
  wall_time_s REAL NOT NULL,
  tool_version TEXT NOT NULL,
  created_utc TEXT NOT NULL
);
)sql";

int tableCount(sqlite3* db, const std::string& file) {
  sql::Statement q(db, file, "SELECT count(*) FROM sqlite_master WHERE type = 'table'", "listing tables");
  return q.step() ? static_cast<int>(q.integer(0)) : 0;
}

enum class SchemaWork { none, create, upgrade };

// Throws for a file this blt cannot use; otherwise what its schema needs.
SchemaWork schemaWork(sqlite3* db, const std::string& file) {
  const std::string allowed = "a run database written by blt campaign run or blt calibrate, or the name of a new file";
  const int version = sql::pragmaInt(db, file, "user_version");
  const int app = sql::pragmaInt(db, file, "application_id");
  if (app != 0 && app != kApplicationId)
    throw InputError(InputLocation::file(file), "is an SQLite database of another kind, not a blt run database", allowed);
  if (version > RunDatabase::kSchemaVersion)
    throw InputError(InputLocation::file(file),
                     "was written by a newer blt (run database schema " + std::to_string(version) +
                         "; this blt reads up to " + std::to_string(RunDatabase::kSchemaVersion) + ")",
                     "upgrade blt to read it");
  if (app == kApplicationId && version == RunDatabase::kSchemaVersion) return SchemaWork::none;
  if (app == kApplicationId && version >= 1) return SchemaWork::upgrade;
  if (tableCount(db, file) > 0)
    throw InputError(InputLocation::file(file), "is an SQLite database but not a blt run database", allowed);
  return SchemaWork::create;
}

const char* stateKey(RunState s) { return s == RunState::completed ? "completed" : "failed"; }
RunState runStateFrom(const std::string& s) { return s == "completed" ? RunState::completed : RunState::failed; }

// A summary as stored: NaN and infinities are no JSON, and nlohmann::json writes them as null; none is {}.
std::string summaryText(const nlohmann::json& j) {
  return j.is_null() ? std::string("{}") : j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

PointState pointStateFrom(const std::string& s) {
  if (s == "started") return PointState::started;
  if (s == "resolved") return PointState::resolved;
  if (s == "unresolved") return PointState::unresolved;
  return PointState::pending;
}

int advancement(PointState s) {
  switch (s) {
    case PointState::pending: return 0;
    case PointState::started: return 1;
    case PointState::resolved:
    case PointState::unresolved: return 2;
  }
  return 0;
}

constexpr const char* kPointColumns =
    "idx, label, velocity_m_s, diameter_m, angle_rad, bracket_lower, bracket_upper, bracket_origin, state, "
    "largest_safe, smallest_perforating, run_count, message";

PointRecord readPoint(const sql::Statement& q) {
  PointRecord p;
  p.index = static_cast<int>(q.integer(0));
  p.label = q.text(1);
  p.velocity = q.real(2);
  p.diameter = q.real(3);
  p.angle = q.real(4);
  p.bracketLower = q.real(5);
  p.bracketUpper = q.real(6);
  p.bracketOrigin = q.text(7);
  p.state = pointStateFrom(q.text(8));
  p.largestSafe = q.optionalReal(9);
  p.smallestPerforating = q.optionalReal(10);
  p.runs = static_cast<int>(q.integer(11));
  p.message = q.text(12);
  return p;
}

constexpr const char* kRunColumns =
    "id, point_idx, value, attempt, settings, scenario_hash, state, perforated, settled, diameter_m, velocity_m_s, "
    "angle_rad, residual_velocity_m_s, reason, measurements, wall_time_s, tool_version, created_utc";

RunRecord readRun(const sql::Statement& q) {
  RunRecord r;
  r.id = q.integer(0);
  r.point = static_cast<int>(q.integer(1));
  r.value = q.real(2);
  r.attempt = static_cast<int>(q.integer(3));
  r.settings = nlohmann::json::parse(q.text(4)).get<std::vector<std::string>>();
  r.scenarioHash = q.text(5);
  r.state = runStateFrom(q.text(6));
  r.perforated = q.integer(7) != 0;
  r.settled = q.integer(8) != 0;
  r.diameter = q.real(9);
  r.velocity = q.real(10);
  r.angle = q.real(11);
  r.residualVelocity = q.real(12);
  r.reason = q.text(13);
  r.measurements = nlohmann::json::parse(q.text(14));
  r.wallSeconds = q.real(15);
  r.toolVersion = q.text(16);
  r.createdUtc = q.text(17);
  return r;
}

CampaignRecord readCampaign(const sql::Statement& q) {
  CampaignRecord c;
  c.id = q.integer(0);
  c.name = q.text(1);
  c.definition = nlohmann::json::parse(q.text(2));
  c.definitionHash = q.text(3);
  c.variable = q.text(4);
  c.projectileDensity = q.real(5);
  c.taskIndex = static_cast<int>(q.integer(6));
  c.taskCount = static_cast<int>(q.integer(7));
  c.createdUtc = q.text(8);
  return c;
}
constexpr const char* kCampaignColumns =
    "id, name, definition, definition_hash, variable, projectile_density_kg_m3, task_index, task_count, created_utc";

// Inserts a run in a transaction the caller holds; false when its hash was recorded already.
bool insertRun(sqlite3* db, const std::string& file, std::int64_t campaign, const RunRecord& r) {
  sql::Statement q(db, file,
               "INSERT INTO runs (campaign_id, point_idx, value, attempt, settings, scenario_hash, state, perforated, "
               "settled, diameter_m, velocity_m_s, angle_rad, residual_velocity_m_s, reason, measurements, wall_time_s, "
               "tool_version, created_utc) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14, ?15, "
               "?16, ?17, ?18) ON CONFLICT (campaign_id, scenario_hash) DO NOTHING",
               "recording a run");
  q.bind(1, campaign).bind(2, r.point).bind(3, r.value).bind(4, r.attempt).bind(5, nlohmann::json(r.settings).dump());
  q.bind(6, r.scenarioHash).bind(7, stateKey(r.state)).bind(8, r.perforated).bind(9, r.settled);
  q.bind(10, r.diameter).bind(11, r.velocity).bind(12, r.angle);
  q.bind(13, std::isfinite(r.residualVelocity) ? r.residualVelocity : 0.0).bind(14, r.reason);
  q.bind(15, summaryText(r.measurements));
  q.bind(16, r.wallSeconds).bind(17, r.toolVersion).bind(18, r.createdUtc.empty() ? nowUtcIso8601() : r.createdUtc);
  q.run();
  return q.changes() > 0;
}

constexpr const char* kCalibrationRunColumns =
    "key, scenario, settings, scenario_hash, state, reason, summary, wall_time_s, tool_version, created_utc";

CalibrationRunRecord readCalibrationRun(const sql::Statement& q) {
  CalibrationRunRecord r;
  r.key = q.text(0);
  r.scenario = q.text(1);
  r.settings = nlohmann::json::parse(q.text(2)).get<std::vector<std::string>>();
  r.scenarioHash = q.text(3);
  r.state = runStateFrom(q.text(4));
  r.reason = q.text(5);
  r.summary = nlohmann::json::parse(q.text(6));
  r.wallSeconds = q.real(7);
  r.toolVersion = q.text(8);
  r.createdUtc = q.text(9);
  return r;
}

// Inserts a calibration run in a transaction the caller holds: a completed run replaces a failed one of its key,
// anything else recorded first stays. False when nothing changed.
bool insertCalibrationRun(sqlite3* db, const std::string& file, const CalibrationRunRecord& r) {
  sql::Statement q(db, file,
               std::string("INSERT INTO calibration_runs (") + kCalibrationRunColumns +
                   ") VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10) ON CONFLICT (key) DO UPDATE SET "
                   "scenario = excluded.scenario, settings = excluded.settings, scenario_hash = excluded.scenario_hash, "
                   "state = excluded.state, reason = excluded.reason, summary = excluded.summary, "
                   "wall_time_s = excluded.wall_time_s, tool_version = excluded.tool_version, "
                   "created_utc = excluded.created_utc WHERE state = 'failed' AND excluded.state = 'completed'",
               "recording a calibration run");
  q.bind(1, r.key).bind(2, r.scenario).bind(3, nlohmann::json(r.settings).dump()).bind(4, r.scenarioHash);
  q.bind(5, stateKey(r.state)).bind(6, r.reason);
  q.bind(7, summaryText(r.summary));
  q.bind(8, r.wallSeconds).bind(9, r.toolVersion).bind(10, r.createdUtc.empty() ? nowUtcIso8601() : r.createdUtc);
  q.run();
  return q.changes() > 0;
}

void writePoint(sqlite3* db, const std::string& file, std::int64_t campaign, const PointRecord& p, bool replace) {
  sql::Statement q(db, file,
               std::string(replace ? "INSERT OR REPLACE" : "INSERT OR IGNORE") +
                   " INTO points (campaign_id, " + kPointColumns +
                   ", updated_utc) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14, ?15)",
               "recording a point");
  q.bind(1, campaign).bind(2, p.index).bind(3, p.label).bind(4, p.velocity).bind(5, p.diameter).bind(6, p.angle);
  q.bind(7, p.bracketLower).bind(8, p.bracketUpper).bind(9, p.bracketOrigin).bind(10, toString(p.state));
  q.bind(11, p.largestSafe).bind(12, p.smallestPerforating).bind(13, p.runs).bind(14, p.message).bind(15, nowUtcIso8601());
  q.run();
}

std::optional<CampaignRecord> campaignByName(sqlite3* db, const std::string& file, const std::string& name) {
  sql::Statement q(db, file, std::string("SELECT ") + kCampaignColumns + " FROM campaigns WHERE name = ?1",
               "looking up a campaign");
  q.bind(1, name);
  if (!q.step()) return std::nullopt;
  return readCampaign(q);
}

}  // namespace

const char* toString(PointState s) {
  switch (s) {
    case PointState::pending: return "pending";
    case PointState::started: return "started";
    case PointState::resolved: return "resolved";
    case PointState::unresolved: return "unresolved";
  }
  return "pending";
}

RunDatabase::RunDatabase(const std::string& path) : path_(path) {
  if (sqlite3_open_v2(path.c_str(), &db_, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_FULLMUTEX, nullptr) !=
      SQLITE_OK) {
    const std::string why = db_ ? sqlite3_errmsg(db_) : "out of memory";
    sqlite3_close(db_);
    db_ = nullptr;
    throw InputError(InputLocation::file(path), "cannot open the run database: " + why,
                     "a writable path (a new file is created)");
  }
  try {
    sqlite3_busy_timeout(db_, kBusyTimeoutMs);
    const auto work = [&] {
      // user_version, application_id and the table count from one snapshot: read one by one, a writer
      // creating the schema between them makes a new database look like a foreign one.
      sql::ReadTransaction snapshot(db_, path_);
      return schemaWork(db_, path_);
    };
    if (work() != SchemaWork::none) {
      sql::WriteTransaction tx(db_, path_);
      // Another process may have created or upgraded it while this one waited for the lock.
      const SchemaWork now = schemaWork(db_, path_);
      if (now == SchemaWork::create) sql::exec(db_, path_, kSchemaV1, "creating the run database schema");
      if (now != SchemaWork::none) {
        sql::exec(db_, path_, kSchemaV2, "adding the calibration runs to the schema");
        sql::exec(db_, path_,
                  "PRAGMA user_version = " + std::to_string(kSchemaVersion) +
                      "; PRAGMA application_id = " + std::to_string(kApplicationId),
                  "setting the schema version");
      }
      tx.commit();
    }
    // WAL persists in the file; readers then never block the writer. FULL: a commit is on disk when it returns.
    sql::Statement wal(db_, path_, "PRAGMA journal_mode = WAL", "switching to WAL");
    wal.run();
    sql::exec(db_, path_, "PRAGMA synchronous = FULL; PRAGMA foreign_keys = ON", "setting PRAGMAs");
  } catch (...) {
    sqlite3_close(db_);
    db_ = nullptr;
    throw;
  }
}

RunDatabase::~RunDatabase() { sqlite3_close(db_); }

std::int64_t RunDatabase::ensureCampaign(const Campaign& c, double projectileDensity, int taskIndex, int taskCount) {
  std::lock_guard lock(mutex_);
  sql::WriteTransaction tx(db_, path_);
  const std::string hash = c.definitionHash();
  if (auto existing = campaignByName(db_, path_, c.name)) {
    if (existing->definitionHash != hash)
      throw InputError(InputLocation::file(path_, std::nullopt, "campaign " + c.name),
                       "holds campaign '" + c.name + "' with another definition (hash " + existing->definitionHash +
                           "; " + c.path + " and its scenario now give " + hash +
                           "): the campaign file, its settings or its scenario changed since it was started",
                       "the campaign as it was, another --db, or another campaign name");
    if (existing->taskIndex != taskIndex || existing->taskCount != taskCount)
      throw InputError(InputLocation::file(path_, std::nullopt, "campaign " + c.name),
                       "was made for task " + std::to_string(existing->taskIndex) + "/" +
                           std::to_string(existing->taskCount) + ", not " + std::to_string(taskIndex) + "/" +
                           std::to_string(taskCount),
                       "--task " + std::to_string(existing->taskIndex) + "/" + std::to_string(existing->taskCount) +
                           " with this file, or a file per task");
    return existing->id;
  }
  sql::Statement q(db_, path_,
               "INSERT INTO campaigns (name, definition, definition_hash, variable, projectile_density_kg_m3, task_index, "
               "task_count, created_utc) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8)",
               "recording the campaign");
  q.bind(1, c.name).bind(2, c.definition().dump()).bind(3, hash).bind(4, sim::toString(c.variable));
  q.bind(5, projectileDensity).bind(6, taskIndex).bind(7, taskCount).bind(8, nowUtcIso8601());
  q.run();
  const std::int64_t id = sqlite3_last_insert_rowid(db_);
  tx.commit();
  return id;
}

std::optional<CampaignRecord> RunDatabase::findCampaign(const std::string& name) const {
  std::lock_guard lock(mutex_);
  return campaignByName(db_, path_, name);
}

std::vector<CampaignRecord> RunDatabase::campaigns() const {
  std::lock_guard lock(mutex_);
  sql::Statement q(db_, path_, std::string("SELECT ") + kCampaignColumns + " FROM campaigns ORDER BY id", "listing campaigns");
  std::vector<CampaignRecord> list;
  while (q.step()) list.push_back(readCampaign(q));
  return list;
}

PointRecord RunDatabase::ensurePoint(std::int64_t campaign, const PointRecord& p) {
  std::lock_guard lock(mutex_);
  sql::WriteTransaction tx(db_, path_);
  writePoint(db_, path_, campaign, p, false);
  sql::Statement q(db_, path_, std::string("SELECT ") + kPointColumns + " FROM points WHERE campaign_id = ?1 AND idx = ?2",
               "reading a point");
  q.bind(1, campaign).bind(2, p.index);
  q.step();
  PointRecord stored = readPoint(q);
  tx.commit();
  return stored;
}

void RunDatabase::updatePoint(std::int64_t campaign, const PointRecord& p) {
  std::lock_guard lock(mutex_);
  sql::WriteTransaction tx(db_, path_);
  writePoint(db_, path_, campaign, p, true);
  tx.commit();
}

std::vector<PointRecord> RunDatabase::points(std::int64_t campaign) const {
  std::lock_guard lock(mutex_);
  sql::Statement q(db_, path_, std::string("SELECT ") + kPointColumns + " FROM points WHERE campaign_id = ?1 ORDER BY idx",
               "listing points");
  q.bind(1, campaign);
  std::vector<PointRecord> list;
  while (q.step()) list.push_back(readPoint(q));
  return list;
}

std::optional<RunRecord> RunDatabase::findRun(std::int64_t campaign, const std::string& scenarioHash) const {
  std::lock_guard lock(mutex_);
  sql::Statement q(db_, path_,
               std::string("SELECT ") + kRunColumns + " FROM runs WHERE campaign_id = ?1 AND scenario_hash = ?2",
               "looking up a run");
  q.bind(1, campaign).bind(2, scenarioHash);
  if (!q.step()) return std::nullopt;
  return readRun(q);
}

RunRecord RunDatabase::recordRun(std::int64_t campaign, const RunRecord& r) {
  std::lock_guard lock(mutex_);
  {
    sql::WriteTransaction tx(db_, path_);
    insertRun(db_, path_, campaign, r);
    tx.commit();
  }
  return *findRun(campaign, r.scenarioHash);
}

std::vector<RunRecord> RunDatabase::runs(std::int64_t campaign) const {
  std::lock_guard lock(mutex_);
  sql::Statement q(db_, path_, std::string("SELECT ") + kRunColumns + " FROM runs WHERE campaign_id = ?1 ORDER BY id",
               "listing runs");
  q.bind(1, campaign);
  std::vector<RunRecord> list;
  while (q.step()) list.push_back(readRun(q));
  return list;
}

std::optional<CalibrationRunRecord> RunDatabase::findCalibrationRun(const std::string& key) const {
  std::lock_guard lock(mutex_);
  sql::Statement q(db_, path_, std::string("SELECT ") + kCalibrationRunColumns + " FROM calibration_runs WHERE key = ?1",
               "looking up a calibration run");
  q.bind(1, key);
  if (!q.step()) return std::nullopt;
  return readCalibrationRun(q);
}

CalibrationRunRecord RunDatabase::recordCalibrationRun(const CalibrationRunRecord& r) {
  std::lock_guard lock(mutex_);
  {
    sql::WriteTransaction tx(db_, path_);
    insertCalibrationRun(db_, path_, r);
    tx.commit();
  }
  return *findCalibrationRun(r.key);
}

std::vector<CalibrationRunRecord> RunDatabase::calibrationRuns() const {
  std::lock_guard lock(mutex_);
  sql::Statement q(db_, path_, std::string("SELECT ") + kCalibrationRunColumns + " FROM calibration_runs ORDER BY rowid",
               "listing calibration runs");
  std::vector<CalibrationRunRecord> list;
  while (q.step()) list.push_back(readCalibrationRun(q));
  return list;
}

int RunDatabase::mergeFrom(const std::string& otherPath) {
  if (!std::filesystem::exists(otherPath))
    throw InputError(InputLocation::file(otherPath), "no such run database", "a file written by blt campaign run");
  const RunDatabase other(otherPath);
  std::lock_guard lock(mutex_);
  sql::WriteTransaction tx(db_, path_);
  int added = 0;
  for (const CampaignRecord& c : other.campaigns()) {
    std::int64_t id = 0;
    if (auto mine = campaignByName(db_, path_, c.name)) {
      if (mine->definitionHash != c.definitionHash)
        throw InputError(InputLocation::file(otherPath, std::nullopt, "campaign " + c.name),
                         "holds campaign '" + c.name + "' with another definition than " + path_ + " (hash " +
                             c.definitionHash + ", not " + mine->definitionHash + ")",
                         "parts of one campaign, run from the same campaign file and scenario");
      id = mine->id;
      // A task's part with another part merged in is no longer that task's: it holds shares of several, and
      // `campaign run` without --task finishes whatever is still missing.
      if (mine->taskIndex != c.taskIndex || mine->taskCount != c.taskCount) {
        sql::Statement q(db_, path_, "UPDATE campaigns SET task_index = 1, task_count = 1 WHERE id = ?1",
                     "relabelling the merged campaign");
        q.bind(1, id);
        q.run();
      }
    } else {
      // The merged file holds every task's points: it is the whole campaign (1/1).
      sql::Statement q(db_, path_,
                   "INSERT INTO campaigns (name, definition, definition_hash, variable, projectile_density_kg_m3, "
                   "task_index, task_count, created_utc) VALUES (?1, ?2, ?3, ?4, ?5, 1, 1, ?6)",
                   "merging a campaign");
      q.bind(1, c.name).bind(2, c.definition.dump()).bind(3, c.definitionHash).bind(4, c.variable);
      q.bind(5, c.projectileDensity).bind(6, c.createdUtc);
      q.run();
      id = sqlite3_last_insert_rowid(db_);
    }
    std::map<int, PointRecord> mine;
    {
      sql::Statement q(db_, path_, std::string("SELECT ") + kPointColumns + " FROM points WHERE campaign_id = ?1",
                   "reading points to merge into");
      q.bind(1, id);
      while (q.step()) {
        PointRecord p = readPoint(q);
        mine[p.index] = p;
      }
    }
    for (const PointRecord& p : other.points(c.id)) {
      const auto it = mine.find(p.index);
      if (it == mine.end() || advancement(p.state) > advancement(it->second.state) ||
          (advancement(p.state) == advancement(it->second.state) && p.runs > it->second.runs))
        writePoint(db_, path_, id, p, true);
    }
    for (const RunRecord& r : other.runs(c.id))
      if (insertRun(db_, path_, id, r)) ++added;
  }
  for (const CalibrationRunRecord& r : other.calibrationRuns())
    if (insertCalibrationRun(db_, path_, r)) ++added;
  tx.commit();
  return added;
}

std::string RunDatabase::integrityCheck() const {
  std::lock_guard lock(mutex_);
  sql::Statement q(db_, path_, "PRAGMA integrity_check", "checking integrity");
  std::string result;
  while (q.step()) result += (result.empty() ? "" : "; ") + q.text(0);
  return result;
}

std::vector<ble::ImpactPoint> campaignImpactPoints(const RunDatabase& db, const std::string& campaign) {
  const auto c = db.findCampaign(campaign);
  if (!c) {
    std::string names;
    for (const auto& other : db.campaigns()) names += (names.empty() ? "" : ", ") + other.name;
    throw InputError(InputLocation::file(db.path()), "holds no campaign '" + campaign + "'",
                     names.empty() ? "a run database with campaigns (this one is empty)" : "one of: " + names);
  }
  std::vector<ble::ImpactPoint> points;
  for (const RunRecord& r : db.runs(c->id)) {
    if (r.state != RunState::completed) continue;
    ble::ImpactPoint p;
    p.diameter = r.diameter;
    p.velocity = r.velocity;
    p.angle = r.angle;
    p.perforated = r.perforated;
    p.projectileDensity = c->projectileDensity;
    p.source = "campaign " + c->name + " run " + std::to_string(r.id);
    p.origin = db.path() + ": run " + std::to_string(r.id);
    points.push_back(p);
  }
  return points;
}

int writeImpactCsv(const std::string& path, const std::vector<ble::ImpactPoint>& points, const std::string& comment) {
  std::ofstream out(path);
  if (!out) throw InputError(InputLocation::file(path), "cannot write the CSV file", "a writable path");
  std::string line;
  for (char ch : comment) {
    if (ch == '\n') {
      out << "# " << line << "\n";
      line.clear();
    } else {
      line += ch;
    }
  }
  if (!line.empty()) out << "# " << line << "\n";
  out << "diameter_mm,velocity_km_s,angle_deg,perforated,source,projectile_density_kg_m3\n";
  for (const auto& p : points) {
    std::string source = p.source;
    for (char& ch : source)
      if (ch == ',' || ch == '"' || ch == '\n') ch = ' ';  // the CSV has no quoting
    out << exactNumber(units::toUnit(p.diameter, "mm")) << "," << exactNumber(units::toUnit(p.velocity, "km/s")) << ","
        << exactNumber(units::toUnit(p.angle, "deg")) << "," << (p.perforated ? 1 : 0) << "," << source << ","
        << exactNumber(p.projectileDensity) << "\n";
  }
  if (!out) throw InputError(InputLocation::file(path), "writing the CSV file failed (disk full?)");
  return static_cast<int>(points.size());
}

}  // namespace blt::campaign
