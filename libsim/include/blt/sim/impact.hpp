#pragma once
// Running an impact scenario to its verdict, and bisection on the projectile's diameter or velocity for the
// ballistic limit: the largest value that does not perforate and the smallest that does.

#include <functional>
#include <limits>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "blt/sim/run.hpp"
#include "blt/sim/scenario.hpp"
#include "blt/sim/verdict.hpp"

namespace blt::sim {

struct ImpactRunOptions {
  std::string outputDirectory;  // empty: write nothing; else frames (PVD + VTU), energy CSV, summary JSON
  int threads = 0;              // as SolverOptions::threads
  std::function<void(const RunProgress&)> progress;
  // Wall time between checkpoints OUT/NAME_checkpoint.bin (and one at the end); 0: none. Needs the directory.
  double checkpointSeconds = 0;
  // Go on from OUT/NAME_checkpoint.bin (RunOptions::resumeFrom): the scenario must build the model the checkpoint's
  // run started from; run.max_time may be raised to run a finished run longer.
  bool resume = false;
  bool frames = true;  // false: no particle frames (VTU, PVD), only the histories, the summary and checkpoints
  long maxSteps = -1;  // stop after this many steps of this run (an interrupted run, for tests); -1: no limit
};

struct ImpactResult {
  PerforationVerdict verdict;  // of the last state, with the hole of every layer
  RunStatus status = RunStatus::completed;
  std::string message;         // why the run ended early (settled verdict, instability)
  ModelMode mode = ModelMode::axisymmetric;
  std::size_t particles = 0;
  double wallSeconds = 0, endTime = 0;  // wall time of the whole run, resumed parts included
  double resumedAt = std::numeric_limits<double>::quiet_NaN();  // s, the checkpoint a resumed run went on from
  // Everything above and the run summary, in the units the keys name (perforated, residual_velocity_m_s,
  // layers: names front to rear, hole_size_mm: [D_h, D_v] per layer in that order, energies of the whole target
  // in J, wall_time_s, ...).
  nlohmann::json summary;
};

// One check of the verdict during a run (the run's stop test makes one every few steps).
struct VerdictCheck {
  double time = 0;  // s
  PerforationVerdict verdict;
};

// The stop rule of a run with run.stop_when_settled: whether the verdict `now`, checked at `time` after the
// checks `earlier` (oldest first), may end the run. It must be settled (verdict.hpp), and it must have held over
// the last half of the time run so far:
//  - perforated: the mass behind the wall, the residual velocity and every layer's hole (within half its particle
//    spacing, `layerSpacing` front to rear) are what they were at the latest check at least that long ago, and
//    that check was perforated too, since holes and residual velocity are measured when the run stops;
//  - not perforated: no check in that half was perforated. Near the ballistic limit a rear wall's opening can
//    flicker: T4 of seed 003 at 161.875 m/s opened at 305 us, closed at 355 us, was then taken as settled and
//    stopped, while the same shot at 161.88 m/s stayed open (a hole, the projectile thrown back).
// `now.holes` is needed only when perforated.
bool verdictHeld(const std::vector<VerdictCheck>& earlier, const PerforationVerdict& now, double time,
                 const std::vector<double>& layerSpacing);

// Whether any of the checks `earlier` over the last half of the time run to `time` was perforated. A run that
// stops when settled and reaches run.max_time with its rear wall closed is still perforated when this holds: the
// same window as for a stop. Seed 003's T2T2 at 164.69 m/s had its wall open at 126 of about 200 checks, from
// 275 us to the check before the last, and was taken as not perforated because the last one found it closed.
bool perforatedLately(const std::vector<VerdictCheck>& earlier, double time);

// Builds the model for the scenario's mode, runs it to run.max_time or until the verdict is settled, and
// measures. Throws InputError for a scenario that cannot be modelled.
ImpactResult runImpact(const ImpactScenario& scenario, const ImpactRunOptions& options = {});

enum class BisectVariable { diameter, velocity };
const char* toString(BisectVariable v);

struct BisectionOptions {
  BisectVariable variable = BisectVariable::diameter;
  double lower = 0, upper = 0;  // SI; perforation is expected at `upper` and not at `lower`
  double tolerance = 0;         // SI; stop when the bracket's half-width is at most this
  bool checkBracket = true;     // run both ends first (false: trust them, two runs fewer)
  int maxRuns = 40;
};

struct BisectionRun {
  double value = 0;  // SI
  bool perforated = false;
  bool settled = false;
  RunStatus status = RunStatus::completed;
  double residualVelocity = 0;  // m/s
  double wallSeconds = 0;
  nlohmann::json summary;
};

struct BisectionResult {
  bool resolved = false;  // a bracket narrowed to the tolerance
  std::string message;    // why it is not resolved (bracket does not hold, unstable run, run limit)
  // The largest value that did not perforate and the smallest that did; NaN where no run showed it.
  double largestSafe = std::numeric_limits<double>::quiet_NaN();
  double smallestPerforating = std::numeric_limits<double>::quiet_NaN();
  double estimate() const { return 0.5 * (largestSafe + smallestPerforating); }
  std::vector<BisectionRun> runs;  // in the order made
  // The run that set largestSafe; nullptr where no run did (a trusted bracket's lower end). A run that ended
  // unsettled at run.max_time took the verdict of its last state, and a longer run may still perforate (spall
  // shed late from a bulging rear wall): then the limit lies lower than the bracket says.
  const BisectionRun* largestSafeRun() const;
};

// Bisection on a monotone outcome (larger values perforate). `evaluate` runs one value. `onRun` is told each
// run as it finishes, so that nothing computed is lost if a later run fails.
BisectionResult bisect(const BisectionOptions& options, const std::function<BisectionRun(double)>& evaluate,
                       const std::function<void(const BisectionRun&)>& onRun = {});

// The same with every run an impact of `scenario` with the projectile's diameter or velocity set to the value;
// run k writes into OUTDIR/run_KK when an output directory is given.
BisectionResult bisectScenario(const ImpactScenario& scenario, const BisectionOptions& options,
                               const ImpactRunOptions& runOptions,
                               const std::function<void(const BisectionRun&)>& onRun = {});

}  // namespace blt::sim
