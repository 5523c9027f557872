#include "blt/sim/impact.hpp"

#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include "blt/core/units.hpp"
#include "blt/sim/output.hpp"

namespace blt::sim {

const char* toString(BisectVariable v) { return v == BisectVariable::diameter ? "diameter" : "velocity"; }

namespace {

// The steadiness window of verdictHeld, a share of the elapsed time rather than a number of checks: checks come
// every few nanoseconds in a hypervelocity run and every microsecond in an ordnance one. A perforation's holes are
// measured when the run stops: stopped at the first sign of perforation, a 1 mm sphere's hole in 1 mm of 5A06 at
// 3 km/s was 0.8 mm and still growing; with a window of 10 % it stopped at 1.9 us, the hole unchanged since
// 1.7 us, and grew to 2.0 mm by 3 us.
constexpr double kSteadyWindow = 0.5;
constexpr double kSteadyMassFraction = 0.002;     // of the projectile's mass
constexpr double kSteadyVelocityFraction = 0.02;  // of the residual velocity

bool holesSteady(const PerforationVerdict& now, const PerforationVerdict& before,
                 const std::vector<double>& layerSpacing) {
  if (now.holes.size() != before.holes.size() || now.holes.size() > layerSpacing.size()) return false;
  for (std::size_t l = 0; l < now.holes.size(); ++l) {
    const double tolerance = 0.5 * layerSpacing[l];
    if (std::fabs(now.holes[l].horizontal - before.holes[l].horizontal) > tolerance ||
        std::fabs(now.holes[l].vertical - before.holes[l].vertical) > tolerance)
      return false;
  }
  return true;
}

// An earlier check's verdict as a checkpoint keeps it (impact runs resumed from one look back over them).
nlohmann::json verdictJson(const PerforationVerdict& v) {
  nlohmann::json holes = nlohmann::json::array();
  for (const LayerHole& h : v.holes)
    holes.push_back({h.name, h.horizontal, h.vertical, h.openingHorizontal, h.openingVertical});
  return {{"perforated", v.perforated},
          {"settled", v.settled},
          {"reason", v.reason},
          {"mass_behind_kg", v.massBehind},
          {"mass_behind_fraction", v.massBehindFraction},
          {"rear_opening", v.rearOpening},
          {"residual_velocity_m_s", v.residualVelocity},
          {"residual_fragment_mass_kg", v.residualFragmentMass},
          {"residual_from", v.residualFrom},
          {"kinetic_fraction", v.kineticFraction},
          {"rearward_kinetic_fraction", v.rearwardKineticFraction},
          {"holes_m", holes}};
}

PerforationVerdict verdictFromJson(const nlohmann::json& j) {
  PerforationVerdict v;
  v.perforated = j.at("perforated").get<bool>();
  v.settled = j.at("settled").get<bool>();
  v.reason = j.at("reason").get<std::string>();
  v.massBehind = j.at("mass_behind_kg").get<double>();
  v.massBehindFraction = j.at("mass_behind_fraction").get<double>();
  v.rearOpening = j.at("rear_opening").get<bool>();
  v.residualVelocity = j.at("residual_velocity_m_s").get<double>();
  v.residualFragmentMass = j.at("residual_fragment_mass_kg").get<double>();
  v.residualFrom = j.at("residual_from").get<std::string>();
  v.kineticFraction = j.at("kinetic_fraction").get<double>();
  v.rearwardKineticFraction = j.at("rearward_kinetic_fraction").get<double>();
  for (const auto& h : j.at("holes_m"))
    v.holes.push_back({h[0].get<std::string>(), h[1].get<double>(), h[2].get<double>(), h[3].get<double>(),
                       h[4].get<double>()});
  return v;
}

template <int D>
ImpactResult runModel(const ImpactScenario& sc, const ImpactRunOptions& options) {
  ImpactModel<D> model = buildImpactModel<D>(sc, options.threads);
  Solver<D>& solver = *model.solver;
  const KineticReference initialKinetic = kineticReference<D>(model);

  RunOptions ro;
  ro.endTime = sc.run.maxTime;
  ro.outputDirectory = options.outputDirectory;
  ro.name = sc.name;
  ro.frames = options.frames ? sc.run.frames : -1;
  ro.checkpointSeconds = options.checkpointSeconds;
  ro.maxSteps = options.maxSteps;
  const std::filesystem::path historyFile = std::filesystem::path(options.outputDirectory) / "verdict_history.csv";
  if (options.resume) {
    if (options.outputDirectory.empty())
      throw InputError(InputLocation::flag("--resume"), "there is no output directory to resume from",
                       "--out DIR, the directory of the run that wrote DIR/" + sc.name + "_checkpoint.bin");
    ro.resumeFrom = (std::filesystem::path(options.outputDirectory) / (sc.name + "_checkpoint.bin")).string();
  }
  RunHooks<D> hooks;
  hooks.progress = options.progress;
  // A settled verdict ends the run only once it has held over the steadiness window (verdictHeld): after a
  // perforation a plug leaves before the projectile and a debris cloud keeps arriving for a while; a rear wall's
  // opening near the limit can close and open again. The verdicts of the checks so far (perforated ones with their
  // holes), to look back over it.
  std::vector<VerdictCheck> checks;
  std::vector<double> layerSpacing;
  for (const auto& layer : model.layers) layerSpacing.push_back(layer.spacing);
  // The verdict at every check, for a plot of why a run stopped when it did (or did not).
  std::ofstream history;
  std::size_t historyRows = 0;
  const bool keepHistory = !options.outputDirectory.empty();
  if (keepHistory && !options.resume) {
    std::filesystem::create_directories(options.outputDirectory);
    history.open(historyFile);
    history << "time_s,kinetic_fraction,rearward_kinetic_fraction,mass_behind_fraction,rear_opening,perforated,"
               "settled\n";
  }
  hooks.saveState = [&] {
    nlohmann::json earlier = nlohmann::json::array();
    for (const VerdictCheck& c : checks) earlier.push_back({c.time, verdictJson(c.verdict)});
    return nlohmann::json{{"checks", earlier}, {"verdict_history_rows", historyRows}};
  };
  hooks.restoreState = [&](const nlohmann::json& state) {
    for (const auto& c : state.at("checks")) checks.push_back({c[0].get<double>(), verdictFromJson(c[1])});
    historyRows = state.at("verdict_history_rows").get<std::size_t>();
    keepFirstLines(historyFile.string(), 1 + historyRows);
    history.open(historyFile, std::ios::app);
  };
  if (sc.run.stopWhenSettled || keepHistory)
    hooks.stop = [&](const Solver<D>& s) {
      // Holes only once perforated (the last check was): steadiness compares them, and 3D holes cost a voxel
      // grid per layer. The first perforated check has none, so steadiness waits for the next.
      const bool holes = sc.run.stopWhenSettled && !checks.empty() && checks.back().verdict.perforated;
      const PerforationVerdict v = assessPerforation<D>(model, sc.verdict, initialKinetic, holes);
      if (history.is_open()) {
        history << s.time() << ',' << v.kineticFraction << ',' << v.rearwardKineticFraction << ','
                << v.massBehindFraction << ',' << v.rearOpening << ',' << v.perforated << ',' << v.settled
                << std::endl;
        ++historyRows;
      }
      if (!sc.run.stopWhenSettled) return std::string();
      const bool held = verdictHeld(checks, v, s.time(), layerSpacing);
      checks.push_back({s.time(), v});
      return held ? "verdict settled: " + std::string(v.perforated ? "perforated" : "not perforated") + " (" +
                        v.reason + ")"
                  : std::string();
    };
  const RunResult r = run<D>(solver, ro, hooks);

  ImpactResult result;
  result.verdict = assessPerforation<D>(model, sc.verdict, initialKinetic, true);
  if (!result.verdict.perforated && perforatedLately(checks, r.time)) {
    result.verdict.perforated = true;
    result.verdict.settled = false;
    result.verdict.reason = "rear wall perforated over the last half of the run, though not at its end (" +
                            result.verdict.reason + ")";
  }
  result.status = r.status;
  result.message = r.message;
  result.mode = D == 2 ? ModelMode::axisymmetric : ModelMode::threeD;
  result.particles = solver.particles().size();
  result.wallSeconds = r.wallSeconds;
  result.endTime = r.time;
  result.resumedAt = r.resumedAt;

  const PerforationVerdict& v = result.verdict;
  nlohmann::json layers = nlohmann::json::array(), holes = nlohmann::json::array(), openings = nlohmann::json::array();
  for (const LayerHole& h : v.holes) {
    layers.push_back(h.name);
    holes.push_back({h.horizontal * 1e3, h.vertical * 1e3});
    openings.push_back({h.openingHorizontal * 1e3, h.openingVertical * 1e3});
  }
  // Energies of the whole target: the model holds a half, a quarter or one radian of it.
  const double whole = 1.0 / model.modelledFraction;
  const auto energy = [&](const EnergyBalance& e) {
    return nlohmann::json{{"kinetic_J", e.kinetic * whole},
                          {"internal_J", e.internal * whole},
                          {"plastic_work_J", e.plasticWork * whole},
                          {"viscous_work_J", e.viscousWork * whole},
                          {"contact_dissipation_J", e.contactDissipation * whole},
                          {"boundary_work_J", e.boundaryWork * whole}};
  };
  // What the solver took out, per body, for the whole target: points eroded (either erosion rule, or failed and
  // turned inside out) and points that flew off the grid (spray off the front face, debris past the lateral
  // edges), each with its mass and the kinetic energy it had when it went. A removed point keeps its last
  // velocity, so this is kinetic energy of the energy history that no longer acts on anything, and eroded
  // momentum that no layer behind feels. With solver.keep_eroded_mass eroded points stay, as stress-free mass.
  nlohmann::json removed = nlohmann::json::array();
  {
    const Particles<D>& pts = solver.particles();
    struct Tally {
      std::size_t particles = 0;
      double mass = 0, kinetic = 0;
      nlohmann::json json(double whole) const {
        return {{"particles", particles}, {"mass_kg", mass * whole}, {"kinetic_energy_J", kinetic * whole}};
      }
    };
    const std::size_t bodies = model.layers.size() + 1;
    std::vector<Tally> eroded(bodies), offGrid(bodies), kept(bodies);
    std::vector<std::array<double, 2 * D>> offGridByFace(bodies);  // mass through each face
    std::vector<double> mass(bodies, 0.0);
    for (std::size_t p = 0; p < pts.size(); ++p) {
      const auto b = static_cast<std::size_t>(pts.body[p]);
      if (b >= bodies) continue;
      mass[b] += pts.mass[p];
      const bool off = !pts.active[p] && solver.offGrid(pts.position[p]);
      if (const int face = off ? solver.exitFace(pts.position[p]) : -1; face >= 0)
        offGridByFace[b][static_cast<std::size_t>(face)] += pts.mass[p];
      Tally* t = off ? &offGrid[b] : !pts.active[p] ? &eroded[b] : pts.failed[p] == kEroded ? &kept[b] : nullptr;
      if (!t) continue;
      ++t->particles;
      t->mass += pts.mass[p];
      t->kinetic += 0.5 * pts.mass[p] * pts.velocity[p].squaredNorm();
    }
    // Faces by axis and side: x-, x+, y-, y+, z-, z+ (r-, r+, z-, z+ in axisymmetric runs). Only those crossed.
    const auto faceName = [](int face) {
      static const char* const axes3[] = {"x", "y", "z"};
      static const char* const axes2[] = {"r", "z"};
      return std::string(D == 2 ? axes2[face / 2] : axes3[face / 2]) + (face % 2 ? "+" : "-");
    };
    for (std::size_t b = 0; b < bodies; ++b) {
      nlohmann::json faces = nlohmann::json::object();
      for (int f = 0; f < 2 * D; ++f)
        if (offGridByFace[b][static_cast<std::size_t>(f)] > 0)
          faces[faceName(f)] = offGridByFace[b][static_cast<std::size_t>(f)] * whole;
      nlohmann::json off = offGrid[b].json(whole);
      off["mass_by_face_kg"] = faces;
      removed.push_back({{"body", b == 0 ? std::string("projectile") : model.layers[b - 1].name},
                         {"body_mass_kg", mass[b] * whole},
                         {"eroded", eroded[b].json(whole)},
                         {"off_grid", off},
                         {"eroded_kept", kept[b].json(whole)}});
    }
  }
  nlohmann::json doc = {
      {"scenario", sc.name},
      {"scenario_file", sc.path},
      {"settings", sc.settings},
      {"mode", toString(result.mode)},
      {"model", D == 2 ? "axisymmetric (r, z)" : (model.mirrorX ? "3D quarter model" : "3D half model")},
      {"projectile_diameter_mm", sc.projectile.diameter * 1e3},
      {"impact_velocity_m_s", sc.projectile.velocity},
      {"impact_angle_deg", sc.projectile.angle * 180.0 / M_PI},
      {"perforated", v.perforated},
      {"settled", v.settled},
      {"verdict_reason", v.reason},
      {"rear_wall_opening", v.rearOpening},
      {"mass_behind_rear_wall_kg", v.massBehind},
      {"mass_behind_rear_wall_fraction", v.massBehindFraction},
      {"residual_velocity_m_s", v.residualVelocity},
      {"residual_fragment_mass_kg", v.residualFragmentMass},
      {"residual_velocity_of", v.residualFrom},
      {"layers", layers},
      {"hole_size_mm", holes},
      {"opening_size_mm", openings},
      {"kinetic_energy_fraction", v.kineticFraction},
      {"rearward_kinetic_energy_fraction", v.rearwardKineticFraction},
      {"energy_initial", energy(r.initialEnergy)},
      {"energy_final", energy(r.finalEnergy)},
      {"status", toString(r.status)},
      {"message", r.message},
      {"time_s", r.time},
      {"max_time_s", sc.run.maxTime},
      {"steps", r.steps},
      {"particles", result.particles},
      {"inactive_particles", solver.particles().size() - solver.activeParticles()},
      {"removed", removed},
      {"wall_time_s", r.wallSeconds},
      {"resumed_at_time_s", std::isnan(r.resumedAt) ? nlohmann::json() : nlohmann::json(r.resumedAt)},
      {"run", r.summary}};
  result.summary = doc;
  if (!options.outputDirectory.empty()) {
    std::ofstream out(std::filesystem::path(options.outputDirectory) / (sc.name + "_summary.json"));
    out << doc.dump(2) << "\n";
  }
  return result;
}

}  // namespace

bool perforatedLately(const std::vector<VerdictCheck>& earlier, double time) {
  const double since = (1.0 - kSteadyWindow) * time;
  for (const VerdictCheck& c : earlier)
    if (c.time >= since && c.verdict.perforated) return true;
  return false;
}

bool verdictHeld(const std::vector<VerdictCheck>& earlier, const PerforationVerdict& now, double time,
                 const std::vector<double>& layerSpacing) {
  if (!now.settled) return false;
  if (!now.perforated) return !perforatedLately(earlier, time);
  const double since = (1.0 - kSteadyWindow) * time;
  // The latest earlier check at least the window ago.
  const PerforationVerdict* then = nullptr;
  for (const VerdictCheck& c : earlier)
    if (c.time <= since) then = &c.verdict;
  return then && then->perforated && std::fabs(now.massBehindFraction - then->massBehindFraction) < kSteadyMassFraction &&
         std::fabs(now.residualVelocity - then->residualVelocity) <= kSteadyVelocityFraction * now.residualVelocity &&
         holesSteady(now, *then, layerSpacing);
}

ImpactResult runImpact(const ImpactScenario& scenario, const ImpactRunOptions& options) {
  return scenario.resolvedMode() == ModelMode::axisymmetric ? runModel<2>(scenario, options)
                                                            : runModel<3>(scenario, options);
}

const BisectionRun* BisectionResult::largestSafeRun() const {
  for (const BisectionRun& r : runs)
    if (!r.perforated && r.value == largestSafe) return &r;
  return nullptr;
}

BisectionResult bisect(const BisectionOptions& o, const std::function<BisectionRun(double)>& evaluate,
                       const std::function<void(const BisectionRun&)>& onRun) {
  BisectionResult result;
  const auto unit = o.variable == BisectVariable::diameter ? "mm" : "m/s";
  if (!(o.lower < o.upper))
    throw InputError(InputLocation::flag("--lo"), "the bracket's lower end must lie below its upper end",
                     "--lo below --hi");
  if (!(o.tolerance > 0)) throw InputError(InputLocation::flag("--tol"), "the tolerance must be positive");
  // Runs one value; false when the run could not give a verdict (it is recorded all the same).
  const auto probe = [&](double value) {
    BisectionRun r = evaluate(value);
    r.value = value;
    result.runs.push_back(r);
    if (onRun) onRun(r);
    if (r.status == RunStatus::unstable) {
      result.message = "the run at " + units::format(value, unit, 5) + " went unstable" +
                       (r.summary.is_object() ? ": " + r.summary.value("message", std::string()) : std::string());
      return false;
    }
    if (r.perforated) result.smallestPerforating = std::isnan(result.smallestPerforating) ? value : std::min(result.smallestPerforating, value);
    else result.largestSafe = std::isnan(result.largestSafe) ? value : std::max(result.largestSafe, value);
    return true;
  };
  double lo = o.lower, hi = o.upper;
  if (o.checkBracket) {
    if (!probe(lo)) return result;
    if (result.runs.back().perforated) {
      result.message = "the bracket does not hold: perforated already at the lower end " + units::format(lo, unit, 5);
      return result;
    }
    if (!probe(hi)) return result;
    if (!result.runs.back().perforated) {
      result.message = "the bracket does not hold: not perforated at the upper end " + units::format(hi, unit, 5);
      return result;
    }
  } else {
    result.largestSafe = lo;
    result.smallestPerforating = hi;
  }
  while (0.5 * (hi - lo) > o.tolerance) {
    if (static_cast<int>(result.runs.size()) >= o.maxRuns) {
      result.message = "stopped at the limit of " + std::to_string(o.maxRuns) + " runs";
      return result;
    }
    const double mid = 0.5 * (lo + hi);
    if (!probe(mid)) return result;
    (result.runs.back().perforated ? hi : lo) = mid;
  }
  result.largestSafe = lo;
  result.smallestPerforating = hi;
  result.resolved = true;
  return result;
}

BisectionResult bisectScenario(const ImpactScenario& scenario, const BisectionOptions& options,
                               const ImpactRunOptions& runOptions,
                               const std::function<void(const BisectionRun&)>& onRun) {
  int index = 0;
  const auto evaluate = [&](double value) {
    ImpactScenario sc = scenario;
    (options.variable == BisectVariable::diameter ? sc.projectile.diameter : sc.projectile.velocity) = value;
    ImpactRunOptions ro = runOptions;
    if (!ro.outputDirectory.empty()) {
      char name[32];
      std::snprintf(name, sizeof name, "run_%02d", index);
      ro.outputDirectory = (std::filesystem::path(runOptions.outputDirectory) / name).string();
    }
    ++index;
    const ImpactResult r = runImpact(sc, ro);
    BisectionRun br;
    br.perforated = r.verdict.perforated;
    br.settled = r.verdict.settled;
    br.status = r.status;
    br.residualVelocity = r.verdict.residualVelocity;
    br.wallSeconds = r.wallSeconds;
    br.summary = r.summary;
    return br;
  };
  return bisect(options, evaluate, onRun);
}

}  // namespace blt::sim
