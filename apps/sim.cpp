// blt sim example: built-in solver cases with known answers, run with full output (ParaView series, energy
// history, run summary). blt bench sim / blt bench taylor: speed and Taylor-bar figures of the MPM solver.
// Scenario files: sim_scenario.cpp (blt sim run, blt sim bisect).
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <memory>
#include <random>
#include <string>
#include <vector>
#include <omp.h>

#include "blt/core/materials.hpp"
#include "blt/sim/cases.hpp"
#include "blt/sim/run.hpp"
#include "cli_support.hpp"
#include "commands.hpp"

namespace blt::cli {

namespace {

using namespace blt::sim;

// Zerilli and Armstrong, J. Appl. Phys. 61 (1987) 1816: OFHC copper Taylor tests, L0 = 25.4 mm, D0 = 7.62 mm.
struct TaylorMeasurement {
  double velocity, length, footprint;  // m/s, m, m
};
constexpr TaylorMeasurement kTaylorTests[] = {
    {130.0, 19.558e-3, 9.906e-3}, {146.0, 18.694e-3, 10.668e-3}, {190.0, 16.205e-3, 13.564e-3}};

std::string fmt(const char* format, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, format, v);
  return buf;
}

void setThreads(int threads) {
  if (threads < 0)
    throw InputError(InputLocation::flag("--threads"), "thread count must be positive", "1, 2, ... (0: all cores)");
  if (threads > 0) omp_set_num_threads(threads);
}

double peakMemoryBytes() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<double>(usage.ru_maxrss) * 1024.0;  // Linux reports kilobytes
}

template <int D>
RunHooks<D> progressHooks(bool quiet) {
  RunHooks<D> hooks;
  if (quiet) return hooks;
  hooks.progress = [](const RunProgress& p) { std::fputs(progressLine(p, true).c_str(), stderr); };
  return hooks;
}

// A library id, or a path to a card of the same format.
Material materialByIdOrPath(const std::string& name) {
  return name.find(".toml") != std::string::npos ? loadMaterial(name) : MaterialLibrary::load().get(name);
}

struct TaylorOptions {
  double velocity = 190.0, endTime = 80e-6, length = 25.4e-3, diameter = 7.62e-3;
  std::string material = "cu_ofhc";
  int particlesPerDiameter = 10, frames = 16, threads = 0;
  bool threeD = false, json = false;
  std::string out = "taylor-bar-out";
};

template <int D>
nlohmann::json runTaylor(const TaylorOptions& o, std::unique_ptr<Solver<D>> solver) {
  RunOptions ro;
  ro.endTime = o.endTime;
  ro.outputDirectory = o.out;
  ro.name = "taylor_bar";
  ro.frames = o.frames;
  if (!o.json)
    std::fprintf(stderr, "Taylor bar (%s), %s, %zu particles, %.0f m/s onto a rigid wall, to %.0f us; writing %s/\n",
                 o.material.c_str(), D == 3 ? "3D" : "axisymmetric", solver->particles().size(), o.velocity,
                 o.endTime * 1e6, o.out.c_str());
  const RunResult r = run<D>(*solver, ro, progressHooks<D>(o.json));
  const TaylorBarShape shape = measureTaylorBar<D>(*solver);
  nlohmann::json doc = r.summary;
  doc["final_length_mm"] = shape.length * 1e3;
  doc["footprint_diameter_mm"] = shape.footprintDiameter * 1e3;
  const bool zerilliArmstrong = o.material == "cu_ofhc" && std::fabs(o.length - 25.4e-3) < 1e-6 &&
                                std::fabs(o.diameter - 7.62e-3) < 1e-6;
  for (const auto& m : kTaylorTests)
    if (zerilliArmstrong && std::fabs(m.velocity - o.velocity) < 0.5) {
      doc["measured_length_mm"] = m.length * 1e3;
      doc["measured_footprint_diameter_mm"] = m.footprint * 1e3;
      doc["measured_source"] = "Zerilli and Armstrong, J. Appl. Phys. 61 (1987) 1816";
    }
  return doc;
}

