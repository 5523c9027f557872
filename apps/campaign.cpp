// blt campaign: bisection campaigns (many ballistic-limit points of one scenario) run concurrently and resumably
// into an SQLite run database; their status, their runs as binary impact data, and the merging of task parts.
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <map>
#include <memory>
#include <mutex>

#include "blt/campaign/campaign.hpp"
#include "blt/campaign/database.hpp"
#include "blt/campaign/mpi.hpp"
#include "blt/campaign/runner.hpp"
#include "cli_support.hpp"
#include "commands.hpp"

namespace blt::cli {

namespace {

using namespace blt::campaign;

std::string clock(double seconds) {
  if (!std::isfinite(seconds)) return "?";
  const long s = std::lround(seconds);
  char buf[32];
  if (s >= 3600) std::snprintf(buf, sizeof buf, "%ld:%02ld:%02ld", s / 3600, s / 60 % 60, s % 60);
  else std::snprintf(buf, sizeof buf, "%ld:%02ld", s / 60, s % 60);
  return buf;
}

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

// ---- blt campaign run --------------------------------------------------------------------------------------------

struct RunCommandOptions {
  std::string file, db, task = "1/1", bleDb;
  int jobs = 1;
  bool json = false, quiet = false, mpi = false;
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
                    clock(p.elapsedSeconds).c_str(), clock(p.etaSeconds).c_str());
      if (tty && !json) {
        // The event above the live line, the live line redrawn under it.
        std::fprintf(stderr, "\r\033[K  %s\n%s", p.event.c_str(), line);
      } else {
        std::fprintf(stderr, "[%s] %s | %s\n", clock(p.elapsedSeconds).c_str(), p.event.c_str(), line);
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
              resolved, r.points.size(), r.simulated, r.failed, r.replayed, perPoint, clock(r.wallSeconds).c_str(),
              clock(r.simulatedSeconds).c_str());
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
                failed, clock(wall).c_str());
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
  RunDatabase db(o.db);
  nlohmann::json added = nlohmann::json::object();
  for (const auto& part : o.parts) {
    const int n = db.mergeFrom(part);
    added[part] = n;
    if (!o.json) std::printf("merged %s: %d runs added\n", part.c_str(), n);
  }
  if (o.json) printJson({{"db", o.db}, {"runs_added", added}});
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

}  // namespace blt::cli
