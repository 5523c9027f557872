// blt sim run / blt sim bisect: impact scenarios (data/scenarios) to their perforation verdict, and bisection
// on the projectile's diameter or velocity for the ballistic limit.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <tuple>

#include "blt/sim/impact.hpp"
#include "cli_support.hpp"
#include "commands.hpp"

namespace blt::cli {

namespace {

using namespace blt::sim;

struct ScenarioOptions {
  std::string file;
  std::vector<std::string> settings;
  std::string out;
  int threads = 0;
  int ensemble = 1;  // runs at grid offsets 0, 1/N, ..., (N-1)/N
  double checkpointSeconds = 0;  // wall time between checkpoints (blt sim run only)
  bool resume = false;
  bool noFrames = false;
  bool json = false, quiet = false;
};

void addScenarioOptions(CLI::App& cmd, ScenarioOptions& o) {
  cmd.add_option("scenario", o.file, "Scenario file (TOML, see data/scenarios/README.md)")->required();
  cmd.add_option("--set", o.settings,
                 "KEY=VALUE on top of the file, repeatable: projectile.diameter=1.2mm, projectile.velocity=4.03km/s, "
                 "projectile.angle=45deg, target.layer.2.gap_before=1.75mm (layer by number from the front, or by "
                 "name), run.mode=3d, run.max_time=8us, solver.friction=0.1");
  cmd.add_option("--out", o.out, "Output directory: ParaView series (NAME.pvd), energy history CSV, summary JSON");
  cmd.add_option("--threads", o.threads, "OpenMP threads (default: all cores; several runs at once: 1 each)");
  cmd.add_flag("--quiet", o.quiet, "No progress lines");
  cmd.add_flag("--no-frames", o.noFrames,
               "With --out: no particle frames (VTU), only the energy and verdict histories and the summary");
  addJsonFlag(cmd, o.json);
}

ImpactRunOptions runOptions(const ScenarioOptions& o) {
  if (o.threads < 0)
    throw InputError(InputLocation::flag("--threads"), "thread count must not be negative", "1, 2, ... (0: all cores)");
  if (o.checkpointSeconds < 0)
    throw InputError(InputLocation::flag("--checkpoint-every"), "a negative interval", "a wall time such as 10min");
  if ((o.checkpointSeconds > 0 || o.resume) && o.out.empty())
    throw InputError(InputLocation::flag(o.resume ? "--resume" : "--checkpoint-every"),
                     "checkpoints live in the output directory, and none is given", "--out DIR as well");
  ImpactRunOptions ro;
  ro.outputDirectory = o.out;
  ro.threads = o.threads;
  ro.checkpointSeconds = o.checkpointSeconds;
  ro.resume = o.resume;
  ro.frames = !o.noFrames;
  if (!o.quiet)
    ro.progress = [](const RunProgress& p) { std::fputs(progressLine(p, false).c_str(), stderr); };
  return ro;
}

void describeScenario(const ImpactScenario& sc) {
  const ProjectileSpec& p = sc.projectile;
  char yaw[48] = "";
  if (p.yaw != 0) std::snprintf(yaw, sizeof yaw, ", yaw %.4g deg", p.yaw * 180 / M_PI);
  std::fprintf(stderr, "%s: %s, %.4g mm %s %s at %s, %.4g deg%s; %zu layers; to %.4g us\n", sc.name.c_str(),
               toString(sc.resolvedMode()), p.diameter * 1e3, p.material.c_str(), toString(p.shape),
               units::format(p.velocity, p.velocity >= 1000 ? "km/s" : "m/s", 4).c_str(), p.angle * 180 / M_PI, yaw,
               sc.target.layers.size(), sc.run.maxTime * 1e6);
}

void printImpact(const nlohmann::json& d) {
  std::printf("verdict: %s (%s)%s at %.3g us\n", d["perforated"].get<bool>() ? "PERFORATED" : "not perforated",
              d["verdict_reason"].get<std::string>().c_str(), d["settled"].get<bool>() ? ", settled" : ", not settled",
              d["time_s"].get<double>() * 1e6);
  if (d["residual_velocity_m_s"].get<double>() > 0)
    std::printf("residual velocity: %.4g m/s (%s, %.4g g)\n", d["residual_velocity_m_s"].get<double>(),
                d["residual_velocity_of"].get<std::string>().c_str(), d["residual_fragment_mass_kg"].get<double>() * 1e3);
  std::printf("hole sizes (D_h x D_v):\n");
  for (std::size_t i = 0; i < d["layers"].size(); ++i)
    std::printf("  %-12s %.3g x %.3g mm\n", d["layers"][i].get<std::string>().c_str(),
                d["hole_size_mm"][i][0].get<double>(), d["hole_size_mm"][i][1].get<double>());
  std::printf("%s, %zu particles, %ld steps, wall time %.2f s\n", d["model"].get<std::string>().c_str(),
              d["particles"].get<std::size_t>(), d["steps"].get<long>(), d["wall_time_s"].get<double>());
}

// The same shot on N alignments of grid and particles (resolution.grid_offset = k/N): how many perforate says
// how far the verdict can be trusted near the ballistic limit.
void runEnsemble(const ScenarioOptions& o) {
  nlohmann::json runs = nlohmann::json::array(), offsets = nlohmann::json::array();
  int perforated = 0;
  for (int k = 0; k < o.ensemble; ++k) {
    const double offset = static_cast<double>(k) / o.ensemble;
    std::vector<std::string> settings = o.settings;
    char value[32];
    std::snprintf(value, sizeof value, "%.6g", offset);
    settings.push_back("resolution.grid_offset=" + std::string(value));
    const ImpactScenario sc = loadScenario(o.file, settings);
    if (!o.json && k == 0) describeScenario(sc);
    ScenarioOptions member = o;
    if (!o.out.empty()) member.out = (std::filesystem::path(o.out) / ("grid_offset_" + std::string(value))).string();
    const ImpactResult r = runImpact(sc, runOptions(member));
    const bool p = r.summary["perforated"].get<bool>();
    perforated += p;
    runs.push_back(r.summary);
    offsets.push_back(offset);
    if (!o.json)
      std::printf("grid offset %-6.4g %s%s, residual velocity %.4g m/s, rear wall hole %.3g x %.3g mm, %.1f s\n", offset,
                  p ? "PERFORATED" : "not perforated", r.summary["settled"].get<bool>() ? "" : " (not settled)",
                  r.summary["residual_velocity_m_s"].get<double>(), r.summary["hole_size_mm"].back()[0].get<double>(),
                  r.summary["hole_size_mm"].back()[1].get<double>(), r.summary["wall_time_s"].get<double>());
  }
  if (o.json)
    return printJson({{"members", o.ensemble},
                      {"grid_offsets", offsets},
                      {"perforated_count", perforated},
                      {"perforated_fraction", static_cast<double>(perforated) / o.ensemble},
                      {"runs", runs}});
  std::printf("perforated in %d of %d grid offsets%s\n", perforated, o.ensemble,
              perforated == 0 || perforated == o.ensemble ? "" : ": the shot is within the discretisation's reach of the limit");
}

void runScenario(const ScenarioOptions& o) {
  if (o.ensemble < 1)
    throw InputError(InputLocation::flag("--ensemble"), std::to_string(o.ensemble) + " is out of range", "1 or more runs");
  if (o.ensemble > 1 && (o.resume || o.checkpointSeconds > 0))
    throw InputError(InputLocation::flag(o.resume ? "--resume" : "--checkpoint-every"),
                     "checkpoints are for single runs, not an ensemble", "--ensemble 1, or no checkpoints");
  if (o.ensemble > 1) return runEnsemble(o);
  const ImpactScenario sc = loadScenario(o.file, o.settings);
  if (!o.json) describeScenario(sc);
  if (!o.json && o.resume)
    std::fprintf(stderr, "going on from %s/%s_checkpoint.bin\n", o.out.c_str(), sc.name.c_str());
  const ImpactResult r = runImpact(sc, runOptions(o));
  if (o.json) return printJson(r.summary);
  if (!std::isnan(r.resumedAt)) std::printf("resumed from a checkpoint at %.4g us\n", r.resumedAt * 1e6);
  if (r.status == RunStatus::unstable) std::printf("run went unstable: %s\n", r.message.c_str());
  printImpact(r.summary);
  if (!o.out.empty())
    std::printf("files in %s/%s\n", o.out.c_str(),
                o.noFrames ? "" : (" (open " + sc.name + ".pvd in ParaView)").c_str());
}

struct BisectCliOptions {
  ScenarioOptions scenario;
  std::string on = "diameter";
  std::string lo, hi, tol;
  bool trustBracket = false;
  int maxRuns = 40;
};

void runBisect(const BisectCliOptions& o) {
  const ImpactScenario sc = loadScenario(o.scenario.file, o.scenario.settings);
  BisectionOptions bo;
  if (o.on != "diameter" && o.on != "velocity")
    throw InputError(InputLocation::flag("--on"), "unknown variable '" + o.on + "'", "diameter or velocity");
  bo.variable = o.on == "diameter" ? BisectVariable::diameter : BisectVariable::velocity;
  const units::Dimension dim = bo.variable == BisectVariable::diameter ? units::length : units::velocity;
  bo.lower = units::parse(o.lo, dim, InputLocation::flag("--lo"));
  bo.upper = units::parse(o.hi, dim, InputLocation::flag("--hi"));
  bo.tolerance = units::parse(o.tol, dim, InputLocation::flag("--tol"));
  bo.checkBracket = !o.trustBracket;
  bo.maxRuns = o.maxRuns;
  const char* unit = bo.variable == BisectVariable::diameter ? "mm" : "m/s";
  const double scale = bo.variable == BisectVariable::diameter ? 1e3 : 1.0;
  if (!o.scenario.json) describeScenario(sc);
  ScenarioOptions quietRuns = o.scenario;
  quietRuns.quiet = true;  // one line per run instead
  // One line per run on stderr, with --json too: a bisection runs for minutes to hours, and the JSON is stdout.
  const auto onRun = [&](const BisectionRun& r) {
    std::fprintf(stderr, "  run %s = %.5g %s: %s%s, %.1f s\n", o.on.c_str(), r.value * scale, unit,
                 r.status == RunStatus::unstable ? "UNSTABLE" : (r.perforated ? "perforated" : "not perforated"),
                 r.settled ? "" : " (not settled)", r.wallSeconds);
  };
  const BisectionResult b = bisectScenario(sc, bo, runOptions(quietRuns), onRun);
  nlohmann::json runs = nlohmann::json::array();
  for (const auto& r : b.runs) runs.push_back(r.summary);
  const auto value = [&](double v) { return std::isnan(v) ? nlohmann::json() : nlohmann::json(v * scale); };
  const std::string key = o.on == "diameter" ? "_mm" : "_m_s";
  const BisectionRun* safe = b.largestSafeRun();
  nlohmann::json doc = {{"scenario", sc.name},
                        {"variable", o.on},
                        {"resolved", b.resolved},
                        {"message", b.message},
                        {"largest_not_perforating" + key, value(b.largestSafe)},
                        {"largest_not_perforating_settled", safe ? nlohmann::json(safe->settled) : nlohmann::json()},
                        {"smallest_perforating" + key, value(b.smallestPerforating)},
                        {"estimate" + key, b.resolved ? value(b.estimate()) : nlohmann::json()},
                        {"half_width" + key, b.resolved ? value(0.5 * (b.smallestPerforating - b.largestSafe)) : nlohmann::json()},
                        {"run_count", b.runs.size()},
                        {"runs", runs}};
  if (o.scenario.json) {
    // The runs' lines went to stderr and the result goes to stdout: a closing line on stderr says, to whoever
    // watches the runs, that the bisection is over.
    if (b.resolved)
      std::fprintf(stderr, "bisection resolved: ballistic limit %.5g +- %.3g %s after %zu runs\n", b.estimate() * scale,
                   0.5 * (b.smallestPerforating - b.largestSafe) * scale, unit, b.runs.size());
    else
      std::fprintf(stderr, "bisection not resolved after %zu runs: %s\n", b.runs.size(), b.message.c_str());
    return printJson(doc);
  }
  if (!b.resolved) std::printf("not resolved: %s\n", b.message.c_str());
  std::printf("largest %s not perforating: %s\nsmallest %s perforating: %s\n", o.on.c_str(),
              std::isnan(b.largestSafe) ? "none found" : (std::to_string(b.largestSafe * scale) + " " + unit).c_str(),
              o.on.c_str(),
              std::isnan(b.smallestPerforating) ? "none found"
                                                : (std::to_string(b.smallestPerforating * scale) + " " + unit).c_str());
  if (b.resolved)
    std::printf("ballistic limit: %.5g +- %.3g %s after %zu runs\n", b.estimate() * scale,
                0.5 * (b.smallestPerforating - b.largestSafe) * scale, unit, b.runs.size());
  if (safe && !safe->settled)
    std::printf("note: the largest %s not perforating ended unsettled at run.max_time = %s; a longer run may still "
                "perforate it, and the limit would then lie lower: check with --set run.max_time=...\n",
                o.on.c_str(), units::format(sc.run.maxTime, "us", 4).c_str());
}


// ---- blt bench scenario: the speed targets of the scenario issue on the seed 000 target ----

struct BenchScenarioOptions {
  std::vector<std::string> cases{"axisymmetric", "oblique", "bisection"};
  int threads = 0;
  bool json = false;
};

void benchScenario(const BenchScenarioOptions& o) {
  const std::string file = std::string(BLT_DATA_DIR) + "/scenarios/fabric_al_corrected.toml";
  nlohmann::json doc = nlohmann::json::object();
  ImpactRunOptions ro;
  ro.threads = o.threads;
  const auto wanted = [&](const char* c) { return std::find(o.cases.begin(), o.cases.end(), c) != o.cases.end(); };
  for (const auto& c : o.cases)
    if (c != "axisymmetric" && c != "oblique" && c != "bisection")
      throw InputError(InputLocation::flag("--cases"), "no case '" + c + "'", "axisymmetric, oblique, bisection");
  // Seed 000 sec. 5.1 resolution (0.1 mm particles, 0.2 mm cells), as in the scenario file.
  for (const auto& [name, angle, target] :
       {std::tuple{"axisymmetric", "0deg", 30.0}, std::tuple{"oblique", "45deg", 600.0}}) {
    if (!wanted(name)) continue;
    const ImpactScenario sc = loadScenario(
        file, {"projectile.diameter=1mm", "projectile.velocity=5km/s", std::string("projectile.angle=") + angle});
    const ImpactResult r = runImpact(sc, ro);
    doc[name] = {{"model", r.summary["model"]},       {"particles", r.particles},
                 {"steps", r.summary["steps"]},       {"simulated_time_s", r.endTime},
                 {"wall_time_s", r.wallSeconds},      {"target_wall_time_s", target},
                 {"perforated", r.verdict.perforated}, {"settled", r.verdict.settled}};
    if (!o.json)
      std::printf("%-13s 1 mm at 5 km/s, %s: %s, %zu particles, %s steps to %.3g us: wall %.1f s (target < %.0f s)\n",
                  name, angle, r.summary["model"].get<std::string>().c_str(), r.particles,
                  r.summary["steps"].dump().c_str(), r.endTime * 1e6, r.wallSeconds, target);
  }
  if (wanted("bisection")) {
    // A good bracket: seed 000 Table 6 puts d_c at 5 km/s between 0.94 and 0.98 mm; start 0.3 mm either side.
    // The original model (layers in contact) is used: it perforates in this range, the corrected one does not.
    const ImpactScenario sc = loadScenario(std::string(BLT_DATA_DIR) + "/scenarios/fabric_al_original.toml",
                                           {"projectile.velocity=5km/s"});
    BisectionOptions bo;
    bo.lower = 0.66e-3;
    bo.upper = 1.26e-3;
    bo.tolerance = 0.02e-3;
    const BisectionResult b = bisectScenario(sc, bo, ro);
    double wall = 0;
    for (const auto& r : b.runs) wall += r.wallSeconds;
    doc["bisection"] = {{"scenario", sc.name}, {"bracket_mm", {0.66, 1.26}}, {"tolerance_mm", 0.02},
                        {"resolved", b.resolved}, {"message", b.message}, {"runs", b.runs.size()},
                        {"target_runs", 6}, {"wall_time_s", wall},
                        {"estimate_mm", b.resolved ? nlohmann::json(b.estimate() * 1e3) : nlohmann::json()}};
    if (!o.json)
      std::printf("bisection     %s at 5 km/s from [0.66, 1.26] mm to +-0.02 mm: %zu runs (target <= 6), %.1f s%s\n",
                  sc.name.c_str(), b.runs.size(), wall,
                  b.resolved ? (", d_c " + units::format(b.estimate(), "mm", 4)).c_str() : (": " + b.message).c_str());
  }
  if (o.json) printJson(doc);
}

}  // namespace

void registerBenchScenarioCommand(CLI::App& bench) {
  auto o = std::make_shared<BenchScenarioOptions>();
  auto* cmd = bench.add_subcommand(
      "scenario",
      "Wall time of seed 000 target runs at the seed's resolution: a normal impact (axisymmetric, target < 30 s), a "
      "45 deg impact (3D half model, < 10 min) and a bisection to +-0.02 mm from a good bracket (<= 6 runs)");
  cmd->add_option("--cases", o->cases, "Which: axisymmetric, oblique, bisection (default all)")->delimiter(',');
  cmd->add_option("--threads", o->threads, "OpenMP threads (default: all cores)");
  addJsonFlag(*cmd, o->json);
  cmd->callback([o] { benchScenario(*o); });
}

void registerSimScenarioCommands(CLI::App& sim) {
  auto so = std::make_shared<ScenarioOptions>();
  auto* run = sim.add_subcommand(
      "run",
      "Run an impact scenario to its perforation verdict: perforated (rear wall), residual velocity, hole size of "
      "every layer (D_h x D_v), energies. Example: blt sim run data/scenarios/fabric_al_corrected.toml --set "
      "projectile.diameter=1.2mm --set projectile.velocity=4.03km/s --out case05");
  addScenarioOptions(*run, *so);
  run->add_option("--ensemble", so->ensemble,
                  "Run the shot N times, the grid shifted along the target normal by 0, 1/N, ... of a cell "
                  "(resolution.grid_offset), and count the perforations: how sure the verdict is near the limit "
                  "(default 1)");
  addWallTime(*run, "--checkpoint-every", so->checkpointSeconds,
              "Wall time between checkpoints OUT/NAME_checkpoint.bin, and one at the end, so that a long run can be "
              "resumed after a kill or run longer; each holds every particle, about 0.3 kB a particle in 3D (0.4 GB "
              "for the seed 000 45 deg model)");
  run->add_flag("--resume", so->resume,
                "Go on from OUT/NAME_checkpoint.bin with the same scenario and --set values (only run.max_time may "
                "differ: raise it to run a finished run longer); the energy history, verdict history and frames are "
                "continued");
  run->callback([so] { runScenario(*so); });

  auto bo = std::make_shared<BisectCliOptions>();
  auto* bis = sim.add_subcommand(
      "bisect",
      "Ballistic limit by bisection: the largest diameter (or velocity) that does not perforate and the smallest "
      "that does. Example: blt sim bisect data/scenarios/fabric_al_corrected.toml --on diameter --lo 0.8mm --hi "
      "1.4mm --tol 0.02mm --set projectile.velocity=5km/s");
  addScenarioOptions(*bis, bo->scenario);
  bis->add_option("--on", bo->on, "What to bisect: diameter or velocity (default diameter)");
  bis->add_option("--lo", bo->lo, "Lower end of the bracket, expected not to perforate (e.g. 0.8mm, 200m/s)")->required();
  bis->add_option("--hi", bo->hi, "Upper end of the bracket, expected to perforate (e.g. 1.4mm, 400m/s)")->required();
  bis->add_option("--tol", bo->tol, "Half-width of the final bracket (e.g. 0.02mm, 5m/s)")->required();
  bis->add_flag("--trust-bracket", bo->trustBracket, "Do not run the bracket's ends first (two runs fewer)");
  bis->add_option("--max-runs", bo->maxRuns, "Stop after this many runs (default 40)");
  bis->callback([bo] { runBisect(*bo); });
}

}  // namespace blt::cli