void exampleTaylor(const TaylorOptions& o) {
  setThreads(o.threads);
  if (!(o.velocity > 0)) throw InputError(InputLocation::flag("--velocity"), "the impact velocity must be positive", "e.g. 190 m/s");
  if (!(o.endTime > 0)) throw InputError(InputLocation::flag("--end-time"), "the end time must be positive", "e.g. 80 us");
  if (o.particlesPerDiameter < 4)
    throw InputError(InputLocation::flag("--particles-per-diameter"), "too coarse", "at least 4");
  if (!(o.length > 0)) throw InputError(InputLocation::flag("--length"), "the bar length must be positive", "e.g. 25.4 mm");
  if (!(o.diameter > 0)) throw InputError(InputLocation::flag("--diameter"), "the bar diameter must be positive", "e.g. 7.62 mm");
  const Material copper = materialByIdOrPath(o.material);
  TaylorBarCase c;
  c.velocity = o.velocity;
  c.length = o.length;
  c.diameter = o.diameter;
  c.particlesPerDiameter = o.particlesPerDiameter;
  const nlohmann::json doc = o.threeD ? runTaylor<3>(o, makeTaylorBar3d(c, copper))
                                      : runTaylor<2>(o, makeTaylorBarAxisymmetric(c, copper));
  if (o.json) return printJson(doc);
  std::cout << "status: " << doc["status"].get<std::string>();
  if (!doc["message"].get<std::string>().empty()) std::cout << " (" << doc["message"].get<std::string>() << ")";
  std::cout << "\nsteps: " << doc["steps"] << ", wall time " << fmt("%.2f s", doc["wall_time_s"].get<double>())
            << "\nfinal length: " << fmt("%.3f mm", doc["final_length_mm"].get<double>())
            << "\nfootprint diameter: " << fmt("%.3f mm", doc["footprint_diameter_mm"].get<double>()) << "\n";
  if (doc.contains("measured_length_mm"))
    std::cout << "measured (Zerilli and Armstrong 1987): " << fmt("%.3f mm", doc["measured_length_mm"].get<double>())
              << " long, " << fmt("%.3f mm", doc["measured_footprint_diameter_mm"].get<double>()) << " footprint\n";
  std::cout << "files in " << o.out << "/: ";
  for (const auto& f : doc["files"]) std::cout << f.get<std::string>() << " ";
  std::cout << "(open taylor_bar.pvd in ParaView)\n";
}

// ---- benchmarks ----

struct BenchOptions {
  int threads = 0;
  bool json = false;
  bool quick = false;
  int repeat = 1;                  // timings of each case, each on a freshly built case; the median is reported
  std::vector<std::string> cases;  // empty: every case
  double disturb = 0;              // cells; each point moved at random by up to this along each axis before timing
};

// Moves every point by a uniform random offset of up to `cells` cell widths along each axis, kept on the grid.
// A point still on the fill lattice has 2 nodes per axis in its stencil where a moved one mostly has 3, so an
// undisturbed case times the cheapest stencils; a disturbed one times what deformed material costs.
template <int D>
void disturbPositions(Solver<D>& solver, double cells) {
  if (cells <= 0) return;
  const GridSpec<D>& grid = solver.grid();
  std::mt19937_64 random(20261206);
  std::uniform_real_distribution<double> offset(-cells * grid.cellSize, cells * grid.cellSize);
  for (auto& x : solver.particles().position)
    for (int a = 0; a < D; ++a) x[a] = std::clamp(x[a] + offset(random), grid.lower[a], grid.upper[a]);
}

const std::vector<std::string> kBenchCases = {"3d-ugimp-musl-jc-mg", "taylor-bar-3d", "axisymmetric-jc-mg"};

std::string benchCaseNames() {
  std::string names;
  for (const auto& name : kBenchCases) names += (names.empty() ? "" : ", ") + name;
  return names;
}

