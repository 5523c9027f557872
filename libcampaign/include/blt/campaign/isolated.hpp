#pragma once
// Runs each simulation of a campaign in a process of its own (`blt sim run SCENARIO --set ... --json`), so that
// a run that crashes (a segmentation fault, an abort, the kernel's out-of-memory kill) is recorded as a failed run
// with its signal and the end of its error output, and the campaign goes on. In process, the same crash would
// end the campaign (what was recorded stays, and a restart resumes, but every run in flight is lost).
//
// The child reads the scenario file again (ImpactScenario::path) with the run's settings; the campaign has
// checked at its start that the file is the one it was defined with (RunDatabase::ensureCampaign). The child
// is killed when the thread that started it dies, so a killed campaign leaves no runs behind it.

#include <cstddef>
#include <string>

#include "blt/campaign/runner.hpp"

namespace blt::campaign {

struct IsolatedRunOptions {
  std::string executable;                // the blt program (its `sim run` subcommand); required
  int threads = 1;                       // OpenMP threads of each run (0: all cores)
  std::size_t errorTailBytes = 600;      // how much of the child's error output a failed run's reason keeps
  // With a directory and an interval, each run keeps a checkpoint (blt sim run --checkpoint-every, no frames) in
  // a directory of its own under it (checkpointDirectoryFor) and goes on from it when it is there: a run killed
  // with its campaign (a job's time limit) loses at most the interval. The directory goes when the run ends.
  std::string checkpointDirectory;
  double checkpointSeconds = 0;          // s of wall time
};

// Where a run keeps its checkpoint: a directory named by the hash of the scenario file's path, the run's
// settings and the build (buildVersion), so that only the same run of the same build goes on from it.
std::string checkpointDirectoryFor(const IsolatedRunOptions& options, const sim::ImpactScenario& scenario);

// Throws InputError when the executable is not there.
Simulator isolatedSimulator(const IsolatedRunOptions& options);

// What the CLI's campaigns and calibrations run with: each run in a process of this program (isolatedSimulator on
// /proc/self/exe, the image this process runs, so rebuilding blt mid-campaign does not mix two builds' runs),
// so that a crash is a failed run and not the end of the job; with inProcess (or under MPI, whose ranks are
// processes already) on threads of this one (impactSimulator). `threads`: OpenMP threads per run. With a
// checkpoint directory and interval, process runs keep checkpoints there (IsolatedRunOptions); in process they
// cannot, and asking for both is an InputError naming --checkpoint-every.
Simulator campaignSimulator(bool inProcess, int threads, const std::string& checkpointDirectory = {},
                            double checkpointSeconds = 0);

}  // namespace blt::campaign
