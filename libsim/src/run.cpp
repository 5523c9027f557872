#include "blt/sim/run.hpp"

#include <omp.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <tuple>

#include "blt/core/error.hpp"
#include "blt/core/units.hpp"
#include "blt/sim/output.hpp"

namespace blt::sim {

const char* toString(RunStatus s) {
  switch (s) {
    case RunStatus::completed: return "completed";
    case RunStatus::stopped: return "stopped";
    case RunStatus::unstable: return "unstable";
    case RunStatus::stepLimit: return "step-limit";
  }
  return "?";
}

namespace {

nlohmann::json energyJson(const EnergyBalance& e) {
  return {{"kinetic_J", e.kinetic},         {"internal_J", e.internal},
          {"plastic_work_J", e.plasticWork}, {"viscous_work_J", e.viscousWork},
          {"contact_dissipation_J", e.contactDissipation}, {"boundary_work_J", e.boundaryWork},
          {"total_J", e.total()}};
}

template <int D>
std::string describeParticle(const Solver<D>& s, long p) {
  const auto& P = s.particles();
  std::ostringstream out;
  out.precision(4);
  out << "particle " << p << " (material " << s.materials()[P.material[p]].id << ", body " << P.body[p] << ") at (";
  for (int a = 0; a < D; ++a) out << (a ? ", " : "") << P.position[p][a] * 1e3;
  out << ") mm";
  return out.str();
}

template <int D>
long fastestParticle(const Solver<D>& s) {
  const auto& P = s.particles();
  long best = -1;
  double vmax = -1;
  for (std::size_t p = 0; p < P.size(); ++p) {
    const double v = P.velocity[p].norm();
    if (v > vmax) {
      vmax = v;
      best = static_cast<long>(p);
    }
  }
  return best;
}

EnergyBalance energyFromJson(const nlohmann::json& j) {
  EnergyBalance e;
  e.kinetic = j.at("kinetic_J").get<double>();
  e.internal = j.at("internal_J").get<double>();
  e.plasticWork = j.at("plastic_work_J").get<double>();
  e.viscousWork = j.at("viscous_work_J").get<double>();
  e.contactDissipation = j.at("contact_dissipation_J").get<double>();
  e.boundaryWork = j.at("boundary_work_J").get<double>();
  return e;
}

// Frames NAME_KKKK.vtu from index `first` on: what an interrupted run wrote after its checkpoint and the
// resumed one did not write again.
void removeFramesFrom(const std::filesystem::path& dir, const std::string& name, int first) {
  for (int k = first;; ++k) {
    char file[64];
    std::snprintf(file, sizeof file, "_%04d.vtu", k);
    if (!std::filesystem::remove(dir / (name + file))) return;
  }
}

std::string when(long step, double time) {
  std::ostringstream out;
  out.precision(5);
  out << "step " << step << ", t = " << time * 1e6 << " us";
  return out.str();
}

}  // namespace

template <int D>
RunResult run(Solver<D>& solver, const RunOptions& options, const RunHooks<D>& hooks) {
  namespace fs = std::filesystem;
  using Clock = std::chrono::steady_clock;
  RunResult result;
  const bool writing = !options.outputDirectory.empty();
  const bool resuming = !options.resumeFrom.empty();
  const bool checkpointing = writing && options.checkpointSeconds > 0;
  const bool framing = writing && options.frames >= 0;
  const fs::path dir(options.outputDirectory);
  if (writing) fs::create_directories(dir);
  if (resuming && !writing)
    throw std::invalid_argument("a resumed run needs the output directory of the run it continues");

  // The state the run started from, so that a checkpoint is only resumed on the model it was made of.
  const std::string startHash = checkpointing || resuming ? particleStateHash<D>(solver) : std::string();
  nlohmann::json restored;
  if (resuming) {
    restored = readCheckpoint<D>(options.resumeFrom, solver);
    const InputLocation where = InputLocation::file(options.resumeFrom);
    if (!restored.is_object() || !restored.contains("start_state_hash"))
      throw InputError(where, "the checkpoint holds no run state", "a checkpoint written by a run");
    if (restored["start_state_hash"] != startHash)
      throw InputError(where,
                       "the checkpoint's run started from another model (start state " +
                           restored["start_state_hash"].get<std::string>() + ", this one " + startHash + ")",
                       "the scenario and settings of the run that wrote it (only the end time may differ)");
    result.resumedAt = solver.time();
  }

  std::ofstream energyCsv;
  std::unique_ptr<PvdSeries> pvd;
  int frameIndex = 0;
  long energyRows = 0;
  auto writeFrame = [&]() {
    if (!framing) return;
    char name[64];
    std::snprintf(name, sizeof name, "_%04d.vtu", frameIndex++);
    const std::string file = options.name + name;
    writeVtu<D>((dir / file).string(), solver.particles());
    pvd->add(solver.time(), file);
    result.files.push_back(file);
  };
  auto writeEnergy = [&](const EnergyBalance& e) {
    if (!writing) return;
    energyCsv << solver.stepCount() << ',' << solver.time() << ',' << solver.timeStep() << ',' << e.kinetic << ','
              << e.internal << ',' << e.plasticWork << ',' << e.viscousWork << ',' << e.contactDissipation << ','
              << e.boundaryWork << ',' << e.total() << ',' << solver.activeParticles() << '\n';
    energyCsv.flush();
    ++energyRows;
  };
  const std::string csv = options.name + "_energy.csv";
  if (framing) {
    pvd = std::make_unique<PvdSeries>((dir / (options.name + ".pvd")).string());
    result.files.push_back(options.name + ".pvd");
  }
  if (writing) {
    if (resuming) {
      // Rows written after the checkpoint (by the interrupted run) are dropped: the resumed run writes them again.
      energyRows = restored["energy_rows"].get<long>();
      keepFirstLines((dir / csv).string(), 1 + energyRows);
      energyCsv.open(dir / csv, std::ios::app);
    } else {
      energyCsv.open(dir / csv);
    }
    if (!energyCsv) throw std::runtime_error("cannot write " + (dir / csv).string());
    energyCsv.precision(10);
    if (!resuming)
      energyCsv << "step,time_s,time_step_s,kinetic_J,internal_J,plastic_work_J,viscous_work_J,"
                   "contact_dissipation_J,boundary_work_J,total_J,active_particles\n";
    result.files.push_back(csv);
  }

  const auto start = Clock::now();
  double wallBefore = 0, updates = 0;
  double firstDt = solver.timeStep();
  long firstStep = solver.stepCount();
  const double frameEvery = options.frames > 0 ? options.endTime / options.frames : 2 * options.endTime;
  const double energyEvery = options.energySamples > 0 ? options.endTime / options.energySamples : options.endTime;
  double nextFrame = solver.time() + frameEvery;
  double nextEnergy = solver.time() + energyEvery;
  bool frameCurrent = true;
  if (resuming) {
    result.initialEnergy = energyFromJson(restored["initial_energy"]);
    firstDt = restored["first_time_step_s"].get<double>();
    firstStep = restored["first_step"].get<long>();
    nextFrame = restored["next_frame_s"].get<double>();
    nextEnergy = restored["next_energy_s"].get<double>();
    wallBefore = restored["wall_time_s"].get<double>();
    updates = restored["particle_updates"].get<double>();
    if (pvd)
      for (const auto& f : restored["frames"]) {
        pvd->add(f[0].get<double>(), f[1].get<std::string>());
        result.files.push_back(f[1].get<std::string>());
      }
    frameIndex = pvd ? static_cast<int>(pvd->frames().size()) : 0;
    frameCurrent = pvd && !pvd->frames().empty() && pvd->frames().back().first == solver.time();
    if (hooks.restoreState) hooks.restoreState(restored["caller"]);
  } else {
    result.initialEnergy = solver.energies();
    writeEnergy(result.initialEnergy);
    writeFrame();
  }
  const double reference = result.initialEnergy.total();
  const long stepsBefore = solver.stepCount();  // the step limit counts this part's steps
  auto lastProgress = start, lastCheckpoint = start;
  const std::string checkpointFile = options.name + "_checkpoint.bin";
  const auto checkpoint = [&]() {
    nlohmann::json state = {{"start_state_hash", startHash},
                            {"initial_energy", energyJson(result.initialEnergy)},
                            {"first_time_step_s", firstDt},
                            {"first_step", firstStep},
                            {"next_frame_s", nextFrame},
                            {"next_energy_s", nextEnergy},
                            {"energy_rows", energyRows},
                            {"frames", pvd ? pvd->frames() : std::vector<std::pair<double, std::string>>()},
                            {"wall_time_s", wallBefore + std::chrono::duration<double>(Clock::now() - start).count()},
                            {"particle_updates", updates},
                            {"caller", hooks.saveState ? hooks.saveState() : nlohmann::json()}};
    writeCheckpoint<D>((dir / checkpointFile).string(), solver, state);
  };
  EnergyBalance e = result.initialEnergy;

  while (solver.time() < options.endTime) {
    if (options.maxSteps >= 0 && solver.stepCount() - stepsBefore >= options.maxSteps) {
      result.status = RunStatus::stepLimit;
      result.message = "stopped after the step limit of " + std::to_string(options.maxSteps) + " steps";
      break;
    }
    updates += static_cast<double>(solver.activeParticles());
    solver.step();
    frameCurrent = false;
    // Every step: a collapsing time step would otherwise crawl towards the next energy sample for hours.
    if (solver.timeStep() < options.minTimeStepRatio * firstDt) {
      std::ostringstream msg;
      msg.precision(4);
      msg << "unstable at " << when(solver.stepCount(), solver.time()) << ": time step " << solver.timeStep()
          << " s fell below " << options.minTimeStepRatio << " of the first step (" << firstDt << " s)";
      result.status = RunStatus::unstable;
      result.message = msg.str();
      break;
    }
    const bool last = solver.time() >= options.endTime;
    if (solver.time() >= nextEnergy || last) {
      nextEnergy += energyEvery;
      e = solver.energies();
      writeEnergy(e);
      if (!std::isfinite(e.total())) {
        const long p = solver.firstNonFiniteParticle();
        result.status = RunStatus::unstable;
        result.message = "unstable at " + when(solver.stepCount(), solver.time()) + ": " +
                         (p >= 0 ? describeParticle(solver, p) + " has a non-finite state" : "non-finite energy");
        break;
      }
      // Kinetic + internal energy cannot exceed the initial total without external work. The tallies stay out of
      // this test: energy that the contact correction makes (a negative contact tally, see EnergyBalance) is
      // growth of the model's own energy all the same, and it is what this test is there to catch.
      const double held = e.kinetic + e.internal;
      if (reference > 0 && held > (1.0 + options.energyGrowthLimit) * reference) {
        std::ostringstream msg;
        msg.precision(4);
        msg << "unstable at " << when(solver.stepCount(), solver.time()) << ": kinetic + internal energy " << held
            << " J exceeds the initial " << reference << " J by more than " << options.energyGrowthLimit * 100
            << " %; fastest " << describeParticle(solver, fastestParticle(solver));
        result.status = RunStatus::unstable;
        result.message = msg.str();
        break;
      }
      if (hooks.stop) {
        const std::string reason = hooks.stop(solver);
        if (!reason.empty()) {
          result.status = RunStatus::stopped;
          result.message = reason;
          break;
        }
      }
    }
    if (solver.time() >= nextFrame && !last) {
      nextFrame += frameEvery;
      writeFrame();
      frameCurrent = true;
    }
    const auto now = Clock::now();
    if (checkpointing && std::chrono::duration<double>(now - lastCheckpoint).count() >= options.checkpointSeconds) {
      lastCheckpoint = now;
      checkpoint();
    }
    if (hooks.progress && std::chrono::duration<double>(now - lastProgress).count() >= options.progressSeconds) {
      lastProgress = now;
      hooks.progress({solver.stepCount(), solver.time(), options.endTime, solver.timeStep(),
                      wallBefore + std::chrono::duration<double>(now - start).count(), solver.activeParticles(), e});
    }
  }
  result.finalEnergy = solver.energies();
  if (!frameCurrent) writeFrame();
  if (framing) removeFramesFrom(dir, options.name, frameIndex);  // left by an interrupted run, past this one's
  // An unstable state is not worth going on from; the last good checkpoint stays.
  if (checkpointing && result.status != RunStatus::unstable) checkpoint();
  if (checkpointing || resuming) result.files.push_back(checkpointFile);
  result.wallSeconds = wallBefore + std::chrono::duration<double>(Clock::now() - start).count();
  result.steps = solver.stepCount() - firstStep;
  result.time = solver.time();
  result.particleUpdatesPerSecond = result.wallSeconds > 0 ? updates / result.wallSeconds : 0.0;
  if (resuming) result.message += (result.message.empty() ? "" : "; ") + std::string("resumed from a checkpoint at ") +
                                  units::format(result.resumedAt, "us", 5);

  const auto& o = solver.options();
  const auto& g = solver.grid();
  nlohmann::json boundaries = nlohmann::json::array();
  for (auto b : g.boundary) boundaries.push_back(toString(b));
  nlohmann::json materials = nlohmann::json::array();
  for (const auto& m : solver.materials()) materials.push_back(m.id);
  std::vector<double> lower(g.lower.data(), g.lower.data() + D), upper(g.upper.data(), g.upper.data() + D);
  std::vector<int> nodes(solver.nodeCounts().data(), solver.nodeCounts().data() + D);
  result.summary = {
      {"status", toString(result.status)},
      {"message", result.message},
      {"geometry", D == 3 ? "3d" : (o.axisymmetric ? "axisymmetric" : "plane-strain")},
      {"steps", result.steps},
      {"time_s", result.time},
      {"end_time_s", options.endTime},
      {"wall_time_s", result.wallSeconds},
      {"threads", o.threads > 0 ? o.threads : omp_get_max_threads()},
      {"particles", solver.particles().size()},
      {"active_particles", solver.activeParticles()},
      {"particle_updates_per_s", result.particleUpdatesPerSecond},
      {"memory_bytes", solver.memoryBytes()},
      {"resumed_at_time_s", resuming ? nlohmann::json(result.resumedAt) : nlohmann::json()},
      {"solver",
       {{"shape_function", toString(o.shapeFunction)},
        {"update_scheme", toString(o.scheme)},
        {"time_step_safety", o.timeStepSafety},
        {"flip_fraction", o.flipFraction},
        {"bulk_viscosity_quadratic", o.viscosity.quadratic},
        {"bulk_viscosity_linear", o.viscosity.linear},
        {"contact", o.contact.mode == ContactMode::multiField ? "multi-field" : "single-field"},
        {"friction", o.contact.friction},
        {"contact_strain", o.contact.strain == ContactStrain::perNode ? "per-node" : "per-particle"},
        {"erosion_expansion", o.erosionExpansion},
        {"erosion_sound_speed", o.erosionSoundSpeed},
        {"keep_eroded_mass", o.keepErodedMass}}},
      {"grid",
       {{"lower_m", lower}, {"upper_m", upper}, {"cell_m", g.cellSize}, {"nodes", nodes}, {"boundaries", boundaries}}},
      {"materials", materials},
      {"energy_initial", energyJson(result.initialEnergy)},
      {"energy_final", energyJson(result.finalEnergy)},
      {"files", result.files}};
  if (writing) {
    const std::string file = options.name + "_summary.json";
    result.summary["files"].push_back(file);
    std::ofstream out(dir / file);
    out << result.summary.dump(2) << "\n";
    result.files.push_back(file);
  }
  return result;
}

namespace {
// Version 2 adds the run state (JSON, after the particle arrays).
constexpr char kCheckpointMagic[8] = {'B', 'L', 'T', 'C', 'K', 'P', 'T', '2'};

struct CheckpointHeader {
  char magic[8];
  std::int32_t dimension;
  std::uint64_t particles;
  double time;
  std::int64_t steps;
  double timeStep, contactDissipation, boundaryWork;
};
}  // namespace

template <int D>
void writeCheckpoint(const std::string& path, Solver<D>& solver, const nlohmann::json& runState) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary);
    if (!out) throw std::runtime_error("cannot write " + tmp);
    CheckpointHeader h{};
    std::copy(std::begin(kCheckpointMagic), std::end(kCheckpointMagic), h.magic);
    h.dimension = D;
    h.particles = solver.particles().size();
    h.time = solver.time();
    h.steps = solver.stepCount();
    h.timeStep = solver.timeStep();
    std::tie(h.contactDissipation, h.boundaryWork) = solver.energyTallies();
    out.write(reinterpret_cast<const char*>(&h), sizeof h);
    solver.particles().forEachArray([&](auto& v) {
      const std::uint64_t bytes = v.size() * sizeof(v[0]);
      out.write(reinterpret_cast<const char*>(&bytes), sizeof bytes);
      out.write(reinterpret_cast<const char*>(v.data()), static_cast<std::streamsize>(bytes));
    });
    const std::string state = runState.dump();
    const std::uint64_t bytes = state.size();
    out.write(reinterpret_cast<const char*>(&bytes), sizeof bytes);
    out.write(state.data(), static_cast<std::streamsize>(bytes));
    if (!out) throw std::runtime_error("failed writing " + tmp);
  }
  std::filesystem::rename(tmp, path);
}