template <int D>
nlohmann::json timeCase(const std::string& name, const std::string& description, Solver<D>& solver, long steps,
                        bool first, double disturb) {
  RunOptions ro;
  ro.endTime = 1.0;  // the step limit ends the run
  ro.maxSteps = steps;
  ro.energySamples = 0;
  ro.frames = 0;
  disturbPositions(solver, disturb);
  // One untimed step first: it touches every page of the grid and caches.
  solver.step();
  const StageTimes before = solver.stageTimes();
  const RunResult r = run<D>(solver, ro);
  const StageTimes& after = solver.stageTimes();
  const double n = static_cast<double>(solver.particles().size());
  // Points whose stencil has 2 nodes per axis touch 2^D nodes instead of 3^D in each stage: most are material
  // still on its initial lattice, so a case's rate depends on how much of it the impact has disturbed. Points off
  // the lattice have 2 on some axes: the mean count of nodes a point touches is the measure of the work.
  std::size_t active = 0, twoNode = 0, nodes = 0;
  for (std::size_t p = 0; p < solver.particles().size(); ++p)
    if (solver.particles().active[p]) {
      ++active;
      const auto& size = solver.stencils()[p].size;
      bool allTwo = true;
      std::size_t touched = 1;
      for (int a = 0; a < D; ++a) allTwo &= size[a] == 2, touched *= size[a];
      twoNode += allTwo;
      nodes += touched;
    }
  const nlohmann::json stages = {{"reorder", after.reorder - before.reorder},
                                 {"shape_functions", after.shapeFunctions - before.shapeFunctions},
                                 {"particles_to_grid", after.particlesToGrid - before.particlesToGrid},
                                 {"grid", after.grid - before.grid},
                                 {"grid_to_particles", after.gridToParticles - before.gridToParticles},
                                 {"remap", after.remap - before.remap},
                                 {"stress", after.stress - before.stress}};
  return {{"case", name},
          {"stage_seconds", stages},
          {"description", description},
          {"particles", solver.particles().size()},
          {"steps", r.steps},
          {"wall_time_s", r.wallSeconds},
          {"particle_updates_per_s", r.particleUpdatesPerSecond},
          {"disturb_cells", disturb},
          {"two_node_stencil_fraction", active ? static_cast<double>(twoNode) / static_cast<double>(active) : 0.0},
          {"mean_stencil_nodes", active ? static_cast<double>(nodes) / static_cast<double>(active) : 0.0},
          {"solver_bytes_per_particle", static_cast<double>(solver.memoryBytes()) / n},
          // The process's peak RSS is a high-water mark, so it is only this case's own for the first case.
          {"peak_rss_bytes_per_particle", first ? nlohmann::json(peakMemoryBytes() / n) : nlohmann::json()}};
}

// Times a case `repeat` times, each on a case built anew by timeOnce(first), and reports the first timing's
// figures with the median rate and wall time. On a shared machine one timing varies by +-20 %; the median of a
// few, with the spread beside it, is the figure to compare builds by.
template <class F>
nlohmann::json timeRepeated(int repeat, bool first, F&& timeOnce) {
  nlohmann::json doc;
  std::vector<double> rates, walls;
  for (int r = 0; r < repeat; ++r) {
    const nlohmann::json t = timeOnce(first && r == 0);
    if (r == 0)
      doc = t;
    else  // the stages' times are summed over the timings
      for (auto& [stage, seconds] : doc["stage_seconds"].items())
        seconds = seconds.template get<double>() + t["stage_seconds"][stage].template get<double>();
    rates.push_back(t["particle_updates_per_s"].get<double>());
    walls.push_back(t["wall_time_s"].get<double>());
  }
  const auto median = [](std::vector<double> v) {
    std::sort(v.begin(), v.end());
    const std::size_t n = v.size();
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
  };
  doc["particle_updates_per_s"] = median(rates);
  doc["wall_time_s"] = median(walls);
  doc["repeats"] = repeat;
  double total = 0;
  for (const auto& w : walls) total += w;
  doc["timed_wall_time_s"] = total;
  doc["particle_updates_per_s_runs"] = rates;
  return doc;
}

