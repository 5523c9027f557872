// This blt was built without MPI: --mpi says so and how to get it.
#include "blt/campaign/mpi.hpp"

namespace blt::campaign {

bool mpiAvailable() { return false; }

MpiRunResult runCampaignMpi(const Campaign&, const std::string&, CampaignRunOptions) {
  throw InputError(InputLocation::flag("--mpi"), "this blt was built without MPI",
                   "install openmpi-bin and libopenmpi-dev (scripts/setup does) and build again, or use --jobs / --task");
}

}  // namespace blt::campaign
