#pragma once
// Running a solver to an end time: field frames and the energy history at fixed intervals, progress reports,
// an optional stop test (the perforation verdict of a scenario), and the instability guard. A run that goes
// unstable (a non-finite particle state, kinetic + internal energy growing past the bound, the time step collapsing) stops
// with a message that says where and when; everything written up to then is kept.

#include <functional>
#include <limits>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "blt/sim/solver.hpp"

namespace blt::sim {

struct RunOptions {
  double endTime = 0;                // s
  std::string outputDirectory;       // empty: write nothing
  std::string name = "run";          // file stem: NAME.pvd, NAME_0000.vtu, NAME_energy.csv, NAME_summary.json
  int frames = 10;                   // particle frames written over [0, endTime] (plus the last state); -1: none
  int energySamples = 200;           // rows of the energy history over [0, endTime]
  // Unstable when kinetic + internal energy exceeds (1 + energyGrowthLimit) x the initial total (the model has
  // no external loads, so nothing can add energy).
  double energyGrowthLimit = 0.05;
  double minTimeStepRatio = 1e-4;    // unstable when dt falls below this fraction of the first step's
  long maxSteps = -1;                // stop after this many steps of this part (benchmarks); -1: no limit
  double progressSeconds = 2.0;      // wall time between progress reports
  // Wall time between checkpoints NAME_checkpoint.bin (and one at the end, unless the run went unstable); 0
  // writes none. Needs an output directory.
  double checkpointSeconds = 0;
  // A checkpoint to continue from instead of from the solver's present state, which must be the state the
  // checkpointed run started from (the solver set up again from the same inputs; checked by a hash of every
  // particle array). The clock, the particles, the energy reference and the output schedule are restored, the
  // energy history and the frame series are cut back to the checkpoint and appended to, and the hooks get their
  // own state back: the run goes on exactly as the uninterrupted one would have. `endTime` may lie beyond the
  // first run's, to run a finished run longer.
  std::string resumeFrom;
};

enum class RunStatus { completed, stopped, unstable, stepLimit };
const char* toString(RunStatus s);

struct RunProgress {
  long step = 0;
  double time = 0, endTime = 0, timeStep = 0, wallSeconds = 0;
  std::size_t activeParticles = 0;
  EnergyBalance energy;
};

struct RunResult {
  RunStatus status = RunStatus::completed;
  std::string message;  // why the run stopped, for stopped and unstable runs
  long steps = 0;
  double time = 0, wallSeconds = 0;
  double particleUpdatesPerSecond = 0;
  EnergyBalance initialEnergy, finalEnergy;
  std::vector<std::string> files;  // written, relative to the output directory
  nlohmann::json summary;          // what NAME_summary.json holds
  // Resumed runs: the time of the checkpoint it went on from (NaN otherwise). Steps, wall time and the energy
  // reference are of the whole run, from its start; particle updates per second of all its parts.
  double resumedAt = std::numeric_limits<double>::quiet_NaN();
};

template <int D>
struct RunHooks {
  std::function<void(const RunProgress&)> progress;
  // Returns a non-empty reason to stop early (checked at every energy sample).
  std::function<std::string(const Solver<D>&)> stop;
  // State of the caller's own that a checkpoint carries (an impact run's earlier verdicts), saved with every
  // checkpoint and handed back on resuming.
  std::function<nlohmann::json()> saveState;
  std::function<void(const nlohmann::json&)> restoreState;
};

template <int D>
RunResult run(Solver<D>& solver, const RunOptions& options, const RunHooks<D>& hooks = {});

// The state a step needs (particles, clock, energy tallies) in a binary file, with `runState` (what a run needs
// to go on: its output schedule, energy reference, the hooks' state) after it as JSON. Written to a temporary
// name and renamed, so an interrupted write leaves the previous checkpoint whole. Grid fields are rebuilt
// every step.
template <int D>
void writeCheckpoint(const std::string& path, Solver<D>& solver, const nlohmann::json& runState = {});
// Restores a checkpoint into a solver set up from the same scenario (same dimension and particle count) and
// returns its run state (null when it was written without). Throws InputError naming the file for a file that
// is not a checkpoint or does not match.
template <int D>
nlohmann::json readCheckpoint(const std::string& path, Solver<D>& solver);

// FNV-1a (64 bit, hex) over every particle array: the identity of a solver's state (a resumed run checks that
// it starts from the state its checkpoint's run started from).
template <int D>
std::string particleStateHash(Solver<D>& solver);

}  // namespace blt::sim