void benchSim(const BenchOptions& o) {
  for (const auto& name : o.cases)
    if (std::find(kBenchCases.begin(), kBenchCases.end(), name) == kBenchCases.end())
      throw InputError(InputLocation::flag("--case"), "no bench case " + name, benchCaseNames());
  const auto selected = [&](const std::string& name) {
    return o.cases.empty() || std::find(o.cases.begin(), o.cases.end(), name) != o.cases.end();
  };
  bool first = true;  // the first case run owns the peak RSS
  setThreads(o.threads);
  const MaterialLibrary lib = MaterialLibrary::load();
  const Material al2a12 = lib.get("al_2a12"), al5a06 = lib.get("al_5a06"), copper = lib.get("cu_ofhc");
  nlohmann::json cases = nlohmann::json::array();
  auto report = [&](const nlohmann::json& c) {
    cases.push_back(c);
    const auto runs = c["particle_updates_per_s_runs"].get<std::vector<double>>();
    const auto [slowest, fastest] = std::minmax_element(runs.begin(), runs.end());
    const std::string spread =
        runs.size() > 1
            ? " (median of " + std::to_string(runs.size()) + ", " + fmt("%.3e", *slowest) + fmt(" to %.3e)", *fastest)
            : "";
    if (!o.json)
      std::printf("%-22s %9zu particles %5ld steps %8.2f s  particle_updates_per_s %.3e%s  memory %.0f B/particle "
                  "(solver)%s\n",
                  c["case"].get<std::string>().c_str(), c["particles"].get<std::size_t>(), c["steps"].get<long>(),
                  c["wall_time_s"].get<double>(), c["particle_updates_per_s"].get<double>(), spread.c_str(),
                  c["solver_bytes_per_particle"].get<double>(),
                  c["peak_rss_bytes_per_particle"].is_null()
                      ? ""
                      : (", " + fmt("%.0f", c["peak_rss_bytes_per_particle"].get<double>()) + " B/particle (peak RSS)")
                            .c_str());
    if (!o.json) {
      // Where the time went: each stage's share of the timed wall time; the rest is the run's own bookkeeping
      // (energies, the verdict's checks, progress).
      const double wall = c["timed_wall_time_s"].get<double>();
      std::string line = "  stages:";
      double staged = 0;
      for (const char* stage : {"reorder", "shape_functions", "particles_to_grid", "grid", "grid_to_particles",
                                "remap", "stress"}) {
        const double seconds = c["stage_seconds"][stage].get<double>();
        line += std::string(" ") + stage + fmt(" %.0f %%", 100.0 * seconds / wall);
        staged += seconds;
      }
      std::printf("%s, other%s\n", line.c_str(), fmt(" %.0f %%", 100.0 * (wall - staged) / wall).c_str());
      const double disturbed = c["disturb_cells"].get<double>();
      std::printf("  stencils: %.0f %% of the points on 2 nodes per axis, %.1f nodes per point, at the end (%s)\n",
                  100.0 * c["two_node_stencil_fraction"].get<double>(), c["mean_stencil_nodes"].get<double>(),
                  disturbed > 0 ? ("points moved at random by up to " + fmt("%g", disturbed) + " cell first").c_str()
                                : "mostly undisturbed lattice");
    }
    std::fflush(stdout);
  };
  if (selected(kBenchCases[0])) {
    // 3D uGIMP MUSL, Johnson-Cook + Mie-Grueneisen + max principal stress: a 2A12 cylinder on a 5A06 plate
    // (seed 000 Table 3 materials), quarter model, two bodies with multi-field contact.
    PlateImpactCase c;
    c.spacing = o.quick ? 0.2e-3 : 0.1e-3;
    c.plateRadius = 14e-3;
    c.plateThickness = 6e-3;
    c.velocity = 5000;
    report(timeRepeated(o.repeat, first, [&](bool owner) {
      auto solver = makePlateImpact3d(c, al2a12, al5a06);
      return timeCase<3>(kBenchCases[0],
                         "2A12 cylinder on 5A06 plate at 5 km/s, 3D quarter model, uGIMP, MUSL, JC + MG, contact",
                         *solver, o.quick ? 5 : 20, owner, o.disturb);
    }));
    first = false;
  }
  if (selected(kBenchCases[1])) {
    TaylorBarCase c;  // 20 particles per diameter: about 21,000 particles in the full bar
    report(timeRepeated(o.repeat, first, [&](bool owner) {
      auto solver = makeTaylorBar3d(c, copper);
      return timeCase<3>(kBenchCases[1], "OFHC copper Taylor bar, full 3D, 20 particles per diameter, 190 m/s",
                         *solver, o.quick ? 20 : 200, owner, o.disturb);
    }));
    first = false;
  }
  if (selected(kBenchCases[2])) {
    PlateImpactCase c;
    c.spacing = 0.05e-3;
    c.plateRadius = 14e-3;
    c.plateThickness = 3e-3;
    c.projectileDiameter = 1e-3;
    c.projectileLength = 1e-3;
    c.velocity = 5000;
    report(timeRepeated(o.repeat, first, [&](bool owner) {
      auto solver = makePlateImpactAxisymmetric(c, al2a12, al5a06);
      return timeCase<2>(kBenchCases[2],
                         "2A12 cylinder on a 3 mm 5A06 plate at 5 km/s, axisymmetric, 0.05 mm spacing, contact",
                         *solver, o.quick ? 50 : 300, owner, o.disturb);
    }));
  }
  if (o.json)
    printJson({{"threads", o.threads > 0 ? o.threads : omp_get_max_threads()}, {"cases", cases}});
}

