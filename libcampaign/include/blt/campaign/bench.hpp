#pragma once
// Benchmark of a campaign (issue 6, "blt bench campaign"): the campaign run end to end into a new run database,
// so that every run is simulated and none replayed from an earlier session, and the figures of that session:
// wall time, runs, runs per point, points resolved.

#include <string>
#include <vector>

#include "blt/campaign/campaign.hpp"
#include "blt/campaign/database.hpp"
#include "blt/campaign/runner.hpp"

namespace blt::campaign {

struct CampaignBenchmark {
  std::string campaign;
  int points = 0, resolved = 0, unresolved = 0;
  int runs = 0;                     // simulations made (failed ones and their retries included)
  int runsFailed = 0;               // of those, failed (went unstable or threw)
  int runsReplayed = 0;             // 0 unless a bisection came back to a value it had already run
  double runsPerPointMean = 0;      // PointRecord::runs over the points (bracket runs included)
  int runsPerPointMax = 0;
  double wallSeconds = 0;           // of the session
  double simulatedSeconds = 0;      // wall time of the simulations, summed
  bool interrupted = false;
  std::vector<PointRecord> pointRecords;  // in campaign order
};

// Runs every point of `campaign` (options.taskIndex/taskCount are ignored: all of them) into a new run database at
// `dbPath`. Throws InputError when that file exists already: a benchmark must simulate, not replay.
CampaignBenchmark benchmarkCampaign(const Campaign& campaign, const std::string& dbPath, CampaignRunOptions options);

}  // namespace blt::campaign
