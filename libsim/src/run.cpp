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
  const fs::path dir(options.outputDirectory);
  if (writing) fs::create_directories(dir);

  std::ofstream energyCsv;
  std::unique_ptr<PvdSeries> pvd;
  int frameIndex = 0;
  auto writeFrame = [&]() {
    if (!writing) return;
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
  };
  if (writing) {
    pvd = std::make_unique<PvdSeries>((dir / (options.name + ".pvd")).string());
    result.files.push_back(options.name + ".pvd");
    const std::string csv = options.name + "_energy.csv";
    energyCsv.open(dir / csv);
    if (!energyCsv) throw std::runtime_error("cannot write " + (dir / csv).string());
    energyCsv.precision(10);
    energyCsv << "step,time_s,time_step_s,kinetic_J,internal_J,plastic_work_J,viscous_work_J,"
                 "contact_dissipation_J,boundary_work_J,total_J,active_particles\n";
    result.files.push_back(csv);
  }

  const auto start = Clock::now();
  result.initialEnergy = solver.energies();
  const double reference = result.initialEnergy.total();
  const double firstDt = solver.timeStep();
  const long firstStep = solver.stepCount();
  writeEnergy(result.initialEnergy);
  writeFrame();

  const double frameEvery = options.frames > 0 ? options.endTime / options.frames : 2 * options.endTime;
  const double energyEvery = options.energySamples > 0 ? options.endTime / options.energySamples : options.endTime;
  double nextFrame = solver.time() + frameEvery;
  double nextEnergy = solver.time() + energyEvery;
  auto lastProgress = start, lastCheckpoint = start;
  const std::string checkpointFile = options.name + "_checkpoint.bin";
  bool frameCurrent = true;
  double updates = 0;
  EnergyBalance e = result.initialEnergy;

  while (solver.time() < options.endTime) {
    if (options.maxSteps >= 0 && solver.stepCount() - firstStep >= options.maxSteps) {
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
      // Kinetic + internal energy cannot exceed the initial total without external work; the contact and
      // boundary tallies are estimates and stay out of this test.
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
    if (writing && options.checkpointSeconds > 0 &&
        std::chrono::duration<double>(now - lastCheckpoint).count() >= options.checkpointSeconds) {
      lastCheckpoint = now;
      writeCheckpoint<D>((dir / checkpointFile).string(), solver);
    }
    if (hooks.progress && std::chrono::duration<double>(now - lastProgress).count() >= options.progressSeconds) {
      lastProgress = now;
      hooks.progress({solver.stepCount(), solver.time(), options.endTime, solver.timeStep(),
                      std::chrono::duration<double>(now - start).count(), solver.activeParticles(), e});
    }
  }
  result.wallSeconds = std::chrono::duration<double>(Clock::now() - start).count();
  result.finalEnergy = solver.energies();
  if (!frameCurrent) writeFrame();
  if (writing && options.checkpointSeconds > 0) {
    writeCheckpoint<D>((dir / checkpointFile).string(), solver);
    result.files.push_back(checkpointFile);
  }
  result.steps = solver.stepCount() - firstStep;
  result.time = solver.time();
  result.particleUpdatesPerSecond = result.wallSeconds > 0 ? updates / result.wallSeconds : 0.0;

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
      {"solver",
       {{"shape_function", toString(o.shapeFunction)},
        {"update_scheme", toString(o.scheme)},
        {"time_step_safety", o.timeStepSafety},
        {"flip_fraction", o.flipFraction},
        {"bulk_viscosity_quadratic", o.viscosity.quadratic},
        {"bulk_viscosity_linear", o.viscosity.linear},
        {"contact", o.contact.mode == ContactMode::multiField ? "multi-field" : "single-field"},
        {"friction", o.contact.friction},
        {"erosion_expansion", o.erosionExpansion},
        {"erosion_sound_speed", o.erosionSoundSpeed}}},
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
constexpr char kCheckpointMagic[8] = {'B', 'L', 'T', 'C', 'K', 'P', 'T', '1'};

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
void writeCheckpoint(const std::string& path, Solver<D>& solver) {
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
    if (!out) throw std::runtime_error("failed writing " + tmp);
  }
  std::filesystem::rename(tmp, path);
}

template <int D>
void readCheckpoint(const std::string& path, Solver<D>& solver) {
  std::ifstream in(path, std::ios::binary);
  const InputLocation where = InputLocation::file(path);
  if (!in) throw InputError(where, "cannot open the checkpoint", "a NAME_checkpoint.bin written by a run");
  CheckpointHeader h{};
  in.read(reinterpret_cast<char*>(&h), sizeof h);
  if (!in || !std::equal(std::begin(kCheckpointMagic), std::end(kCheckpointMagic), h.magic))
    throw InputError(where, "not a blt checkpoint", "a NAME_checkpoint.bin written by a run");
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
  solver.setClock(h.time, h.steps, h.timeStep);
  solver.setEnergyTallies(h.contactDissipation, h.boundaryWork);
}

template void writeCheckpoint<2>(const std::string&, Solver<2>&);
template void writeCheckpoint<3>(const std::string&, Solver<3>&);
template void readCheckpoint<2>(const std::string&, Solver<2>&);
template void readCheckpoint<3>(const std::string&, Solver<3>&);

template RunResult run<2>(Solver<2>&, const RunOptions&, const RunHooks<2>&);
template RunResult run<3>(Solver<3>&, const RunOptions&, const RunHooks<3>&);

}  // namespace blt::sim
