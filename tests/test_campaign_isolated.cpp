// Campaign runs in a process of their own (libcampaign isolated.hpp): the same outcome as a run in process, a
// crash recorded as a failed run with its signal, and a campaign that goes on past a crashing point.
#include <doctest/doctest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "approx.hpp"
#include "scratch_dir.hpp"
#include "blt/campaign/campaign.hpp"
#include "blt/campaign/database.hpp"
#include "blt/campaign/isolated.hpp"
#include "blt/campaign/runner.hpp"
#include "blt/core/error.hpp"
#include "blt/sim/scenario.hpp"

using namespace blt;
using namespace blt::campaign;
namespace fs = std::filesystem;

namespace {

const std::string kScenario = std::string(BLT_DATA_DIR) + "/scenarios/fabric_al_corrected.toml";
const std::string kBlt = std::string(BLT_BINARY_DIR) + "/bin/blt";

fs::path scratch(const std::string& name) { return scratchDir("isolated", name); }

// A stand-in for the blt program: a shell script given as IsolatedRunOptions::executable.
std::string script(const fs::path& path, const std::string& body) {
  std::ofstream(path) << "#!/bin/sh\n" << body;
  fs::permissions(path, fs::perms::owner_all);
  return path.string();
}

}  // namespace

TEST_SUITE("campaign") {

TEST_CASE("campaign: a run in its own process gives the outcome of the same run in process") {
  const sim::ImpactScenario sc = sim::loadScenario(
      kScenario, {"resolution.particle_spacing=0.2mm", "resolution.cell_size=0.4mm", "target.lateral_size=12mm",
                  "run.max_time=8us", "projectile.diameter=1.6mm", "projectile.velocity=7km/s"});
  IsolatedRunOptions o;
  o.executable = kBlt;
  const SimulationOutcome isolated = isolatedSimulator(o)(sc);
  const SimulationOutcome inProcess = simulateImpact(sc);
  INFO(isolated.reason);
  REQUIRE_FALSE(isolated.failed);
  CHECK(isolated.perforated == inProcess.perforated);
  CHECK(isolated.settled == inProcess.settled);
  CHECK(isolated.residualVelocity == relApprox(inProcess.residualVelocity, 1e-12));
  CHECK(isolated.measurements["hole_size_mm"] == inProcess.measurements["hole_size_mm"]);
  CHECK(isolated.measurements["steps"] == inProcess.measurements["steps"]);
}

TEST_CASE("campaign: a run killed with its campaign goes on from its checkpoint when the campaign starts again") {
  // Reference: the same run made straight through in process. The killed run is stood in for by the first half
  // of it (to 4 us of 8), made by the command line into the run's checkpoint directory as the killed child
  // would have left it; the shot perforates only after 4 us, so nothing stops either run before its end.
  const fs::path dir = scratch("checkpoint");
  const std::vector<std::string> settings = {"resolution.particle_spacing=0.2mm", "resolution.cell_size=0.4mm",
                                             "target.lateral_size=12mm", "run.max_time=8us",
                                             "projectile.diameter=1.6mm", "projectile.velocity=7km/s"};
  const sim::ImpactScenario sc = sim::loadScenario(kScenario, settings);
  IsolatedRunOptions o;
  o.executable = kBlt;
  o.checkpointDirectory = (dir / "checkpoints").string();
  o.checkpointSeconds = 3600;
  const fs::path keep = checkpointDirectoryFor(o, sc);
  CHECK(keep.parent_path() == dir / "checkpoints");
  std::string firstHalf = "'" + kBlt + "' sim run '" + kScenario + "'";
  for (const std::string& s : settings) firstHalf += " --set " + s;
  firstHalf += " --set run.max_time=4us --threads 1 --quiet --no-frames --checkpoint-every 1h --out '" + keep.string() +
               "' > /dev/null 2>&1";
  REQUIRE(std::system(firstHalf.c_str()) == 0);
  REQUIRE(fs::exists(keep / (sc.name + "_checkpoint.bin")));
  CHECK_FALSE(fs::exists(keep / (sc.name + ".pvd")));

  const SimulationOutcome resumed = isolatedSimulator(o)(sc);
  const SimulationOutcome straight = simulateImpact(sc);
  INFO(resumed.reason);
  REQUIRE_FALSE(resumed.failed);
  CHECK(resumed.measurements["resumed_at_time_s"].get<double>() == doctest::Approx(4e-6).epsilon(0.01));
  CHECK(resumed.perforated == straight.perforated);
  CHECK(resumed.perforated);
  for (const char* key : {"steps", "time_s", "hole_size_mm", "residual_velocity_m_s", "mass_behind_rear_wall_fraction"})
    CHECK_MESSAGE(resumed.measurements[key] == straight.measurements[key], key);
  CHECK_FALSE(fs::exists(keep));  // the run is recorded: its checkpoint is of no more use

  // With no checkpoint there the run starts from the beginning, and leaves nothing either.
  const SimulationOutcome fresh = isolatedSimulator(o)(sc);
  REQUIRE_FALSE(fresh.failed);
  CHECK(fresh.measurements["resumed_at_time_s"].is_null());
  CHECK(fresh.measurements["steps"] == straight.measurements["steps"]);
  CHECK_FALSE(fs::exists(keep));
  // In process there is nowhere to keep one.
  CHECK_THROWS_WITH_AS(campaignSimulator(true, 1, o.checkpointDirectory, 60), doctest::Contains("--checkpoint-every"),
                       InputError);
}

TEST_CASE("campaign: a run that crashes in its own process is a failed run naming the signal") {
  const fs::path dir = scratch("crash");
  IsolatedRunOptions o;
  o.executable = script(dir / "crashing_blt", "echo 'solver: about to fail' >&2\nkill -SEGV $$\n");
  const sim::ImpactScenario sc = sim::loadScenario(kScenario);
  const SimulationOutcome r = isolatedSimulator(o)(sc);
  CHECK(r.failed);
  CHECK(r.reason.find("crashed: signal 11") != std::string::npos);
  CHECK(r.reason.find("solver: about to fail") != std::string::npos);

  o.executable = script(dir / "failing_blt", "echo 'file x.toml: bad value' >&2\nexit 2\n");
  const SimulationOutcome bad = isolatedSimulator(o)(sc);
  CHECK(bad.failed);
  CHECK(bad.reason.find("exited with status 2: file x.toml: bad value") != std::string::npos);

  o.executable = (dir / "no_such_blt").string();
  CHECK_THROWS_AS(isolatedSimulator(o), InputError);
  fs::remove_all(dir);
}

TEST_CASE("campaign: a point whose runs crash is unresolved with the reason, and the others are resolved") {
  const fs::path dir = scratch("campaign");
  // Crashes at 3 km/s; elsewhere perforated exactly above 1 mm, in the JSON of blt sim run.
  IsolatedRunOptions o;
  o.executable = script(dir / "fake_blt",
                        "case \"$*\" in *projectile.velocity=3000m/s*) kill -SEGV $$ ;; esac\n"
                        "d=$(for a in \"$@\"; do echo \"$a\"; done | sed -n 's/^projectile.diameter=\\(.*\\)m$/\\1/p')\n"
                        "p=$(awk -v d=\"$d\" 'BEGIN { print (d > 0.001) ? \"true\" : \"false\" }')\n"
                        "echo \"{\\\"status\\\": \\\"completed\\\", \\\"perforated\\\": $p, \\\"settled\\\": true, "
                        "\\\"residual_velocity_m_s\\\": 0, \\\"wall_time_s\\\": 0.01}\"\n");
  const std::string text = "name = \"crashy\"\nscenario = \"" + kScenario +
                           "\"\n[bisect]\nvariable = \"diameter\"\nlower = \"0.5 mm\"\nupper = \"2.5 mm\"\n"
                           "tolerance = \"0.05 mm\"\n[grid]\nvelocity = [\"3 km/s\", \"7 km/s\"]\n";
  const Campaign c = parseCampaign(text, (dir / "crashy.toml").string());
  RunDatabase db((dir / "runs.sqlite").string());
  CampaignRunOptions ro;
  ro.simulator = isolatedSimulator(o);
  const CampaignRunResult result = runCampaign(c, db, ro);
  REQUIRE(result.points.size() == 2);
  const PointRecord& crashing = result.points[0];
  const PointRecord& fine = result.points[1];
  CHECK(std::string(toString(crashing.state)) == "unresolved");
  CHECK(crashing.message.find("signal 11") != std::string::npos);
  CHECK(crashing.message.find("again at half the spacing") != std::string::npos);
  CHECK(std::string(toString(fine.state)) == "resolved");
  REQUIRE(fine.largestSafe);
  REQUIRE(fine.smallestPerforating);
  CHECK(*fine.largestSafe <= 1e-3);
  CHECK(*fine.smallestPerforating > 1e-3);
  CHECK(0.5 * (*fine.smallestPerforating - *fine.largestSafe) <= 0.05e-3 + 1e-12);  // the tolerance is a half-width
  fs::remove_all(dir);
}

}  // TEST_SUITE("campaign")
