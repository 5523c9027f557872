// The run cache shared by blt validate and blt calibrate: kept across sessions, a half-written line skipped, an
// edited scenario or a changed model keyed apart.
#include <doctest/doctest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "blt/core/error.hpp"
#include "blt/sim/run_cache.hpp"
#include "scratch_dir.hpp"

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
  CHECK(base.find(" model=" + blt::sim::modelFingerprint() + " ") != std::string::npos);
  // The campaign databases' hashes are this function's: a list of texts is fed with lengths, so moving a
  // character between two settings changes it.
  CHECK(blt::sim::scenarioHash("t", {"ab", "c"}) != blt::sim::scenarioHash("t", {"a", "bc"}));
}

TEST_CASE("run cache: an unwritable file is an error naming it") {
  RunCache cache((std::filesystem::temp_directory_path() / "blt_no_such_dir_cache" / "runs.jsonl").string());
  CHECK_THROWS_WITH_AS(cache.record("k", {{"perforated", true}}), doctest::Contains("blt_no_such_dir_cache/runs.jsonl"),
                       blt::InputError);
}

namespace {
// Runs cmake/model_fingerprint.cmake over `files` (paths under `root`) and returns the fingerprint it writes.
std::string fingerprintOf(const std::filesystem::path& root, const std::vector<std::string>& files) {
  std::ostringstream command;
  command << '"' << BLT_CMAKE_COMMAND << "\" -DROOT=" << root.string()
          << " -DOUT=" << (root / "fingerprint.hpp").string() << " \"-DFILES=";
  for (std::size_t i = 0; i < files.size(); ++i) command << (i ? ";" : "") << (root / files[i]).string();
  command << "\" -P " << BLT_SOURCE_DIR << "/cmake/model_fingerprint.cmake";
  REQUIRE(std::system(command.str().c_str()) == 0);
  std::ifstream in(root / "fingerprint.hpp");
  std::stringstream text;
  text << in.rdbuf();
  const std::string s = text.str(), tag = "#define BLT_MODEL_FINGERPRINT \"";
  const auto at = s.find(tag);
  REQUIRE(at != std::string::npos);
  return s.substr(at + tag.size(), 16);
}
}  // namespace

TEST_CASE("run cache: the model fingerprint changes with any model file's text, and only then") {
  const auto root = scratchDir("run_cache", "fingerprint");
  std::filesystem::create_directories(root / "src");
  std::ofstream(root / "src/solver.cpp") << "double viscosity = 0.06;\n";
  std::ofstream(root / "card.toml") << "density = \"2770 kg/m3\"\n";
  const std::vector<std::string> files{"src/solver.cpp", "card.toml"};
  const std::string base = fingerprintOf(root, files);
  CHECK(base.size() == 16);
  CHECK(base.find_first_not_of("0123456789abcdef") == std::string::npos);
  CHECK(fingerprintOf(root, files) == base);
  CHECK(fingerprintOf(root, {"card.toml", "src/solver.cpp"}) == base);  // the order of the list does not matter

  std::ofstream(root / "card.toml") << "density = \"2780 kg/m3\"\n";  // an edited material card
  const std::string edited = fingerprintOf(root, files);
  CHECK(edited != base);
  std::ofstream(root / "extra.cpp") << "\n";  // a new source file
  CHECK(fingerprintOf(root, {"src/solver.cpp", "card.toml", "extra.cpp"}) != edited);
  std::filesystem::rename(root / "card.toml", root / "src/card.toml");  // the same text under another name
  CHECK(fingerprintOf(root, {"src/solver.cpp", "src/card.toml"}) != edited);

  // The build's own fingerprint has the same form.
  CHECK(blt::sim::modelFingerprint().size() == 16);
  std::filesystem::remove_all(root);
}
