#pragma once
// The run database of bisection campaigns: one SQLite file holding campaigns (their definitions), their points
// (bracket, state, result) and every simulation made for them (inputs as settings, scenario hash, verdict,
// measurements, wall time, tool version, failure reason). Calibrations (blt calibrate) keep their runs in the same
// kind of file, in a table of their own: they bisect nothing, so their runs belong to no campaign or point.
//
// Journal mode WAL with synchronous = FULL: every write is one transaction, durable once it returns, so a
// kill or a power cut loses at most the run in flight. The schema is versioned (PRAGMA user_version); a newer
// file is refused. Several connections (threads or processes) may write one file: writers wait for each other
// (busy timeout). SQLite's locking is not safe on network file systems: give each machine a file of its own
// (--task) and merge them.

#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "blt/ble/impact_data.hpp"
#include "blt/campaign/campaign.hpp"

struct sqlite3;

namespace blt::campaign {

struct CampaignRecord {
  std::int64_t id = 0;
  std::string name, definitionHash, variable, createdUtc;
  nlohmann::json definition;
  double projectileDensity = 0;  // kg/m³ of the scenario's projectile, for the exported points
  int taskIndex = 1, taskCount = 1;  // the share of the points this file was made for (1/1: all)
};

enum class PointState { pending, started, resolved, unresolved };
const char* toString(PointState s);

struct PointRecord {
  int index = 0;         // position in the campaign
  std::string label;     // "4.5 km/s, 45 deg"
  double velocity = 0, diameter = 0, angle = 0;  // SI; the bisected one is 0
  double bracketLower = 0, bracketUpper = 0;     // the first bracket (SI)
  std::string bracketOrigin;  // "campaign", "point" or "ble fit NAME: d_c X"
  PointState state = PointState::pending;
  std::optional<double> largestSafe, smallestPerforating;  // SI
  int runs = 0;                 // runs its bisection took, bracket included (replayed ones too)
  std::string message;          // why it is unresolved
};

enum class RunState { completed, failed };

struct RunRecord {
  std::int64_t id = 0;
  int point = 0;        // the point's index
  double value = 0;     // the bisected variable, SI
  int attempt = 0;      // 0: the campaign's resolution; 1: the retry at half the spacing
  std::vector<std::string> settings;
  std::string scenarioHash;
  RunState state = RunState::completed;
  bool perforated = false, settled = false;
  double diameter = 0, velocity = 0, angle = 0;  // SI, the shot
  double residualVelocity = 0;                   // m/s
  std::string reason;                            // why it failed
  nlohmann::json measurements;                   // the run's summary (sim::ImpactResult::summary)
  double wallSeconds = 0;
  std::string toolVersion, createdUtc;
};

// A run made for a calibration. Its key is the run cache's (sim::RunCache::key: a label of the scenario, the hash
// of its text, the model fingerprint, the settings), so a run is found again only by the same build.
struct CalibrationRunRecord {
  std::string key;
  std::string scenario;               // the scenario file
  std::vector<std::string> settings;  // on top of it
  std::string scenarioHash;           // of its text and the settings (sim::scenarioHash)
  RunState state = RunState::completed;
  std::string reason;                 // why it failed
  nlohmann::json summary;             // the run's summary, as far as the calibration keeps it
  double wallSeconds = 0;
  std::string toolVersion;            // the build that made it (sim::buildVersion), or where it was imported from
  std::string createdUtc;
};

class RunDatabase {
 public:
  // 2 added the calibration runs; a file of schema 1 is given the table when opened.
  static constexpr int kSchemaVersion = 2;

  // Opens or creates the file. Throws InputError naming it when it is not a blt run database, or a newer one.
  explicit RunDatabase(const std::string& path);
  ~RunDatabase();
  RunDatabase(const RunDatabase&) = delete;
  RunDatabase& operator=(const RunDatabase&) = delete;

  // Records the campaign, or checks that the one recorded under its name has the same definition (else an
  // InputError: the file or its scenario changed since). Returns its id.
  std::int64_t ensureCampaign(const Campaign& c, double projectileDensity, int taskIndex, int taskCount);
  std::optional<CampaignRecord> findCampaign(const std::string& name) const;
  std::vector<CampaignRecord> campaigns() const;

  // Records a point with its first bracket; a point recorded before keeps its bracket, which is returned, so a
  // resumed campaign bisects exactly as it began even if the BLE store changed since.
  PointRecord ensurePoint(std::int64_t campaign, const PointRecord& p);
  void updatePoint(std::int64_t campaign, const PointRecord& p);
  std::vector<PointRecord> points(std::int64_t campaign) const;

  std::optional<RunRecord> findRun(std::int64_t campaign, const std::string& scenarioHash) const;
  // Records a run unless one with its scenario hash is there already (another process made it meanwhile);
  // returns the recorded one.
  RunRecord recordRun(std::int64_t campaign, const RunRecord& r);
  std::vector<RunRecord> runs(std::int64_t campaign) const;

  // The calibration run of that key; nullopt when none was recorded.
  std::optional<CalibrationRunRecord> findCalibrationRun(const std::string& key) const;
  // Records a calibration run. A completed run replaces a failed one of the same key (the run was made again);
  // otherwise the one recorded first stays (another process made it meanwhile). Returns the recorded one.
  CalibrationRunRecord recordCalibrationRun(const CalibrationRunRecord& r);
  std::vector<CalibrationRunRecord> calibrationRuns() const;

  // Copies every campaign, point and run, and every calibration run, of another run database into this one, in one
  // transaction. A campaign present in both must have the same definition; runs are matched by scenario hash and
  // calibration runs by key as recordCalibrationRun does; a point takes the more advanced state (resolved or
  // unresolved over started over pending). Returns the runs added (of both kinds).
  int mergeFrom(const std::string& otherPath);

  // PRAGMA integrity_check; "ok" when the file is sound.
  std::string integrityCheck() const;
  const std::string& path() const { return path_; }

 private:
  std::string path_;
  sqlite3* db_ = nullptr;
  // One connection, many worker threads: the statements of one call must not interleave with another's.
  mutable std::recursive_mutex mutex_;
};

// Every completed run of a campaign as a binary impact point (failed runs have no outcome), source
// "campaign NAME run ID", with the campaign's projectile density. Throws InputError naming the campaigns present
// when there is none of that name.
std::vector<ble::ImpactPoint> campaignImpactPoints(const RunDatabase& db, const std::string& campaign);
// Writes them as the project's binary impact CSV (readImpactCsv reads it back). Returns the rows written.
int writeImpactCsv(const std::string& path, const std::vector<ble::ImpactPoint>& points, const std::string& comment);


}  // namespace blt::campaign
