#include "blt/campaign/bench.hpp"

#include <algorithm>
#include <filesystem>

namespace blt::campaign {

CampaignBenchmark benchmarkCampaign(const Campaign& campaign, const std::string& dbPath, CampaignRunOptions options) {
  if (std::filesystem::exists(dbPath))
    throw InputError(InputLocation::file(dbPath),
                     "a benchmark's run database must be new, and this file exists: its runs would be replayed",
                     "a path where no file is");
  options.taskIndex = 1;
  options.taskCount = 1;
  CampaignRunResult r;
  {
    RunDatabase db(dbPath);
    r = runCampaign(campaign, db, options);
  }
  CampaignBenchmark b;
  b.campaign = campaign.name;
  b.points = static_cast<int>(r.points.size());
  b.runs = r.simulated;
  b.runsFailed = r.failed;
  b.runsReplayed = r.replayed;
  b.wallSeconds = r.wallSeconds;
  b.simulatedSeconds = r.simulatedSeconds;
  b.interrupted = r.interrupted;
  int pointRuns = 0;
  for (const PointRecord& p : r.points) {
    b.resolved += p.state == PointState::resolved;
    b.unresolved += p.state == PointState::unresolved;
    pointRuns += p.runs;
    b.runsPerPointMax = std::max(b.runsPerPointMax, p.runs);
  }
  b.runsPerPointMean = b.points > 0 ? static_cast<double>(pointRuns) / b.points : 0.0;
  b.pointRecords = std::move(r.points);
  return b;
}

}  // namespace blt::campaign