struct BenchTaylorOptions {
  int threads = 0, particlesPerDiameter = 20;
  bool threeD = false, json = false;
  std::string material = "cu_ofhc";
};

void benchTaylor(const BenchTaylorOptions& o) {
  setThreads(o.threads);
  const Material copper = materialByIdOrPath(o.material);
  if (!o.json) std::printf("%s (%s), %s\n", copper.name.c_str(), o.material.c_str(), o.threeD ? "3D" : "axisymmetric");
  nlohmann::json rows = nlohmann::json::array();
  for (const auto& m : kTaylorTests) {
    TaylorBarCase c;
    c.velocity = m.velocity;
    c.particlesPerDiameter = o.particlesPerDiameter;
    RunOptions ro;
    ro.endTime = 80e-6;
    TaylorBarShape shape;
    RunResult r;
    if (o.threeD) {
      auto s = makeTaylorBar3d(c, copper);
      r = run<3>(*s, ro);
      shape = measureTaylorBar<3>(*s);
    } else {
      auto s = makeTaylorBarAxisymmetric(c, copper);
      r = run<2>(*s, ro);
      shape = measureTaylorBar<2>(*s);
    }
    const double eL = shape.length / m.length - 1, eD = shape.footprintDiameter / m.footprint - 1;
    rows.push_back({{"velocity_m_s", m.velocity},
                    {"length_mm", shape.length * 1e3},
                    {"measured_length_mm", m.length * 1e3},
                    {"length_error", eL},
                    {"footprint_diameter_mm", shape.footprintDiameter * 1e3},
                    {"measured_footprint_diameter_mm", m.footprint * 1e3},
                    {"footprint_error", eD},
                    {"status", toString(r.status)},
                    {"wall_time_s", r.wallSeconds}});
    if (!o.json)
      std::printf("%5.0f m/s  length %.3f mm (measured %.3f, %+.1f %%)  footprint %.3f mm (measured %.3f, %+.1f %%)  "
                  "%.1f s\n",
                  m.velocity, shape.length * 1e3, m.length * 1e3, 100 * eL, shape.footprintDiameter * 1e3,
                  m.footprint * 1e3, 100 * eD, r.wallSeconds);
  }
  if (o.json)
    printJson({{"material", o.material},
               {"geometry", o.threeD ? "3d" : "axisymmetric"},
               {"particles_per_diameter", o.particlesPerDiameter},
               {"source", "Zerilli and Armstrong, J. Appl. Phys. 61 (1987) 1816"},
               {"targets", "length within 3 %, footprint within 5 % (issue 4)"},
               {"results", rows}});
}

}  // namespace

