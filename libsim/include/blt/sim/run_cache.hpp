#pragma once
// Finished impact runs kept in a file so that a report or a calibration started again runs nothing twice: one
// JSON line per run (its key and its summary), appended and flushed as the run ends. A line cut short by a kill
// is skipped when the file is read, so at most the run in flight is lost. Several threads may share one cache.
// The validation report keeps its runs here; bisection campaigns and calibrations keep theirs in a run database
// (blt/campaign/database.hpp), whose calibration runs carry this cache's keys.
//
// A run's key names its scenario by the hash of the scenario's text and the model by modelFingerprint(), so an
// edited scenario file, an edited material card or a changed solver is run again instead of replayed.

#include <cstddef>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace blt::sim {

// FNV-1a (64 bit, hex) of a scenario's text and the settings of a run: the identity of a run's inputs.
std::string scenarioHash(const std::string& scenarioText, const std::vector<std::string>& settings);

// 16 hex digits over the sources and material cards that decide a run's result (solver, constitutive models,
// laminate model, units and parsing, data/materials), made at build time by cmake/model_fingerprint.cmake. Two
// builds with the same fingerprint give the same result for the same inputs (up to thread scheduling).
std::string modelFingerprint();
// "VERSION+model.FINGERPRINT": the build a recorded run came from (a campaign database's tool_version).
std::string buildVersion();

class RunCache {
 public:
  // Reads the runs already in `path` (created on the first record); an empty path keeps runs in memory only.
  explicit RunCache(std::string path = {});

  // "LABEL HASH model=FINGERPRINT --set k=v ...": LABEL names the scenario for a reader (its path), HASH is of
  // `scenarioText`, FINGERPRINT is modelFingerprint().
  static std::string key(const std::string& label, const std::string& scenarioText,
                         const std::vector<std::string>& settings);

  std::optional<nlohmann::json> find(const std::string& key) const;
  // Appends the run; throws InputError naming the file when it cannot be written.
  void record(const std::string& key, const nlohmann::json& summary);
  std::size_t size() const;
  std::map<std::string, nlohmann::json> runs() const;  // every run, by key
  std::size_t loaded() const { return loaded_; }  // runs read from the file at construction
  const std::string& path() const { return path_; }

 private:
  std::string path_;
  std::map<std::string, nlohmann::json> runs_;
  std::size_t loaded_ = 0;
  mutable std::mutex mutex_;
};

}  // namespace blt::sim
