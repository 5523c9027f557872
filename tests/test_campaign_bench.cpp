// blt bench campaign (issue 6): the benchmark of a campaign run from scratch, on a stand-in solver, and the
// command line's argument handling. No real simulation here; the benchmark itself is run by hand.
#include <doctest/doctest.h>
#include <unistd.h>

#include <atomic>
#include <cmath>
#include <filesystem>
#include <fstream>

#include "blt/campaign/bench.hpp"
#include "blt/campaign/campaign.hpp"
#include "blt/core/error.hpp"
#include "run_blt.hpp"
#include "scratch_dir.hpp"

namespace fs = std::filesystem;
using namespace blt::campaign;

namespace {

fs::path benchScratch(const std::string& name) { return scratchDir("bench_campaign_test", name); }

// Perforated exactly above d_c = 1 mm (5 km/s / V)^0.5: instant and deterministic.
Simulator countingFake(std::atomic<int>& calls) {
  return [&calls](const blt::sim::ImpactScenario& sc) {
    ++calls;
    SimulationOutcome o;
    o.perforated = sc.projectile.diameter > 1.0e-3 * std::sqrt(5000.0 / sc.projectile.velocity);
    o.settled = true;
    o.wallSeconds = 0.01;
    o.measurements = {{"fake", true}};
    return o;
  };
}

}  // namespace

TEST_SUITE("campaign") {

TEST_CASE("bench campaign: figures of a campaign run into a new database, which must not exist yet") {
  const fs::path dir = benchScratch("figures");
  const std::string text = "name = \"b\"\nscenario = \"" + std::string(BLT_DATA_DIR) +
                           "/scenarios/fabric_al_corrected.toml\"\n[bisect]\nlower = \"0.5 mm\"\nupper = \"2.5 mm\"\n"
                           "tolerance = \"0.02 mm\"\n[grid]\nvelocity = [\"2 km/s\", \"5 km/s\", \"8 km/s\"]\n";
  const Campaign c = parseCampaign(text, (dir / "b.toml").string());
  std::atomic<int> calls{0};
  CampaignRunOptions o;
  o.jobs = 2;
  o.taskIndex = 2;  // ignored: a benchmark runs every point
  o.taskCount = 3;
  o.simulator = countingFake(calls);
  const std::string db = (dir / "runs.sqlite").string();
  const CampaignBenchmark b = benchmarkCampaign(c, db, o);
  CHECK(b.campaign == "b");
  CHECK(b.points == 3);
  CHECK(b.resolved == 3);
  CHECK(b.unresolved == 0);
  CHECK(b.runs == calls.load());
  CHECK(b.runsFailed == 0);
  CHECK(b.runsReplayed == 0);
  CHECK(b.runsPerPointMean == doctest::Approx(calls.load() / 3.0));
  // From 2 mm to +-0.02 mm: the two bracket ends and ceil(log2(2 / 0.04)) = 6 halvings.
  CHECK(b.runsPerPointMax == 8);
  CHECK(b.simulatedSeconds == doctest::Approx(0.01 * calls.load()));
  CHECK(b.wallSeconds >= 0);
  CHECK_FALSE(b.interrupted);
  REQUIRE(b.pointRecords.size() == 3);
  for (const auto& p : b.pointRecords) CHECK(*p.smallestPerforating - *p.largestSafe <= 2 * c.tolerance + 1e-12);

  // Run again on the same file, every run would be replayed: refused before anything runs.
  const int before = calls.load();
  CHECK_THROWS_AS(benchmarkCampaign(c, db, o), blt::InputError);
  CHECK(calls.load() == before);
  fs::remove_all(dir);
}

TEST_CASE("bench campaign CLI: options, and bad arguments refused before any simulation") {
  const BltRun help = runBlt("bench campaign --help");
  CHECK(help.status == 0);
  for (const char* flag : {"--campaign", "--seeded", "--quick", "--jobs", "--threads", "--json", "--ble-db"})
    CHECK_MESSAGE(help.output.find(flag) != std::string::npos, flag);
  CHECK(runBlt("bench --help").output.find("campaign") != std::string::npos);

  const BltRun jobs = runBlt("bench campaign --quick --jobs 0");
  CHECK(jobs.status == 2);
  CHECK(jobs.output.find("--jobs") != std::string::npos);
  const BltRun threads = runBlt("bench campaign --quick --threads -1");
  CHECK(threads.status == 2);
  CHECK(threads.output.find("--threads") != std::string::npos);

  const BltRun missing = runBlt("bench campaign --campaign no_such_campaign.toml");
  CHECK(missing.status == 2);
  CHECK(missing.output.find("no_such_campaign.toml") != std::string::npos);
  CHECK(missing.output.find("bench campaign:") == std::string::npos);  // stopped before the first run

  // --quick names both campaigns itself.
  CHECK(runBlt("bench campaign --quick --campaign data/campaigns/seed000_theta0.toml").status != 0);
}

}  // TEST_SUITE
