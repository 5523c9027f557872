// Bisection campaigns (issue 6): the campaign file, the run database, resuming without repeating a run, several
// writers on one file, task split and merge, failed runs, BLE-seeded brackets; and the CLI killed mid-campaign.
#include <doctest/doctest.h>
#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <set>
#include <thread>

#include "blt/ble/christiansen.hpp"
#include "blt/ble/impact_data.hpp"
#include "blt/ble/store.hpp"
#include "blt/campaign/campaign.hpp"
#include "blt/campaign/database.hpp"
#include "blt/campaign/runner.hpp"
#include "raw_db.hpp"
#include "run_blt.hpp"
#include "scratch_dir.hpp"

namespace fs = std::filesystem;
using namespace blt::campaign;

namespace {

fs::path scratch(const std::string& name) { return scratchDir("campaign", name); }

const std::string kScenario = std::string(BLT_DATA_DIR) + "/scenarios/fabric_al_corrected.toml";

fs::path writeFile(const fs::path& path, const std::string& text) {
  std::ofstream(path) << text;
  return path;
}

// A campaign file on the seed 000 scenario with the given body after the scenario line.
std::string campaignText(const std::string& name, const std::string& body) {
  return "name = \"" + name + "\"\nscenario = \"" + kScenario + "\"\n" + body;
}

const std::string kBisect = "[bisect]\nvariable = \"diameter\"\nlower = \"0.5 mm\"\nupper = \"2.5 mm\"\ntolerance = \"0.02 mm\"\n";
const std::string kGrid = "[grid]\nvelocity = [\"2 km/s\", \"3 km/s\", \"4 km/s\", \"5 km/s\", \"7 km/s\"]\nangle = [\"0 deg\", \"45 deg\"]\n";

// A stand-in for the solver: perforated exactly when the diameter exceeds a smooth d_c(V, θ). Deterministic,
// instant, and it counts what it is asked.
double fakeCriticalDiameter(double velocity, double angle) {
  return 1.0e-3 * std::pow(5000.0 / velocity, 0.5) / std::pow(std::cos(angle), 0.4);
}

struct FakeSolver {
  std::atomic<int> calls{0};
  std::mutex mutex;
  std::multiset<std::string> seen;  // "d v a spacing" of every call

  Simulator simulator() {
    return [this](const blt::sim::ImpactScenario& sc) {
      ++calls;
      {
        std::lock_guard lock(mutex);
        seen.insert(exactNumber(sc.projectile.diameter) + " " + exactNumber(sc.projectile.velocity) + " " +
                    exactNumber(sc.projectile.angle) + " " + exactNumber(sc.resolution.particleSpacing));
      }
      SimulationOutcome o;
      o.perforated = sc.projectile.diameter > fakeCriticalDiameter(sc.projectile.velocity, sc.projectile.angle);
      o.settled = true;
      o.wallSeconds = 0.01;
      o.measurements = {{"perforated", o.perforated}, {"fake", true}};
      return o;
    };
  }
};

// What a campaign ends with, for comparing two databases: each point's state and bracket, and the set of
// runs by their input hash with their outcome.
struct Final {
  std::vector<std::tuple<int, std::string, std::optional<double>, std::optional<double>, int>> points;
  std::map<std::string, std::pair<bool, int>> runs;  // hash -> perforated, state
  friend bool operator==(const Final&, const Final&) = default;
};

Final finalOf(const RunDatabase& db, const std::string& campaign) {
  Final f;
  const auto c = db.findCampaign(campaign);
  REQUIRE(c);
  for (const auto& p : db.points(c->id))
    f.points.emplace_back(p.index, toString(p.state), p.largestSafe, p.smallestPerforating, p.runs);
  for (const auto& r : db.runs(c->id)) f.runs[r.scenarioHash] = {r.perforated, static_cast<int>(r.state)};
  return f;
}

// Real MPM runs for the CLI tests, made small (coarse particles, a narrower target, a shorter run, a loose
// tolerance: 5 runs a point) so that the sanitizer build runs them in reasonable time too.
const std::string kQuickCampaign = campaignText(
    "quick",
    "settings = [\"resolution.particle_spacing=0.2mm\", \"resolution.cell_size=0.4mm\", \"target.lateral_size=12mm\", "
    "\"run.max_time=8us\"]\n[bisect]\nlower = \"0.6 mm\"\nupper = \"2.0 mm\"\ntolerance = \"0.1 mm\"\n"
    "[grid]\nvelocity = [\"3 km/s\", \"7 km/s\"]\n");

}  // namespace

