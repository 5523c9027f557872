#include "blt/sim/run_cache.hpp"

#include <cstdint>
#include <cstdio>
#include <fstream>
#include <string_view>

#include "blt/core/error.hpp"
#include "blt_model_fingerprint.hpp"

namespace blt::sim {

std::string scenarioHash(const std::string& scenarioText, const std::vector<std::string>& settings) {
  std::uint64_t h = 0xcbf29ce484222325ull;
  const auto feed = [&h](std::string_view text) {
    for (unsigned char ch : text) {
      h ^= ch;
      h *= 0x100000001b3ull;
    }
  };
  // Lengths first, so that no two different lists of texts feed the same bytes.
  const auto feedLength = [&feed](std::size_t n) {
    feed(std::to_string(n));
    feed("\n");
  };
  feed("blt-campaign-run-v1\n");  // the tag of the campaign databases' hashes: kept, so their runs stay found
  feedLength(scenarioText.size());
  feed(scenarioText);
  for (const auto& s : settings) {
    feed("\n");
    feedLength(s.size());
    feed(s);
  }
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(h));
  return hex;
}

std::string modelFingerprint() { return BLT_MODEL_FINGERPRINT; }
std::string buildVersion() { return std::string(BLT_VERSION) + "+model." + modelFingerprint(); }

RunCache::RunCache(std::string path) : path_(std::move(path)) {
  if (path_.empty()) return;
  std::ifstream in(path_);
  std::string line;
  while (std::getline(in, line)) {
    const nlohmann::json j = nlohmann::json::parse(line, nullptr, false);
    if (j.is_object() && j.contains("key") && j.contains("summary")) runs_[j["key"]] = j["summary"];
  }
  loaded_ = runs_.size();
}

std::string RunCache::key(const std::string& label, const std::string& scenarioText,
                          const std::vector<std::string>& settings) {
  std::string k = label + " " + scenarioHash(scenarioText, {}) + " model=" + modelFingerprint();
  for (const auto& s : settings) k += " --set " + s;
  return k;
}

std::optional<nlohmann::json> RunCache::find(const std::string& key) const {
  std::lock_guard lock(mutex_);
  if (auto it = runs_.find(key); it != runs_.end()) return it->second;
  return std::nullopt;
}

void RunCache::record(const std::string& key, const nlohmann::json& summary) {
  std::lock_guard lock(mutex_);
  runs_[key] = summary;
  if (path_.empty()) return;
  std::ofstream out(path_, std::ios::app);
  out << nlohmann::json{{"key", key}, {"summary", summary}}.dump() << "\n";
  out.flush();
  if (!out) throw InputError(InputLocation::file(path_), "cannot append the run to the run cache", "a writable folder");
}

std::map<std::string, nlohmann::json> RunCache::runs() const {
  std::lock_guard lock(mutex_);
  return runs_;
}

std::size_t RunCache::size() const {
  std::lock_guard lock(mutex_);
  return runs_.size();
}

}  // namespace blt::sim