template <int D>
nlohmann::json readCheckpoint(const std::string& path, Solver<D>& solver) {
  std::ifstream in(path, std::ios::binary);
  const InputLocation where = InputLocation::file(path);
  if (!in) throw InputError(where, "cannot open the checkpoint", "a NAME_checkpoint.bin written by a run with checkpoints (blt sim run --checkpoint-every)");
  CheckpointHeader h{};
  in.read(reinterpret_cast<char*>(&h), sizeof h);
  if (!in || !std::equal(std::begin(kCheckpointMagic), std::end(kCheckpointMagic), h.magic))
    throw InputError(where, "not a blt checkpoint of this version", "a NAME_checkpoint.bin written by this build");
  if (h.dimension != D)
    throw InputError(where, "checkpoint of a " + std::to_string(h.dimension) + "D run",
                     "a checkpoint of a " + std::to_string(D) + "D run");
  if (h.particles != solver.particles().size())
    throw InputError(where, "checkpoint holds " + std::to_string(h.particles) + " particles, the scenario " +
                                std::to_string(solver.particles().size()),
                     "a checkpoint of the same scenario");
  solver.particles().forEachArray([&](auto& v) {
    std::uint64_t bytes = 0;
    in.read(reinterpret_cast<char*>(&bytes), sizeof bytes);
    if (!in || bytes != v.size() * sizeof(v[0]))
      throw InputError(where, "truncated or mismatched checkpoint", "a checkpoint of the same scenario");
    in.read(reinterpret_cast<char*>(v.data()), static_cast<std::streamsize>(bytes));
    if (!in) throw InputError(where, "truncated checkpoint", "a complete checkpoint");
  });
  std::uint64_t bytes = 0;
  in.read(reinterpret_cast<char*>(&bytes), sizeof bytes);
  std::string state(bytes, '\0');
  in.read(state.data(), static_cast<std::streamsize>(bytes));
  if (!in) throw InputError(where, "truncated checkpoint (run state)", "a complete checkpoint");
  solver.setClock(h.time, h.steps, h.timeStep);
  solver.setEnergyTallies(h.contactDissipation, h.boundaryWork);
  return nlohmann::json::parse(state);
}

template <int D>
std::string particleStateHash(Solver<D>& solver) {
  std::uint64_t h = 1469598103934665603ull;
  solver.particles().forEachArray([&](auto& v) {
    const auto* bytes = reinterpret_cast<const unsigned char*>(v.data());
    for (std::size_t i = 0, n = v.size() * sizeof(v[0]); i < n; ++i) h = (h ^ bytes[i]) * 1099511628211ull;
  });
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(h));
  return hex;
}

template void writeCheckpoint<2>(const std::string&, Solver<2>&, const nlohmann::json&);
template void writeCheckpoint<3>(const std::string&, Solver<3>&, const nlohmann::json&);
template nlohmann::json readCheckpoint<2>(const std::string&, Solver<2>&);
template nlohmann::json readCheckpoint<3>(const std::string&, Solver<3>&);
template std::string particleStateHash<2>(Solver<2>&);
template std::string particleStateHash<3>(Solver<3>&);

template RunResult run<2>(Solver<2>&, const RunOptions&, const RunHooks<2>&);
template RunResult run<3>(Solver<3>&, const RunOptions&, const RunHooks<3>&);

}  // namespace blt::sim