TEST_SUITE("campaign") {

TEST_CASE("campaign file: points from a list and a grid with exact settings and paths relative to the file") {
  const fs::path dir = scratch("file");
  const fs::path file = writeFile(
      dir / "c.toml",
      campaignText("c", "settings = [\"resolution.particle_spacing=0.2mm\", \"resolution.cell_size=0.4mm\"]\n" + kBisect +
                            "[[point]]\nvelocity = \"6.5 km/s\"\nangle = \"30 deg\"\nlower = \"0.8 mm\"\nupper = \"1.2 mm\"\n" +
                            kGrid));
  const Campaign c = loadCampaign(file.string());
  CHECK(c.name == "c");
  REQUIRE(c.points.size() == 11);
  CHECK(c.points[0].velocity == doctest::Approx(6500));
  CHECK(c.points[0].angle == doctest::Approx(M_PI / 6));
  CHECK(c.points[0].lower == doctest::Approx(0.8e-3));
  CHECK(c.points[0].line == 9);
  // The grid is angle-major: all velocities at 0 deg, then at 45 deg.
  CHECK(c.points[1].velocity == doctest::Approx(2000));
  CHECK(c.points[6].angle == doctest::Approx(M_PI / 4));
  CHECK(std::isnan(c.points[1].lower));
  // Settings read back to the very doubles.
  const blt::sim::ImpactScenario sc = runScenario(c, [&] {
    auto s = c.settings;
    for (const auto& x : pointSettings(c, c.points[6])) s.push_back(x);
    s.push_back(variableSetting(c, 1.234567891234e-3));
    return s;
  }());
  CHECK(sc.projectile.velocity == c.points[6].velocity);
  CHECK(sc.projectile.angle == c.points[6].angle);
  CHECK(sc.projectile.diameter == 1.234567891234e-3);
  CHECK(sc.resolution.particleSpacing == doctest::Approx(0.2e-3));
  // The definition does not depend on where the files are, only on what they say.
  const fs::path other = scratch("file_moved");
  std::ifstream in(file);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const Campaign moved = parseCampaign(text, (other / "c.toml").string());
  CHECK(moved.definitionHash() == c.definitionHash());
  // The shipped campaigns load.
  for (const char* shipped : {"seed000_quick", "seed000_theta0", "seed000_oblique", "seed000_theta0_seeded"})
    CHECK_NOTHROW(loadCampaign(std::string(BLT_DATA_DIR) + "/campaigns/" + shipped + ".toml"));
  CHECK(loadCampaign(std::string(BLT_DATA_DIR) + "/campaigns/seed000_oblique.toml").points.size() == 22);
}

TEST_CASE("campaign file: a bad file is an error naming the file and line and key") {
  const fs::path dir = scratch("errors");
  const auto errorOf = [&](const std::string& text) {
    const fs::path file = writeFile(dir / "bad.toml", text);
    try {
      loadCampaign(file.string());
    } catch (const blt::InputError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  std::string e = errorOf(campaignText("c", kBisect + kGrid + "colour = \"red\"\n"));
  CHECK(e.find("bad.toml") != std::string::npos);
  CHECK(e.find("line 11") != std::string::npos);
  CHECK(e.find("'grid.colour'") != std::string::npos);
  CHECK(e.find("unknown key") != std::string::npos);

  e = errorOf(campaignText("c", "[bisect]\nlower = \"0.5\"\nupper = \"2.5 mm\"\ntolerance = \"0.02 mm\"\n" + kGrid));
  CHECK(e.find("line 4") != std::string::npos);
  CHECK(e.find("bisect.lower") != std::string::npos);

  e = errorOf(campaignText("c", "[bisect]\nlower = \"2.5 mm\"\nupper = \"0.5 mm\"\ntolerance = \"0.02 mm\"\n" + kGrid));
  CHECK(e.find("bisect.upper") != std::string::npos);
  CHECK(e.find("upper > lower") != std::string::npos);

  e = errorOf(campaignText("c", kBisect + "[grid]\nvelocity = [\"2 km/s\", \"5 mm\"]\n"));
  CHECK(e.find("grid.velocity") != std::string::npos);
  CHECK(e.find("velocity") != std::string::npos);

  e = errorOf(campaignText("c", kBisect + "[[point]]\nvelocity = \"2 km/s\"\n[grid]\nvelocity = [\"2 km/s\"]\n"));
  CHECK(e.find("given twice") != std::string::npos);
  CHECK(e.find("line 8") != std::string::npos);

  e = errorOf(campaignText("c", kBisect + "[[point]]\nvelocity = \"2 km/s\"\nangle = \"90 deg\"\n"));
  CHECK(e.find("point.1.angle") != std::string::npos);

  e = errorOf(campaignText("c", kBisect));
  CHECK(e.find("no points") != std::string::npos);

  e = errorOf("scenario = \"nowhere.toml\"\n" + kBisect + kGrid);
  CHECK(e.find("line 1") != std::string::npos);
  CHECK(e.find("nowhere.toml") != std::string::npos);

  // A setting the scenario refuses fails when the campaign is read, naming the scenario and the key.
  e = errorOf(campaignText("c", "settings = [\"resolution.particle_spacing=1mm\", \"projectile.colour=red\"]\n" + kBisect + kGrid));
  CHECK(e.find("fabric_al_corrected.toml") != std::string::npos);
  CHECK(e.find("colour") != std::string::npos);

  e = errorOf(campaignText("c", "[bisect]\nvariable = \"velocity\"\nlower = \"1 km/s\"\nupper = \"9 km/s\"\n"
                                "tolerance = \"10 m/s\"\n[grid]\ndiameter = [\"1 mm\"]\n[ble]\ndb = \"f.db\"\nfit = \"x\"\n"));
  CHECK(e.find("diameter campaign") != std::string::npos);

  e = errorOf(campaignText("c", kBisect + "[grid]\nvelocity = [\"2 km/s\"]\n[ble]\ndb = \"f.db\"\nfit = \"x\"\nhalf_width = 2\n"));
  CHECK(e.find("ble.half_width") != std::string::npos);
}

TEST_CASE("campaign: every point resolved to the tolerance with its runs recorded and none twice") {
  const fs::path dir = scratch("basic");
  const Campaign c = parseCampaign(campaignText("basic", kBisect + kGrid), (dir / "basic.toml").string());
  RunDatabase db((dir / "runs.sqlite").string());
  FakeSolver fake;
  CampaignRunOptions o;
  o.simulator = fake.simulator();
  const CampaignRunResult r = runCampaign(c, db, o);
  REQUIRE(r.points.size() == 10);
  CHECK_FALSE(r.interrupted);
  for (const auto& p : r.points) {
    CHECK(std::string(toString(p.state)) == "resolved");
    const double dc = fakeCriticalDiameter(p.velocity, p.angle);
    CHECK(*p.largestSafe <= dc);
    CHECK(*p.smallestPerforating > dc);
    CHECK(*p.smallestPerforating - *p.largestSafe <= 2 * c.tolerance + 1e-12);
    // 2 mm wide to +-0.02 mm: the two ends and 6 halvings.
    CHECK(p.runs == 8);
  }
  CHECK(fake.calls == 80);
  CHECK(r.simulated == 80);
  CHECK(r.replayed == 0);
  // Each simulated input once.
  CHECK(std::set<std::string>(fake.seen.begin(), fake.seen.end()).size() == fake.seen.size());
  const auto rec = db.findCampaign("basic");
  REQUIRE(rec);
  CHECK(rec->projectileDensity == doctest::Approx(2770).epsilon(0.02));  // al_2a12
  const auto runs = db.runs(rec->id);
  REQUIRE(runs.size() == 80);
  CHECK(runs[0].toolVersion == std::string(BLT_VERSION) + "+model." + blt::sim::modelFingerprint());
  CHECK(runs[0].toolVersion == blt::sim::buildVersion());
  CHECK(runs[0].measurements.value("fake", false));
  CHECK(runs[0].settings.back().rfind("projectile.diameter=", 0) == 0);
  CHECK(runs[0].scenarioHash == scenarioHash(c.scenarioText, runs[0].settings));

  // Run again: everything replayed, nothing simulated, the same result.
  const auto replayEverything = [&] {
    FakeSolver again;
    o.simulator = again.simulator();
    const CampaignRunResult replay = runCampaign(c, db, o);
    CHECK(again.calls == 0);
    CHECK(replay.replayed == 80);
    CHECK(db.runs(rec->id).size() == 80);
    return replay.replayedFromOtherBuild;
  };
  CHECK(replayEverything() == 0);

  // Runs recorded by another build are still replayed (a resumed campaign repeats nothing) but counted apart.
  RawDb((dir / "runs.sqlite").string()).exec("UPDATE runs SET tool_version = '0.0.1+model.0123456789abcdef' "
                                             "WHERE id IN (SELECT id FROM runs ORDER BY id LIMIT 3)");
  CHECK(replayEverything() == 3);

  // The exported CSV reads back as the same shots.
  const fs::path csv = dir / "runs.csv";
  CHECK(writeImpactCsv(csv.string(), campaignImpactPoints(db, "basic"), "test") == 80);
  const auto points = blt::ble::readImpactCsv(csv.string());
  REQUIRE(points.size() == 80);
  CHECK(points[5].diameter == doctest::Approx(runs[5].diameter).epsilon(1e-12));
  CHECK(points[5].velocity == doctest::Approx(runs[5].velocity).epsilon(1e-12));
  CHECK(points[5].angle == doctest::Approx(runs[5].angle).epsilon(1e-12));
  CHECK(points[5].perforated == runs[5].perforated);
  CHECK(points[5].source == "campaign basic run " + std::to_string(runs[5].id));
  CHECK(points[5].projectileDensity == doctest::Approx(rec->projectileDensity));

  // The same database refuses a changed definition of the campaign.
  const Campaign changed = parseCampaign(campaignText("basic", kBisect + "[grid]\nvelocity = [\"2 km/s\"]\n"),
                                         (dir / "basic.toml").string());
  CHECK_THROWS_WITH_AS(runCampaign(changed, db, o), doctest::Contains("another definition"), blt::InputError);
}

TEST_CASE("campaign: resumed after an interruption it ends as the uninterrupted one without repeating a run") {
  const fs::path dir = scratch("resume");
  const Campaign c = parseCampaign(campaignText("resume", kBisect + kGrid), (dir / "c.toml").string());
  FakeSolver reference;
  RunDatabase whole((dir / "whole.sqlite").string());
  CampaignRunOptions o;
  o.simulator = reference.simulator();
  runCampaign(c, whole, o);

  for (int jobs : {1, 3}) {
    for (int stopAfter : {1, 17, 45, 70}) {
      CAPTURE(jobs);
      CAPTURE(stopAfter);
      const fs::path file = dir / ("part_" + std::to_string(jobs) + "_" + std::to_string(stopAfter) + ".sqlite");
      std::atomic<bool> stop{false};
      FakeSolver first;
      CampaignRunResult interrupted;
      {
        RunDatabase db(file.string());
        CampaignRunOptions oi;
        oi.jobs = jobs;
        const Simulator inner = first.simulator();
        oi.simulator = [&](const blt::sim::ImpactScenario& sc) {
          SimulationOutcome out = inner(sc);
          if (first.calls >= stopAfter) stop = true;
          return out;
        };
        oi.stop = &stop;
        interrupted = runCampaign(c, db, oi);
      }
      CHECK(interrupted.interrupted);
      // The runs in flight when the stop came finish and are kept.
      CHECK(first.calls >= stopAfter);
      CHECK(first.calls < 80);

      FakeSolver second;
      RunDatabase db(file.string());
      CampaignRunOptions o2;
      o2.jobs = jobs;
      o2.simulator = second.simulator();
      const CampaignRunResult resumed = runCampaign(c, db, o2);
      CHECK_FALSE(resumed.interrupted);
      CHECK(first.calls + second.calls == reference.calls);
      CHECK(resumed.replayed == first.calls);
      // No input simulated in both sessions.
      for (const auto& s : second.seen) CHECK(first.seen.count(s) == 0);
      CHECK(finalOf(db, "resume") == finalOf(whole, "resume"));
      CHECK(db.integrityCheck() == "ok");
    }
  }
}

TEST_CASE("campaign: several threads and processes writing one database do not corrupt it") {
  const fs::path dir = scratch("writers");
  const std::string file = (dir / "shared.sqlite").string();
  const auto campaignNamed = [&](const std::string& name) {
    return parseCampaign(campaignText(name, kBisect + kGrid), (dir / (name + ".toml")).string());
  };
  // Processes: each its own connection and campaign, at the same time.
  std::vector<pid_t> children;
  std::fflush(nullptr);
  for (int k = 0; k < 3; ++k) {
    const pid_t pid = fork();
    REQUIRE(pid >= 0);
    if (pid == 0) {
      int code = 0;
      try {
        const Campaign c = campaignNamed("proc" + std::to_string(k));
        RunDatabase db(file);
        FakeSolver fake;
        CampaignRunOptions o;
        o.jobs = 2;
        o.simulator = fake.simulator();
        code = runCampaign(c, db, o).interrupted ? 3 : 0;
      } catch (const std::exception& e) {
        std::fprintf(stderr, "writer process %d: %s\n", k, e.what());
        code = 2;
      } catch (...) {
        code = 2;
      }
      _exit(code);
    }
    children.push_back(pid);
  }
  // Threads of this process meanwhile: each its own connection and campaign, and two sharing one connection.
  {
    RunDatabase sharedConnection(file);
    std::vector<std::thread> threads;
    for (int k = 0; k < 4; ++k)
      threads.emplace_back([&, k] {
        const Campaign c = campaignNamed("thread" + std::to_string(k));
        FakeSolver fake;
        CampaignRunOptions o;
        o.jobs = 2;
        o.simulator = fake.simulator();
        if (k < 2) {
          RunDatabase own(file);
          runCampaign(c, own, o);
        } else {
          runCampaign(c, sharedConnection, o);
        }
      });
    for (auto& t : threads) t.join();
  }
  for (pid_t pid : children) {
    int status = 0;
    REQUIRE(waitpid(pid, &status, 0) == pid);
    CHECK(WIFEXITED(status));
    CHECK(WEXITSTATUS(status) == 0);
  }
  const RunDatabase db(file);
  CHECK(db.integrityCheck() == "ok");
  const auto campaigns = db.campaigns();
  CHECK(campaigns.size() == 7);
  // Each campaign is the same bisection as alone, so the same result as a single writer's.
  RunDatabase alone((dir / "alone.sqlite").string());
  FakeSolver fake;
  CampaignRunOptions o;
  o.simulator = fake.simulator();
  runCampaign(campaignNamed("thread0"), alone, o);
  const Final expected = finalOf(alone, "thread0");
  for (const auto& c : campaigns) {
    CAPTURE(c.name);
    const Final f = finalOf(db, c.name);
    CHECK(f.points == expected.points);
    CHECK(f.runs.size() == expected.runs.size());
  }
}

TEST_CASE("campaign: task split into parts and merged equals one run") {
  const fs::path dir = scratch("tasks");
  const Campaign c = parseCampaign(campaignText("split", kBisect + kGrid), (dir / "c.toml").string());
  RunDatabase whole((dir / "whole.sqlite").string());
  FakeSolver fake;
  CampaignRunOptions o;
  o.simulator = fake.simulator();
  runCampaign(c, whole, o);

  std::set<int> owned;
  for (int i = 1; i <= 3; ++i) {
    RunDatabase part((dir / ("part-" + std::to_string(i) + ".sqlite")).string());
    CampaignRunOptions oi;
    oi.taskIndex = i;
    oi.taskCount = 3;
    oi.simulator = fake.simulator();
    const CampaignRunResult r = runCampaign(c, part, oi);
    for (const auto& p : r.points) {
      CHECK(owned.insert(p.index).second);  // no point in two tasks
      CHECK(p.index % 3 == i - 1);
    }
    // A part refuses another task's share.
    CampaignRunOptions wrong = oi;
    wrong.taskIndex = i % 3 + 1;
    CHECK_THROWS_WITH_AS(runCampaign(c, part, wrong), doctest::Contains("was made for task"), blt::InputError);
  }
  CHECK(owned.size() == c.points.size());

  RunDatabase merged((dir / "merged.sqlite").string());
  int added = 0;
  for (int i = 1; i <= 3; ++i) added += merged.mergeFrom((dir / ("part-" + std::to_string(i) + ".sqlite")).string());
  CHECK(added == 80);
  CHECK(finalOf(merged, "split") == finalOf(whole, "split"));
  // Merging a part again adds nothing.
  CHECK(merged.mergeFrom((dir / "part-2.sqlite").string()) == 0);
  CHECK(finalOf(merged, "split") == finalOf(whole, "split"));
  // The merged file is the whole campaign: running it replays everything.
  FakeSolver none;
  o.simulator = none.simulator();
  const CampaignRunResult again = runCampaign(c, merged, o);
  CHECK(none.calls == 0);
  CHECK(again.replayed == 80);
  // Merged into one of the parts, the part becomes the whole campaign (1/1) too.
  RunDatabase intoPart((dir / "part-1.sqlite").string());
  intoPart.mergeFrom((dir / "part-2.sqlite").string());
  intoPart.mergeFrom((dir / "part-3.sqlite").string());
  CHECK(intoPart.findCampaign("split")->taskIndex == 1);
  CHECK(intoPart.findCampaign("split")->taskCount == 1);
  CHECK(finalOf(intoPart, "split") == finalOf(whole, "split"));
  FakeSolver stillNone;
  o.simulator = stillNone.simulator();
  CHECK(runCampaign(c, intoPart, o).replayed == 80);
  CHECK(stillNone.calls == 0);

  // Parts of another definition are refused.
  const Campaign other = parseCampaign(campaignText("split", kBisect + "[grid]\nvelocity = [\"2 km/s\"]\n"),
                                       (dir / "c.toml").string());
  RunDatabase foreign((dir / "foreign.sqlite").string());
  runCampaign(other, foreign, o);
  CHECK_THROWS_WITH_AS(merged.mergeFrom((dir / "foreign.sqlite").string()), doctest::Contains("another definition"),
                       blt::InputError);
}

TEST_CASE("run database: calibration runs are kept beside the campaigns, a schema-1 file gains their table, merge carries them") {
  const fs::path dir = scratch("calibration_runs");
  const Campaign c = parseCampaign(campaignText("beside", kBisect + kGrid), (dir / "c.toml").string());
  const auto calibrationRun = [](const std::string& key, RunState state) {
    CalibrationRunRecord r;
    r.key = key;
    r.scenario = "target.toml";
    r.settings = {"projectile.diameter=1.2mm"};
    r.scenarioHash = scenarioHash("text", r.settings);
    r.state = state;
    r.reason = state == RunState::failed ? "the run crashed" : "";
    if (state == RunState::completed) r.summary = {{"perforated", true}};
    r.toolVersion = blt::sim::buildVersion();
    return r;
  };
  const std::string oldFile = (dir / "schema1.sqlite").string();
  {
    RunDatabase db(oldFile);
    FakeSolver fake;
    CampaignRunOptions o;
    o.simulator = fake.simulator();
    runCampaign(c, db, o);
  }
  // The file as blt wrote it before calibration runs had a table: schema 1.
  {
    RawDb raw(oldFile);
    raw.exec("DROP TABLE calibration_runs; PRAGMA user_version = 1");
  }
  const int campaignRuns = [&] {
    RunDatabase db(oldFile);
    CHECK(db.calibrationRuns().empty());
    // A completed run replaces a failed one of its key; a second completed one does not replace the first.
    db.recordCalibrationRun(calibrationRun("k1", RunState::failed));
    CHECK(db.findCalibrationRun("k1")->state == RunState::failed);
    CHECK(db.recordCalibrationRun(calibrationRun("k1", RunState::completed)).state == RunState::completed);
    CalibrationRunRecord later = calibrationRun("k1", RunState::completed);
    later.summary = {{"perforated", false}};
    CHECK(db.recordCalibrationRun(later).summary["perforated"] == true);
    CHECK_FALSE(db.findCalibrationRun("k2"));
    return static_cast<int>(db.runs(db.findCampaign("beside")->id).size());
  }();
  CHECK(campaignRuns > 0);
  CHECK(RawDb(oldFile).integer("PRAGMA user_version") == RunDatabase::kSchemaVersion);
  // Merged into a file with a failed run of the same key and one of its own: the completed run wins, both stay.
  const std::string other = (dir / "other.sqlite").string();
  {
    RunDatabase db(other);
    db.recordCalibrationRun(calibrationRun("k1", RunState::failed));
    db.recordCalibrationRun(calibrationRun("k3", RunState::completed));
    CHECK(db.mergeFrom(oldFile) == campaignRuns + 1);
    CHECK(db.findCalibrationRun("k1")->state == RunState::completed);
    CHECK(db.findCalibrationRun("k1")->settings == std::vector<std::string>{"projectile.diameter=1.2mm"});
    CHECK(db.calibrationRuns().size() == 2);
    CHECK(db.mergeFrom(oldFile) == 0);
  }
}

TEST_CASE("campaign: a failed run is recorded and retried at half the spacing and an unresolvable point says why") {
  const fs::path dir = scratch("failures");
  const Campaign c = parseCampaign(campaignText("fail", kBisect + "[grid]\nvelocity = [\"3 km/s\", \"5 km/s\", \"7 km/s\"]\n"),
                                   (dir / "c.toml").string());
  RunDatabase db((dir / "runs.sqlite").string());
  FakeSolver fake;
  const Simulator good = fake.simulator();
  CampaignRunOptions o;
  // At 3 km/s every run at the scenario's spacing (0.1 mm) goes unstable, and fine ones too above 1.6 mm;
  // at 5 km/s the solver throws at 1.5 mm, at any spacing.
  o.simulator = [&](const blt::sim::ImpactScenario& sc) {
    SimulationOutcome out = good(sc);
    const bool coarse = sc.resolution.particleSpacing > 0.09e-3;
    if (sc.projectile.velocity == 3000 && (coarse || sc.projectile.diameter > 1.6e-3)) {
      out.failed = true;
      out.reason = "the run went unstable: the time step collapsed";
    }
    if (sc.projectile.velocity == 5000 && sc.projectile.diameter == 1.5e-3) throw std::runtime_error("out of memory");
    return out;
  };
  const CampaignRunResult r = runCampaign(c, db, o);
  REQUIRE(r.points.size() == 3);
  // 3 km/s: the lower end passes at half spacing, the upper end (2.5 mm) fails both times.
  CHECK(std::string(toString(r.points[0].state)) == "unresolved");
  CHECK(r.points[0].message.find("2.5 mm") != std::string::npos);
  CHECK(r.points[0].message.find("time step collapsed") != std::string::npos);
  CHECK(r.points[0].message.find("again at half the spacing") != std::string::npos);
  // 5 km/s: 1.5 mm is the first midpoint; it throws at both resolutions.
  CHECK(std::string(toString(r.points[1].state)) == "unresolved");
  CHECK(r.points[1].message.find("out of memory") != std::string::npos);
  // 7 km/s untouched by either.
  CHECK(std::string(toString(r.points[2].state)) == "resolved");
  const auto runs = db.runs(db.findCampaign("fail")->id);
  int failed = 0, retries = 0;
  for (const auto& run : runs) {
    failed += run.state == RunState::failed;
    if (run.attempt == 1) {
      ++retries;
      CHECK(run.settings.back() == "resolution.cell_size=" + exactNumber(0.1e-3) + "m");
      CHECK(run.settings[run.settings.size() - 2] == "resolution.particle_spacing=" + exactNumber(0.05e-3) + "m");
    }
    if (run.state == RunState::failed) CHECK_FALSE(run.reason.empty());
  }
  CHECK(failed == 5);   // 3 km/s: 0.5 coarse, 2.5 coarse and fine; 5 km/s: 1.5 coarse and fine
  CHECK(retries == 3);  // 3 km/s at 0.5 and 2.5 mm, 5 km/s at 1.5 mm
  CHECK(r.failed == 5);
  // The failures are replayed like any run: a second session simulates nothing.
  FakeSolver none;
  o.simulator = none.simulator();
  const CampaignRunResult again = runCampaign(c, db, o);
  CHECK(none.calls == 0);
  CHECK(again.points[0].message == r.points[0].message);
}

TEST_CASE("campaign: brackets seeded from a BLE fit take fewer runs and widen when they do not hold") {
  const fs::path dir = scratch("seeded");
  // A store with seed 000's Table 8 BLE, stood for by the fake solver's truth at 2-5 km/s within +-10 %.
  blt::ble::StoredFit fit;
  fit.name = "table8";
  fit.result.coefficients = blt::ble::ChristiansenCoefficients::seed000Table8();
  fit.toolVersion = BLT_VERSION;
  {
    blt::ble::BleStore store((dir / "fits.db").string());
    store.saveFit(fit, false);
  }
  const std::string grid = "[grid]\nvelocity = [\"2 km/s\", \"3 km/s\", \"5 km/s\", \"7 km/s\", \"9 km/s\"]\n";
  const Campaign plain = parseCampaign(campaignText("plain", kBisect + grid), (dir / "plain.toml").string());
  const Campaign seeded = parseCampaign(
      campaignText("seeded", kBisect + grid + "[ble]\ndb = \"fits.db\"\nfit = \"table8\"\nhalf_width = 0.1\n"),
      (dir / "seeded.toml").string());
  REQUIRE(seeded.ble);
  CHECK(seeded.ble->db == (dir / "fits.db").string());
  FakeSolver a, b;
  RunDatabase db((dir / "runs.sqlite").string());
  CampaignRunOptions o;
  o.simulator = a.simulator();
  const CampaignRunResult rp = runCampaign(plain, db, o);
  o.simulator = b.simulator();
  const CampaignRunResult rs = runCampaign(seeded, db, o);
  int widened = 0;
  for (std::size_t i = 0; i < rs.points.size(); ++i) {
    const PointRecord& p = rs.points[i];
    CAPTURE(p.label);
    CHECK(std::string(toString(p.state)) == "resolved");
    CHECK(p.bracketOrigin.find("ble fit table8") == 0);
    const double dc = fakeCriticalDiameter(p.velocity, p.angle);
    CHECK(*p.largestSafe <= dc);
    CHECK(*p.smallestPerforating > dc);
    CHECK(*p.smallestPerforating - *p.largestSafe <= 2 * seeded.tolerance + 1e-12);
    if (!(dc >= p.bracketLower && dc < p.bracketUpper)) ++widened;
  }
  // The fake truth lies outside the fit's +-10 % at some points (the bracket had to widen) and inside at others.
  CHECK(widened > 0);
  CHECK(widened < static_cast<int>(rs.points.size()));
  CHECK(b.calls < a.calls);
  MESSAGE("runs without seeding: " << a.calls.load() << ", seeded from the BLE: " << b.calls.load());

  // Resuming needs no store: the first brackets were recorded with the points.
  fs::remove(dir / "fits.db");
  FakeSolver none;
  o.simulator = none.simulator();
  CHECK(runCampaign(seeded, db, o).replayed == b.calls);
  CHECK(none.calls == 0);
}

TEST_CASE("campaign CLI: killed mid-campaign the database is consistent and the rerun repeats no run") {
  const fs::path dir = scratch("kill");
  const fs::path file = writeFile(
      dir / "quick.toml",
      kQuickCampaign);
  const std::string exe = std::string(BLT_BINARY_DIR) + "/bin/blt";
  const std::string killed = (dir / "killed.sqlite").string();
  const fs::path temp = dir / "tmp";  // the killed campaign's temporary directory, to see what it leaves there
  fs::create_directories(temp);

  std::fflush(nullptr);  // else the child's copy of unwritten test output would be written twice
  const pid_t pid = fork();
  REQUIRE(pid >= 0);
  if (pid == 0) {
    const int devNull = open("/dev/null", O_WRONLY);
    dup2(devNull, 1);
    dup2(devNull, 2);
    setenv("TMPDIR", temp.c_str(), 1);
    execl(exe.c_str(), exe.c_str(), "campaign", "run", file.c_str(), "--db", killed.c_str(), "--jobs", "2", "--quiet",
          static_cast<char*>(nullptr));
    _exit(127);
  }
  // Kill it once a few runs are recorded (not at a point boundary: the runs of two points are in flight).
  std::size_t before = 0;
  bool exitedEarly = false;
  while (true) {
    int status = 0;
    if (waitpid(pid, &status, WNOHANG) == pid) {
      exitedEarly = true;
      break;
    }
    if (fs::exists(killed)) {
      try {
        const RunDatabase db(killed);
        if (auto c = db.findCampaign("quick"); c && db.runs(c->id).size() >= 3) break;
      } catch (const blt::InputError&) {
        // Created but its schema not yet committed: look again.
      }
    }
    usleep(5000);
  }
  REQUIRE_FALSE(exitedEarly);
  REQUIRE(kill(pid, SIGKILL) == 0);
  int status = 0;
  REQUIRE(waitpid(pid, &status, 0) == pid);
  CHECK(WIFSIGNALED(status));
  // The capture files of the runs it had in flight went with it.
  for (const auto& entry : fs::directory_iterator(temp))
    CHECK_MESSAGE(entry.path().filename().string().rfind("blt-run-", 0) != 0, "left behind: ", entry.path().string());
  {
    const RunDatabase db(killed);
    CHECK(db.integrityCheck() == "ok");
    const auto c = db.findCampaign("quick");
    REQUIRE(c);
    before = db.runs(c->id).size();
    const auto points = db.points(c->id);
    CHECK(points.size() == 2);
    bool unfinished = false;
    for (const auto& p : points) unfinished |= p.state != PointState::resolved;
    CHECK(unfinished);
  }
  CHECK(before >= 3);

  const BltRun rerun = runBlt("campaign run '" + file.string() + "' --db '" + killed + "' --jobs 2 --json --quiet");
  REQUIRE(rerun.status == 0);
  const auto doc = nlohmann::json::parse(rerun.output);
  CHECK(doc["runs_replayed"].get<std::size_t>() == before);
  CHECK(doc["interrupted"] == false);
  const BltRun whole = runBlt("campaign run '" + file.string() + "' --db '" + (dir / "whole.sqlite").string() +
                              "' --jobs 2 --json --quiet");
  REQUIRE(whole.status == 0);
  const auto wholeDoc = nlohmann::json::parse(whole.output);
  // Every run the killed session recorded was used again, none made twice, and the result is an uninterrupted one.
  CHECK(doc["runs_replayed"].get<int>() + doc["runs_simulated"].get<int>() == wholeDoc["runs_simulated"].get<int>());
  CHECK(doc["points"] == wholeDoc["points"]);
  const RunDatabase db(killed);
  CHECK(finalOf(db, "quick") == finalOf(RunDatabase((dir / "whole.sqlite").string()), "quick"));

  // status, export and a fit straight from the database.
  const BltRun st = runBlt("campaign status --db '" + killed + "' --json");
  REQUIRE(st.status == 0);
  CHECK(nlohmann::json::parse(st.output)["campaigns"][0]["point_states"]["resolved"] == 2);
  const std::string csv = (dir / "quick.csv").string();
  REQUIRE(runBlt("campaign export --db '" + killed + "' --csv '" + csv + "'").status == 0);
  CHECK(blt::ble::readImpactCsv(csv).size() == wholeDoc["runs_simulated"].get<std::size_t>());
  const BltRun fitRun = runBlt("ble fit " + std::string(BLT_DATA_DIR) + "/seed/seed000_table1_tests.csv --method classify --density 2770kg/m3 "
                               "--campaign quick --campaign-db '" + killed + "' --db '" + (dir / "fits.db").string() +
                               "' --name quick --json");
  CHECK_MESSAGE(fitRun.status == 0, fitRun.output);
  const BltRun bad = runBlt("campaign status --db '" + (dir / "missing.sqlite").string() + "'");
  CHECK(bad.status == 2);
  CHECK(bad.output.find("--db") != std::string::npos);
}

}  // TEST_SUITE

#ifdef BLT_HAVE_MPI
TEST_CASE("campaign CLI: under mpirun rank 0 records what the other ranks simulate as without MPI" *
          doctest::test_suite("campaign")) {
  const fs::path dir = scratch("mpi");
  const fs::path file = writeFile(
      dir / "quick.toml",
      kQuickCampaign);
  const std::string db = (dir / "mpi.sqlite").string();
  // OpenMPI refuses root unless told; LeakSanitizer (CI's sanitizer build) reports OpenMPI's own allocations.
  const std::string command = std::string("OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 ASAN_OPTIONS=detect_leaks=0 '") +
                              BLT_MPIEXEC + "' -n 3 --oversubscribe '" + BLT_BINARY_DIR + "/bin/blt' campaign run '" +
                              file.string() + "' --db '" + db + "' --mpi --json --quiet 2>/dev/null";
  std::string output;
  FILE* pipe = popen(command.c_str(), "r");
  REQUIRE(pipe != nullptr);
  char buf[512];
  while (fgets(buf, sizeof buf, pipe)) output += buf;
  const int raw = pclose(pipe);
  REQUIRE_MESSAGE(WIFEXITED(raw), output);
  REQUIRE_MESSAGE(WEXITSTATUS(raw) == 0, output);
  const auto doc = nlohmann::json::parse(output);
  CHECK(doc["mpi_ranks"] == 3);
  CHECK(doc["runs_replayed"] == 0);
  CHECK(doc["resolved"] == 2);
  // Without MPI on the same file every run is found by its input hash: the same runs, the same bisections.
  const BltRun plain = runBlt("campaign run '" + file.string() + "' --db '" + db + "' --json --quiet");
  REQUIRE(plain.status == 0);
  const auto again = nlohmann::json::parse(plain.output);
  CHECK(again["runs_simulated"] == 0);
  CHECK(again["runs_replayed"] == doc["runs_simulated"]);
  CHECK(again["points"] == doc["points"]);
}
#endif