void registerSimCommand(CLI::App& app) {
  auto* sim = app.add_subcommand("sim", "MPM impact solver: scenarios (run, bisect) and built-in example cases");
  sim->require_subcommand(1);
  registerSimScenarioCommands(*sim);
  auto* example = sim->add_subcommand("example", "Run a built-in case with known answers and write its output");
  example->require_subcommand(1);
  auto to = std::make_shared<TaylorOptions>();
  auto* taylor = example->add_subcommand(
      "taylor-bar",
      "Taylor bar onto a rigid frictionless wall (default: OFHC copper, L0 25.4 mm, D0 7.62 mm, compared with "
      "Zerilli and Armstrong 1987); writes taylor_bar.pvd + .vtu frames, taylor_bar_energy.csv and "
      "taylor_bar_summary.json");
  addQuantity(*taylor, "--velocity", to->velocity, units::velocity, "Impact velocity (default 190 m/s)");
  addQuantity(*taylor, "--end-time", to->endTime, units::time, "Simulated time (default 80 us)");
  addQuantity(*taylor, "--length", to->length, units::length, "Bar length (default 25.4 mm)");
  addQuantity(*taylor, "--diameter", to->diameter, units::length, "Bar diameter (default 7.62 mm)");
  taylor->add_option("--material", to->material,
                     "Library material id, or a path to a material card (.toml) (default cu_ofhc)");
  taylor->add_option("--particles-per-diameter", to->particlesPerDiameter, "Resolution (default 10)");
  taylor->add_flag("--3d", to->threeD, "Full 3D model instead of axisymmetric");
  taylor->add_option("--out", to->out, "Output directory (default taylor-bar-out)");
  taylor->add_option("--frames", to->frames, "Particle frames written over the run (default 16)");
  taylor->add_option("--threads", to->threads, "OpenMP threads (default: all cores)");
  addJsonFlag(*taylor, to->json);
  taylor->callback([to] { exampleTaylor(*to); });
}

void registerBenchCommand(CLI::App& app) {
  auto* bench = app.add_subcommand("bench", "Benchmarks: print speed and accuracy figures (not tests)");
  bench->require_subcommand(1);
  auto bo = std::make_shared<BenchOptions>();
  auto* sim = bench->add_subcommand(
      "sim",
      "Solver speed on fixed cases (3D uGIMP ~1e6 particles, 3D Taylor bar ~21,000 particles, axisymmetric): "
      "particle_updates_per_s and memory per particle");
  sim->add_option("--threads", bo->threads, "OpenMP threads (default: all cores)");
  sim->add_flag("--quick", bo->quick, "Smaller 3D case and fewer steps (a smoke run)");
  sim->add_option("--case", bo->cases, "Run only this case (repeatable): " + benchCaseNames() + "; default all")
      ->type_name("NAME");
  sim->add_option("--repeat", bo->repeat,
                  "Time each case N times, each built anew, and report the median rate with the spread (one timing "
                  "varies by about 20 % on a shared machine); default 1")
      ->type_name("N")
      ->check(CLI::Range(1, 100));
  sim->add_option("--disturb", bo->disturb,
                  "Move every point at random by up to this many cells along each axis before timing, as in "
                  "material the impact has deformed (e.g. 0.25; default 0: the cases as built, whose undisturbed "
                  "points have the cheaper 2-node stencils)")
      ->type_name("CELLS")
      ->check(CLI::Range(0.0, 0.5));
  addJsonFlag(*sim, bo->json);
  sim->callback([bo] { benchSim(*bo); });
  auto tb = std::make_shared<BenchTaylorOptions>();
  auto* taylor = bench->add_subcommand(
      "taylor", "Taylor bar at 130, 146 and 190 m/s against Zerilli and Armstrong 1987 (final length, footprint)");
  taylor->add_option("--particles-per-diameter", tb->particlesPerDiameter, "Resolution (default 20)");
  taylor->add_flag("--3d", tb->threeD, "Full 3D model instead of axisymmetric");
  taylor->add_option("--material", tb->material,
                     "Copper card: a library id or a .toml path (default cu_ofhc, Johnson-Cook 1983; cu_ofhc_za: "
                     "Zerilli-Armstrong 1987)");
  taylor->add_option("--threads", tb->threads, "OpenMP threads (default: all cores)");
  addJsonFlag(*taylor, tb->json);
  taylor->callback([tb] { benchTaylor(*tb); });
  registerBenchScenarioCommand(*bench);
}

}  // namespace blt::cli
