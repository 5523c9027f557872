// blt campaign: bisection campaigns (many ballistic-limit points of one scenario) run concurrently and resumably
// into an SQLite run database; their status, their runs as binary impact data, and the merging of task parts.
// blt bench campaign: wall time and runs of a campaign run from scratch, with and without BLE-seeded brackets.
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <functional>
#include <iostream>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>

#include "blt/ble/fit.hpp"
#include "blt/ble/impact_data.hpp"
#include "blt/ble/store.hpp"
#include "blt/campaign/bench.hpp"
#include "blt/campaign/campaign.hpp"
#include "blt/campaign/database.hpp"
#include "blt/campaign/isolated.hpp"
#include "blt/campaign/mpi.hpp"
#include "blt/campaign/runner.hpp"
#include "cli_support.hpp"
#include "commands.hpp"

namespace blt::cli {

namespace {

using namespace blt::campaign;

bool isDiameter(const std::string& variable) { return variable == "diameter"; }
const char* unitOf(const std::string& variable) { return isDiameter(variable) ? "mm" : "m/s"; }
std::string keySuffix(const std::string& variable) { return isDiameter(variable) ? "_mm" : "_m_s"; }

nlohmann::json pointJson(const PointRecord& p, const std::string& variable) {
  const std::string k = keySuffix(variable);
  const auto value = [&](const std::optional<double>& v) {
    return v ? nlohmann::json(units::toUnit(*v, unitOf(variable))) : nlohmann::json();
  };
  const bool resolved = p.state == PointState::resolved;
  nlohmann::json j = {{"index", p.index},
                      {"point", p.label},
                      {"angle_deg", units::toUnit(p.angle, "deg")},
                      {"state", toString(p.state)},
                      {"largest_not_perforating" + k, value(p.largestSafe)},
                      {"smallest_perforating" + k, value(p.smallestPerforating)},
                      {"estimate" + k, resolved ? value(0.5 * (*p.largestSafe + *p.smallestPerforating)) : nlohmann::json()},
                      {"half_width" + k,
                       resolved ? value(0.5 * (*p.smallestPerforating - *p.largestSafe)) : nlohmann::json()},
                      {"runs", p.runs},
                      {"first_bracket" + k,
                       {units::toUnit(p.bracketLower, unitOf(variable)), units::toUnit(p.bracketUpper, unitOf(variable))}},
                      {"bracket_origin", p.bracketOrigin},
                      {"message", p.message}};
  if (isDiameter(variable)) j["velocity_km_s"] = units::toUnit(p.velocity, "km/s");
  else j["diameter_mm"] = units::toUnit(p.diameter, "mm");
  return j;
}

void printPoints(const std::vector<PointRecord>& points, const std::string& variable) {
  const char* unit = unitOf(variable);
  std::printf("  %-22s %-10s %-24s %5s  %s\n", "point", "state", ("ballistic limit (" + std::string(unit) + ")").c_str(),
              "runs", "first bracket");
  for (const auto& p : points) {
    std::string limit = "-";
    if (p.state == PointState::resolved) {
      char buf[64];
      std::snprintf(buf, sizeof buf, "%.5g +- %.2g", units::toUnit(0.5 * (*p.largestSafe + *p.smallestPerforating), unit),
                    units::toUnit(0.5 * (*p.smallestPerforating - *p.largestSafe), unit));
      limit = buf;
    }
    std::printf("  %-22s %-10s %-24s %5d  %s\n", p.label.c_str(), toString(p.state), limit.c_str(), p.runs,
                p.bracketOrigin.c_str());
    if (p.state == PointState::unresolved) std::printf("      unresolved: %s\n", p.message.c_str());
  }
}

constexpr const char* kInProcessHelp =
    "Run the simulations on threads of this process instead of one blt process each (a crashing run then ends "
    "the campaign; what was recorded stays)";

// ---- blt campaign run --------------------------------------------------------------------------------------------

struct RunCommandOptions {
  std::string file, db, task = "1/1", bleDb;
  int jobs = 1;
  double checkpointSeconds = 0;
  bool json = false, quiet = false, mpi = false, inProcess = false;
};

void runCommand(const RunCommandOptions& o) {
  Campaign c = loadCampaign(o.file);
  if (!o.bleDb.empty()) {
    if (!c.ble)
      throw InputError(InputLocation::flag("--ble-db"), "campaign " + o.file + " has no [ble] table to seed from",
                       "a campaign with [ble] fit = NAME, or no --ble-db");
    c.ble->db = o.bleDb;
  }
  const auto [taskIndex, taskCount] = parseTask(o.task, InputLocation::flag("--task"));
  CampaignRunOptions ro;
  ro.jobs = o.jobs;
  ro.taskIndex = taskIndex;
  ro.taskCount = taskCount;
  if (o.mpi && o.checkpointSeconds > 0)
    throw InputError(InputLocation::flag("--checkpoint-every"), "MPI ranks run in process and keep no checkpoints",
                     "no --mpi, or no --checkpoint-every");
  // Beside the database: a run's checkpoint belongs with the record it will become.
  if (!o.mpi) ro.simulator = campaignSimulator(o.inProcess, 1, o.db + ".checkpoints", o.checkpointSeconds);
  const bool tty = isatty(fileno(stderr)) != 0;
  if (!o.quiet && !o.json && !o.mpi) {
    std::fprintf(stderr, "campaign %s: %zu points (%s), %s bisection, base scenario %s; %d at once; database %s\n",
                 c.name.c_str(), c.points.size(), taskCount > 1 ? ("task " + o.task).c_str() : "all",
                 sim::toString(c.variable), c.scenarioPath.c_str(), o.jobs, o.db.c_str());
  }
  if (!o.quiet)
    ro.progress = [tty, json = o.json](const CampaignProgress& p) {
      char line[256];
      std::snprintf(line, sizeof line, "points %d/%d, runs %d (%d simulated, %d replayed, %d failed), %s elapsed, ETA %s",
                    p.pointsDone, p.pointsTotal, p.simulated + p.replayed, p.simulated, p.replayed, p.failed,
                    wallClock(p.elapsedSeconds).c_str(), wallClock(p.etaSeconds).c_str());
      if (tty && !json) {
        // The event above the live line, the live line redrawn under it.
        std::fprintf(stderr, "\r\033[K  %s\n%s", p.event.c_str(), line);
      } else {
        std::fprintf(stderr, "[%s] %s | %s\n", wallClock(p.elapsedSeconds).c_str(), p.event.c_str(), line);
      }
      std::fflush(stderr);
    };
  CampaignRunResult r;
  int ranks = 0;
  if (o.mpi) {
    const MpiRunResult m = runCampaignMpi(c, o.db, ro);
    if (!m.coordinator) return;  // rank 0 reports
    r = m.result;
    ranks = m.ranks;
  } else {
    RunDatabase db(o.db);
    r = runCampaign(c, db, ro);
    if (o.checkpointSeconds > 0 && !r.interrupted) {
      std::error_code ignored;
      std::filesystem::remove(o.db + ".checkpoints", ignored);  // only when empty: every run in it has ended
    }
  }
  if (!o.quiet && tty && !o.json) std::fprintf(stderr, "\n");

  const std::string variable = sim::toString(c.variable);
  int resolved = 0, runs = 0;
  for (const auto& p : r.points) {
    resolved += p.state == PointState::resolved;
    runs += p.runs;
  }
  const double perPoint = r.points.empty() ? 0.0 : static_cast<double>(runs) / static_cast<double>(r.points.size());
  if (o.json) {
    nlohmann::json points = nlohmann::json::array();
    for (const auto& p : r.points) points.push_back(pointJson(p, variable));
    printJson({{"campaign", c.name},
               {"db", o.db},
               {"task", o.task},
               {"jobs", o.mpi ? ranks - 1 : o.jobs},
               {"mpi_ranks", ranks},
               {"points", points},
               {"resolved", resolved},
               {"runs_simulated", r.simulated},
               {"runs_replayed", r.replayed},
               {"runs_replayed_from_other_build", r.replayedFromOtherBuild},
               {"runs_failed", r.failed},
               {"runs_per_point", perPoint},
               {"wall_time_s", r.wallSeconds},
               {"simulated_wall_time_s", r.simulatedSeconds},
               {"interrupted", r.interrupted}});
    return;
  }
  std::printf("campaign %s (%s), database %s:\n", c.name.c_str(), taskCount > 1 ? ("task " + o.task).c_str() : "all points",
              o.db.c_str());
  printPoints(r.points, variable);
  std::printf("%d of %zu points resolved; %d runs simulated (%d failed), %d replayed from the database; %.3g runs per "
              "point; wall time %s (simulations %s)\n",
              resolved, r.points.size(), r.simulated, r.failed, r.replayed, perPoint, wallClock(r.wallSeconds).c_str(),
              wallClock(r.simulatedSeconds).c_str());
  if (r.replayedFromOtherBuild > 0)
    std::printf("note: %d of the replayed runs were recorded by another build of blt (its tool_version, with the model "
                "fingerprint, differs from this one's, %s), so this build might judge them otherwise; a new "
                "--db reruns everything with this build\n",
                r.replayedFromOtherBuild, sim::buildVersion().c_str());
}

// ---- blt campaign status -----------------------------------------------------------------------------------------

void requireDatabase(const std::string& path) {
  if (!std::filesystem::exists(path))
    throw InputError(InputLocation::flag("--db"), "no such file '" + path + "'",
                     "a run database made by 'blt campaign run CAMPAIGN --db FILE'");
}

std::vector<CampaignRecord> selectCampaigns(const RunDatabase& db, const std::string& name) {
  if (name.empty()) return db.campaigns();
  const auto c = db.findCampaign(name);
  if (!c) {
    std::string names;
    for (const auto& other : db.campaigns()) names += (names.empty() ? "" : ", ") + other.name;
    throw InputError(InputLocation::flag("--campaign"), "no campaign '" + name + "' in " + db.path(),
                     names.empty() ? "none: the database is empty" : "one of: " + names);
  }
  return {*c};
}

struct StatusOptions {
  std::string db, campaign;
  bool json = false;
};

void statusCommand(const StatusOptions& o) {
  requireDatabase(o.db);
  const RunDatabase db(o.db);
  nlohmann::json list = nlohmann::json::array();
  for (const CampaignRecord& c : selectCampaigns(db, o.campaign)) {
    const auto points = db.points(c.id);
    const auto runs = db.runs(c.id);
    int failed = 0;
    double wall = 0;
    for (const auto& r : runs) {
      failed += r.state == RunState::failed;
      wall += r.wallSeconds;
    }
    std::map<std::string, int> states;
    for (const auto& p : points) ++states[toString(p.state)];
    const std::size_t defined = c.definition.value("points", nlohmann::json::array()).size();
    if (o.json) {
      nlohmann::json pj = nlohmann::json::array();
      for (const auto& p : points) pj.push_back(pointJson(p, c.variable));
      list.push_back({{"campaign", c.name},
                      {"variable", c.variable},
                      {"task", std::to_string(c.taskIndex) + "/" + std::to_string(c.taskCount)},
                      {"points_defined", defined},
                      {"points", pj},
                      {"point_states", states},
                      {"runs", runs.size()},
                      {"runs_failed", failed},
                      {"simulated_wall_time_s", wall},
                      {"definition_hash", c.definitionHash},
                      {"created_utc", c.createdUtc}});
      continue;
    }
    std::printf("campaign %s: %s bisection, %zu of %zu points in this file (task %d/%d), %zu runs (%d failed), "
                "simulation time %s\n",
                c.name.c_str(), c.variable.c_str(), points.size(), defined, c.taskIndex, c.taskCount, runs.size(),
                failed, wallClock(wall).c_str());
    std::string summary;
    for (const auto& [state, n] : states) summary += (summary.empty() ? "" : ", ") + std::to_string(n) + " " + state;
    std::printf("  points: %s\n", summary.c_str());
    printPoints(points, c.variable);
  }
  if (o.json) printJson({{"db", o.db}, {"campaigns", list}});
  else if (list.empty() && db.campaigns().empty()) std::printf("no campaigns in %s\n", o.db.c_str());
}

// ---- blt campaign export -----------------------------------------------------------------------------------------

struct ExportOptions {
  std::string db, csv, campaign;
  bool json = false;
};

void exportCommand(const ExportOptions& o) {
  requireDatabase(o.db);
  const RunDatabase db(o.db);
  std::vector<ble::ImpactPoint> points;
  std::string names;
  for (const CampaignRecord& c : selectCampaigns(db, o.campaign)) {
    const auto more = campaignImpactPoints(db, c.name);
    points.insert(points.end(), more.begin(), more.end());
    names += (names.empty() ? "" : ", ") + c.name;
  }
  const int rows = writeImpactCsv(o.csv, points,
                                  "binary impact data: every completed run of campaign(s) " + names + " in " + o.db +
                                      " (blt " + BLT_VERSION + "), one shot per row");
  if (o.json) return printJson({{"csv", o.csv}, {"rows", rows}, {"campaigns", names}});
  std::printf("wrote %s: %d runs of %s\n", o.csv.c_str(), rows, names.empty() ? "no campaign" : names.c_str());
}

// ---- blt campaign merge ------------------------------------------------------------------------------------------

struct MergeOptions {
  std::vector<std::string> parts;
  std::string db;
  bool json = false;
};

void mergeCommand(const MergeOptions& o) {
  for (const auto& part : o.parts)
    if (std::filesystem::exists(o.db) && std::filesystem::equivalent(part, o.db))
      throw InputError(InputLocation::flag("--db"), "the merged database is also one of the parts (" + part + ")",
                       "a --db file other than the parts");
  if (const auto folder = std::filesystem::path(o.db).parent_path(); !folder.empty())
    std::filesystem::create_directories(folder);
  RunDatabase db(o.db);
  nlohmann::json added = nlohmann::json::object();
  for (const auto& part : o.parts) {
    const int n = db.mergeFrom(part);
    added[part] = n;
    if (!o.json) std::printf("merged %s: %d runs added\n", part.c_str(), n);
  }
  if (o.json) printJson({{"db", o.db}, {"runs_added", added}});
}


// ---- blt bench campaign ------------------------------------------------------------------------------------------

namespace fs = std::filesystem;

// Issue 6: the theta = 0 campaign at the seed's resolution on 2 cores in under 15 minutes.
constexpr double kBenchTargetSeconds = 15 * 60;

struct BenchCampaignOptions {
  std::string campaign = std::string(BLT_DATA_DIR) + "/campaigns/seed000_theta0.toml";
  std::string seeded = std::string(BLT_DATA_DIR) + "/campaigns/seed000_theta0_seeded.toml";
  std::string bleDb;
  int jobs = 2, threads = 1;
  bool quick = false, json = false, quiet = false, keep = false, inProcess = false;
};

// A campaign file as given (relative to the working directory), else relative to the checkout, so that
// data/campaigns/NAME.toml is found from anywhere.
std::string benchCampaignPath(const std::string& given) {
  if (fs::exists(given) || fs::path(given).is_absolute()) return given;
  const fs::path inCheckout = fs::path(BLT_DATA_DIR).parent_path() / given;
  return fs::exists(inCheckout) ? inCheckout.string() : given;
}

// The fit a seeded campaign names, when its store holds it; else made into `dir` as
// data/campaigns/seed000_theta0_seeded.toml's header says (seed 000's Table 1 tests and Table 7, 2770 kg/m3), and
// the seed pointed at it. Returns where the fit came from, one line.
std::string benchSeedFit(BleSeed& seed, const fs::path& dir) {
  std::string why;
  if (seed.db.empty()) {
    why = "no BLE store given";
  } else if (!fs::exists(seed.db)) {
    why = "no BLE store " + seed.db;
  } else {
    const ble::BleStore store(seed.db);
    if (store.hasFit(seed.fit)) return "stored fit '" + seed.fit + "' in " + seed.db;
    why = seed.db + " has no fit '" + seed.fit + "'";
  }
  const auto start = std::chrono::steady_clock::now();
  ble::FitOptions options;
  options.defaultProjectileDensity = 2770;  // 2A12, seed 000's projectiles
  std::vector<ble::ImpactPoint> points;
  std::string origin;
  for (const char* name : {"seed000_table1_tests.csv", "seed000_table7_mpm.csv"}) {
    const std::string file = std::string(BLT_DATA_DIR) + "/seed/" + name;
    const auto read = ble::readImpactCsv(file);
    points.insert(points.end(), read.begin(), read.end());
    origin += (origin.empty() ? "" : "; ") + file;
  }
  ble::FitResult result = ble::fitChristiansen(points, options);
  const std::size_t pointCount = points.size();
  const ble::StoredFit stored = ble::storedFit(seed.fit, options, std::move(result), std::move(points), origin);
  const std::string path = (dir / "fits.db").string();
  ble::BleStore(path).saveFit(stored, false);
  seed.db = path;
  char took[32];
  std::snprintf(took, sizeof took, "%.2g s",
                std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  return why + "; made fit '" + seed.fit + "' from seed 000 Table 1 tests + Table 7 (" + std::to_string(pointCount) +
         " points, 2770 kg/m3, " + ble::toString(stored.result.method) + ") into " + path + " in " + took;
}

nlohmann::json benchJson(const CampaignBenchmark& b, const Campaign& c, const std::string& brackets) {
  nlohmann::json points = nlohmann::json::array();
  for (const auto& p : b.pointRecords) points.push_back(pointJson(p, sim::toString(c.variable)));
  return {{"campaign", b.campaign},
          {"file", c.path},
          {"brackets", brackets},
          {"wall_time_s", b.wallSeconds},
          {"wall_time_min", b.wallSeconds / 60},
          {"simulated_wall_time_s", b.simulatedSeconds},
          {"points", b.points},
          {"points_resolved", b.resolved},
          {"points_unresolved", b.unresolved},
          {"runs", b.runs},
          {"runs_failed", b.runsFailed},
          {"runs_replayed", b.runsReplayed},
          {"runs_per_point_mean", b.runsPerPointMean},
          {"runs_per_point_max", b.runsPerPointMax},
          {"target_wall_time_s", kBenchTargetSeconds},
          {"target_met", b.wallSeconds < kBenchTargetSeconds && b.unresolved == 0 && !b.interrupted},
          {"point_results", points}};
}

void printBench(const CampaignBenchmark& b, const Campaign& c, const std::string& brackets) {
  std::printf("%s (%s), brackets: %s\n", b.campaign.c_str(), c.path.c_str(), brackets.c_str());
  printPoints(b.pointRecords, sim::toString(c.variable));
  std::printf("  wall time %.1f s (%.2f min), summed run time %.1f s\n", b.wallSeconds, b.wallSeconds / 60,
              b.simulatedSeconds);
  std::printf("  %d points: %d resolved, %d unresolved\n", b.points, b.resolved, b.unresolved);
  std::printf("  %d runs (%d failed%s), runs per point %.2f mean, %d max\n", b.runs, b.runsFailed,
              b.runsReplayed ? (", " + std::to_string(b.runsReplayed) + " repeated values replayed").c_str() : "",
              b.runsPerPointMean, b.runsPerPointMax);
  const bool met = b.wallSeconds < kBenchTargetSeconds && b.unresolved == 0;
  std::printf("  target (whole campaign in under %.0f min): %s\n", kBenchTargetSeconds / 60,
              met ? "met" : (b.unresolved ? "missed (points unresolved)" : "missed"));
}

void benchCampaign(const BenchCampaignOptions& o) {
  if (o.jobs < 1)
    throw InputError(InputLocation::flag("--jobs"), "'" + std::to_string(o.jobs) + "' points at once", "1, 2, ...");
  if (o.threads < 0)
    throw InputError(InputLocation::flag("--threads"), "thread count must not be negative", "1, 2, ... (0: all cores)");
  const std::string quick = std::string(BLT_DATA_DIR) + "/campaigns/seed000_quick.toml";
  const Campaign plain = loadCampaign(o.quick ? quick : benchCampaignPath(o.campaign));
  Campaign seeded = loadCampaign(o.quick ? quick : benchCampaignPath(o.seeded));
  if (!o.bleDb.empty()) {
    if (!seeded.ble) seeded.ble = BleSeed{};
    seeded.ble->db = o.bleDb;
  }
  std::string skipped;
  bool addedSeed = false;
  if (seeded.variable != sim::BisectVariable::diameter) {
    skipped = "campaign " + seeded.path + " bisects on velocity; BLE seeding is for diameter campaigns only";
  } else if (!seeded.ble || seeded.ble->fit.empty()) {
    // A file without [ble] (seed000_quick.toml): seeded as seed000_theta0_seeded.toml is, fit seed000, +-10 %.
    const std::string db = seeded.ble ? seeded.ble->db : "";
    seeded.ble = BleSeed{};
    seeded.ble->db = db;
    seeded.ble->fit = "seed000";
    seeded.name += "_seeded";
    addedSeed = true;
  }

  // Fresh databases: nothing replayed from an earlier session.
  const fs::path dir = fs::temp_directory_path() /
                       ("blt_bench_campaign_" + std::to_string(::getpid()) + "_" + std::to_string(std::time(nullptr)));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const unsigned cores = std::thread::hardware_concurrency();
  if (!o.quiet)
    std::fprintf(stderr, "bench campaign: %d points at once, %d thread(s) per run, %u cores seen; run databases in %s\n",
                 o.jobs, o.threads, cores, dir.string().c_str());

  CampaignRunOptions ro;
  ro.jobs = o.jobs;
  ro.simulator = campaignSimulator(o.inProcess, o.threads);
  const auto progressFor = [&o](const std::string& name) -> std::function<void(const CampaignProgress&)> {
    if (o.quiet) return {};
    return [name](const CampaignProgress& p) {
      std::fprintf(stderr, "[%s] %s: %s | points %d/%d, runs %d, ETA %s\n", wallClock(p.elapsedSeconds).c_str(),
                   name.c_str(), p.event.c_str(), p.pointsDone, p.pointsTotal, p.simulated + p.replayed,
                   wallClock(p.etaSeconds).c_str());
      std::fflush(stderr);
    };
  };

  ro.progress = progressFor(plain.name);
  const std::string plainBrackets = plain.ble ? "BLE fit '" + plain.ble->fit + "' (the campaign's [ble])" : "the campaign's";
  const CampaignBenchmark a = benchmarkCampaign(plain, (dir / "unseeded.sqlite").string(), ro);

  std::optional<CampaignBenchmark> b;
  std::string seededBrackets;
  if (skipped.empty()) {
    try {
      const std::string fit = benchSeedFit(*seeded.ble, dir);
      char width[32];
      std::snprintf(width, sizeof width, "%.3g", 100 * seeded.ble->halfWidth);
      seededBrackets = "BLE fit '" + seeded.ble->fit + "' +-" + width + " %" + (addedSeed ? " (added by the benchmark: the file has no [ble])" : "") + "; " + fit;
      if (!o.quiet) std::fprintf(stderr, "seeded variant %s: %s\n", seeded.name.c_str(), seededBrackets.c_str());
    } catch (const std::exception& e) {
      skipped = std::string("no BLE fit to seed from: ") + e.what();
    }
  }
  if (skipped.empty()) {
    ro.progress = progressFor(seeded.name);
    b = benchmarkCampaign(seeded, (dir / "seeded.sqlite").string(), ro);
  } else if (!o.quiet) {
    std::fprintf(stderr, "seeded comparison skipped: %s\n", skipped.c_str());
  }
  if (o.keep) {
    if (!o.quiet) std::fprintf(stderr, "kept the run databases in %s\n", dir.string().c_str());
  } else {
    std::error_code ignored;
    fs::remove_all(dir, ignored);
  }

  const auto percent = [](double part, double whole) { return whole > 0 ? 100 * part / whole : 0.0; };
  if (o.json) {
    nlohmann::json doc = {{"jobs", o.jobs},
                          {"threads_per_run", o.threads},
                          {"hardware_threads", cores},
                          {"quick", o.quick},
                          {"target_wall_time_s", kBenchTargetSeconds},
                          {"unseeded", benchJson(a, plain, plainBrackets)},
                          {"seeded", b ? benchJson(*b, seeded, seededBrackets) : nlohmann::json()},
                          {"seeded_skipped", skipped.empty() ? nlohmann::json() : nlohmann::json(skipped)},
                          {"saving", nlohmann::json()}};
    if (o.keep) doc["run_databases_dir"] = dir.string();
    if (b)
      doc["saving"] = {{"runs", a.runs - b->runs},
                       {"runs_percent", percent(a.runs - b->runs, a.runs)},
                       {"wall_time_s", a.wallSeconds - b->wallSeconds},
                       {"wall_time_percent", percent(a.wallSeconds - b->wallSeconds, a.wallSeconds)}};
    return printJson(doc);
  }
  std::printf("bench campaign: %d points at once, %d thread(s) per run, %u cores seen\n", o.jobs, o.threads, cores);
  printBench(a, plain, plainBrackets);
  if (!b) {
    std::printf("seeded comparison skipped: %s\n", skipped.c_str());
    return;
  }
  printBench(*b, seeded, seededBrackets);
  if (b->points != a.points)
    std::printf("note: the two campaigns have different points (%d and %d)\n", a.points, b->points);
  std::printf("BLE-seeded brackets save %d runs of %d (%.0f %%) and %.1f s of %.1f s wall time (%.0f %%)\n",
              a.runs - b->runs, a.runs, percent(a.runs - b->runs, a.runs), a.wallSeconds - b->wallSeconds,
              a.wallSeconds, percent(a.wallSeconds - b->wallSeconds, a.wallSeconds));
}
}  // namespace

void registerCampaignCommand(CLI::App& app) {
  auto* campaign = app.add_subcommand(
      "campaign",
      "Bisection campaigns: the ballistic limit at many points (velocity x angle) of one scenario, run concurrently, "
      "recorded run by run in an SQLite database, resumable after any stop (format: data/campaigns/README.md)");
  campaign->require_subcommand(1);

  {
    auto o = std::make_shared<RunCommandOptions>();
    auto* cmd = campaign->add_subcommand(
        "run",
        "Run or resume a campaign: every point's bisection, every simulation recorded as it finishes. Started again "
        "with the same --db it replays what was recorded and simulates only the rest; no run is repeated. A failed "
        "run is retried once at half the particle spacing; a point that cannot be resolved says why.\n"
        "Example: blt campaign run data/campaigns/seed000_quick.toml --db quick.sqlite --jobs 2\n"
        "Example (Slurm array or GNU parallel, one file per task): blt campaign run data/campaigns/seed000_theta0.toml "
        "--task 3/8 --db part-3.sqlite");
    cmd->add_option("campaign", o->file, "Campaign file (TOML, see data/campaigns/README.md)")->required();
    cmd->add_option("--db", o->db, "Run database (SQLite file, created when missing; keep it on a local disk)")->required();
    cmd->add_option("--jobs", o->jobs, "Points at once, each simulation on one thread (default 1)");
    cmd->add_option("--task", o->task,
                    "I/N: run only task I's share of the points (point k belongs to task k mod N + 1), for job arrays; "
                    "give each task its own --db and merge them");
    cmd->add_option("--ble-db", o->bleDb, "BLE store to seed brackets from, in place of the campaign's [ble] db");
    cmd->add_flag("--mpi", o->mpi,
                  std::string("Under mpirun: rank 0 walks the bisections and writes --db, the other ranks simulate "
                              "(mpirun -n K blt campaign run CAMPAIGN --db FILE --mpi)") +
                      (mpiAvailable() ? "" : "; this blt was built without MPI"));
    cmd->add_flag("--in-process", o->inProcess, kInProcessHelp);
    addWallTime(*cmd, "--checkpoint-every", o->checkpointSeconds,
                "Each run in flight keeps a checkpoint at this wall-time interval in DB.checkpoints/, and a campaign "
                "killed and started again goes on with its runs from there instead of from the start: for runs of "
                "hours under a job time limit. About 0.3 kB a particle per run in flight");
    cmd->add_flag("--quiet", o->quiet, "No progress lines");
    addJsonFlag(*cmd, o->json);
    cmd->callback([o] { runCommand(*o); });
  }
  {
    auto o = std::make_shared<StatusOptions>();
    auto* cmd = campaign->add_subcommand(
        "status", "What a run database holds: each campaign's points (pending, started, resolved with their ballistic "
                  "limit, unresolved with the reason), runs and failures. Example: blt campaign status --db quick.sqlite");
    cmd->add_option("--db", o->db, "Run database")->required();
    cmd->add_option("--campaign", o->campaign, "Only this campaign (default: all in the file)");
    addJsonFlag(*cmd, o->json);
    cmd->callback([o] { statusCommand(*o); });
  }
  {
    auto o = std::make_shared<ExportOptions>();
    auto* cmd = campaign->add_subcommand(
        "export",
        "Write every completed run as binary impact data (diameter_mm, velocity_km_s, angle_deg, perforated, source, "
        "projectile_density_kg_m3), the CSV that blt ble fit reads. Example: blt campaign export --db quick.sqlite "
        "--csv quick.csv");
    cmd->add_option("--db", o->db, "Run database")->required();
    cmd->add_option("--csv", o->csv, "CSV file to write")->required();
    cmd->add_option("--campaign", o->campaign, "Only this campaign (default: all in the file)");
    addJsonFlag(*cmd, o->json);
    cmd->callback([o] { exportCommand(*o); });
  }
  {
    auto o = std::make_shared<MergeOptions>();
    auto* cmd = campaign->add_subcommand(
        "merge",
        "Merge the run databases of a campaign's tasks (--task I/N) into one; runs are matched by the hash of their "
        "inputs, so merging twice adds nothing. Example: blt campaign merge part-*.sqlite --db theta0.sqlite");
    cmd->add_option("parts", o->parts, "Run databases to merge")->required()->check(CLI::ExistingFile);
    cmd->add_option("--db", o->db, "Run database to merge into (created when missing)")->required();
    addJsonFlag(*cmd, o->json);
    cmd->callback([o] { mergeCommand(*o); });
  }
}


void registerBenchCampaignCommand(CLI::App& bench) {
  auto o = std::make_shared<BenchCampaignOptions>();
  auto* cmd = bench.add_subcommand(
      "campaign",
      "Wall time of a whole campaign run from scratch (fresh run databases, every run simulated): the theta = 0 "
      "campaign at the seed's resolution (target: under 15 min on 2 cores), runs per point, points resolved; then "
      "the same with BLE-seeded first brackets and what they save. Makes the BLE fit the seeded campaign names when "
      "its store lacks it. Example: blt bench campaign --jobs 2 --threads 1; smoke check: blt bench campaign --quick");
  auto* campaignOpt = cmd->add_option("--campaign", o->campaign,
                                      "Campaign without seeding (default data/campaigns/seed000_theta0.toml)");
  auto* seededOpt = cmd->add_option(
      "--seeded", o->seeded,
      "Its BLE-seeded variant (default data/campaigns/seed000_theta0_seeded.toml; a file without [ble] is seeded "
      "from fit seed000, +-10 %)");
  cmd->add_flag("--quick", o->quick, "data/campaigns/seed000_quick.toml for both (seconds, a smoke check)")
      ->excludes(campaignOpt)
      ->excludes(seededOpt);
  cmd->add_option("--ble-db", o->bleDb, "BLE store for the seeded variant, in place of its [ble] db");
  cmd->add_option("--jobs", o->jobs, "Points at once (default 2)");
  cmd->add_option("--threads", o->threads, "OpenMP threads per run (default 1; 0: all cores)");
  cmd->add_flag("--in-process", o->inProcess, kInProcessHelp);
  cmd->add_flag("--keep", o->keep, "Keep the run databases (their directory is printed) for blt campaign status");
  cmd->add_flag("--quiet", o->quiet, "No progress lines");
  addJsonFlag(*cmd, o->json);
  cmd->callback([o] { benchCampaign(*o); });
}

}  // namespace blt::cli
