#pragma once
// MPI mode of a campaign (OpenMPI): `mpirun -n K blt campaign run CAMPAIGN --db FILE --mpi`. Rank 0 walks the
// points' bisections (as runCampaign, K - 1 points at once) and is the only one to touch the database; every
// simulation it needs goes to a free rank among 1..K-1, which builds the scenario from the same campaign file
// and settings and sends the outcome back. Built only where CMake finds MPI (BLT_HAVE_MPI).

#include <string>

#include "blt/campaign/campaign.hpp"
#include "blt/campaign/runner.hpp"

namespace blt::campaign {

// True when this blt was built with MPI.
bool mpiAvailable();

struct MpiRunResult {
  bool coordinator = false;   // rank 0: `result` holds the campaign's result
  int ranks = 0;
  CampaignRunResult result;
};

// Initialises MPI, runs the campaign over MPI_COMM_WORLD and finalises MPI; every rank returns. options.jobs and
// options.simulator are set here (one point per worker rank; simulateImpact on the workers). Throws InputError
// with fewer than 2 ranks, or when blt was built without MPI.
MpiRunResult runCampaignMpi(const Campaign& campaign, const std::string& dbPath, CampaignRunOptions options);

}  // namespace blt::campaign
