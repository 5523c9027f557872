// The run cache shared by blt validate and blt calibrate: kept across sessions, a half-written line skipped, an
// edited scenario keyed apart.
#include <doctest/doctest.h>

#include <filesystem>
#include <fstream>

#include "blt/core/error.hpp"
#include "blt/sim/run_cache.hpp"

using blt::sim::RunCache;

TEST_CASE("run cache: runs come back in a new session, a line cut short by a kill is skipped") {
  const auto path = (std::filesystem::temp_directory_path() / "blt_run_cache.jsonl").string();
  std::filesystem::remove(path);
  const std::string a = RunCache::key("s.toml", "velocity = 1", {"projectile.diameter=1mm"});
  const std::string b = RunCache::key("s.toml", "velocity = 1", {"projectile.diameter=2mm"});
  {
    RunCache cache(path);
    CHECK(cache.loaded() == 0);
    CHECK_FALSE(cache.find(a));
    cache.record(a, {{"perforated", true}});
    cache.record(b, {{"perforated", false}});
  }
  std::ofstream(path, std::ios::app) << "{\"key\": \"s.toml 0123 --set";  // killed mid-write
  RunCache again(path);
  CHECK(again.loaded() == 2);
  REQUIRE(again.find(a));
  CHECK((*again.find(a))["perforated"] == true);
  CHECK((*again.find(b))["perforated"] == false);
}

TEST_CASE("run cache: the key changes with the scenario's text and with each setting, not with the label's reader") {
  const std::string base = RunCache::key("s.toml", "x = 1", {"a=1"});
  CHECK(RunCache::key("s.toml", "x = 2", {"a=1"}) != base);
  CHECK(RunCache::key("s.toml", "x = 1", {"a=2"}) != base);
  CHECK(RunCache::key("s.toml", "x = 1", {"a=1", "b=1"}) != base);
  CHECK(RunCache::key("s.toml", "x = 1", {"a=1"}) == base);
  CHECK(base.rfind("s.toml ", 0) == 0);
  CHECK(base.find(" --set a=1") != std::string::npos);
  // The campaign databases' hashes are this function's: a list of texts is fed with lengths, so moving a
  // character between two settings changes it.
  CHECK(blt::sim::scenarioHash("t", {"ab", "c"}) != blt::sim::scenarioHash("t", {"a", "bc"}));
}

TEST_CASE("run cache: an unwritable file is an error naming it") {
  RunCache cache((std::filesystem::temp_directory_path() / "blt_no_such_dir_cache" / "runs.jsonl").string());
  CHECK_THROWS_WITH_AS(cache.record("k", {{"perforated", true}}), doctest::Contains("blt_no_such_dir_cache/runs.jsonl"),
                       blt::InputError);
}
