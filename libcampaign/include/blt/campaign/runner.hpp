#pragma once
// Running a campaign: its points concurrently (a pool of threads, each simulation on one thread), every run
// recorded in the run database as it finishes.
//
// Resuming: the bisection of a point is deterministic given the outcomes of its runs, and a run is identified
// by the hash of its inputs (scenario text and settings). So every run is first looked up in the database and
// its recorded outcome replayed; only a run that is not there is simulated. A campaign stopped anywhere (kill,
// power loss) and started again walks the same bisections, replays what was done, and simulates only the rest.
//
// A run that fails (the solver goes unstable, or the run throws) is recorded as failed with its reason and made
// again once at half the particle spacing and half the cell size; if that fails too, its point is unresolved,
// with the reasons, and the campaign goes on with the other points.

#include <atomic>
#include <functional>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "blt/campaign/campaign.hpp"
#include "blt/campaign/database.hpp"
#include "blt/sim/scenario.hpp"

namespace blt::campaign {

// What one simulation gives.
struct SimulationOutcome {
  bool failed = false;
  std::string reason;  // why it failed
  bool perforated = false, settled = false;
  double residualVelocity = 0;  // m/s
  double wallSeconds = 0;
  nlohmann::json measurements;  // the run's summary
};

// Runs one scenario. The seam through which tests put a fast stand-in in place of the MPM solver.
using Simulator = std::function<SimulationOutcome(const sim::ImpactScenario&)>;
// The MPM impact run (sim::runImpact) on one thread; an unstable run is a failed one, with the solver's message.
SimulationOutcome simulateImpact(const sim::ImpactScenario& scenario);
// The same with `threads` OpenMP threads per run (0: all cores), for runs that are not side by side.
Simulator impactSimulator(int threads);

struct CampaignProgress {
  int pointsDone = 0, pointsTotal = 0;  // of this task
  int simulated = 0, replayed = 0, failed = 0;  // runs this session (failed: of the simulated)
  int replayedFromOtherBuild = 0;  // of the replayed: recorded by a build with another tool_version (model fingerprint)
  double elapsedSeconds = 0;
  double etaSeconds = std::numeric_limits<double>::quiet_NaN();  // NaN until a run has been timed
  std::string event;  // what just happened, one line
};

struct CampaignRunOptions {
  int jobs = 1;                       // points at once
  int taskIndex = 1, taskCount = 1;   // run only the points of task I of N (ownsPoint)
  Simulator simulator;                // empty: simulateImpact
  // Called after every run and every finished point, from worker threads, one call at a time.
  std::function<void(const CampaignProgress&)> progress;
  // When it becomes true no further simulation starts; runs in flight finish and are recorded.
  const std::atomic<bool>* stop = nullptr;
};

struct CampaignRunResult {
  std::vector<PointRecord> points;  // this task's, in campaign order, as recorded
  int simulated = 0, replayed = 0, failed = 0;
  // Of the replayed runs, those recorded by a build with another tool_version: its model fingerprint differs, so
  // this build might give another verdict. They are reused, as a resumed campaign must; the caller says so.
  int replayedFromOtherBuild = 0;
  double simulatedSeconds = 0;  // wall time of the simulated runs, summed
  double wallSeconds = 0;       // of the session
  bool interrupted = false;     // stopped before every point was finished
};

// Task I of N owns the points whose 0-based index k has k mod N == I - 1, so that every task gets velocities
// from the whole range.
bool ownsPoint(int index, int taskIndex, int taskCount);
// "I/N" with 1 <= I <= N; throws InputError naming `where`.
std::pair<int, int> parseTask(const std::string& text, const InputLocation& where);

// Runs (or resumes) the campaign's points of the task. Throws InputError for a database that holds another
// definition of the campaign, or a BLE fit that cannot be read when a point needs it.
CampaignRunResult runCampaign(const Campaign& campaign, RunDatabase& db, const CampaignRunOptions& options);

}  // namespace blt::campaign
