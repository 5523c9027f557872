// The MPI mode: rank 0 coordinates through the Simulator seam of runCampaign, the other ranks simulate.
#include <mpi.h>

#include <chrono>
#include <condition_variable>
#include <mutex>
#include <thread>
#include <vector>

#include "blt/campaign/mpi.hpp"

namespace blt::campaign {

namespace {

enum Tag : int { kRun = 1, kOutcome = 2, kStop = 3 };

// Calls into MPI come from several coordinator threads; MPI_THREAD_SERIALIZED asks only that they do not overlap.
std::mutex mpiMutex;

void sendText(const std::string& text, int to, int tag) {
  std::lock_guard lock(mpiMutex);
  MPI_Send(text.data(), static_cast<int>(text.size()), MPI_CHAR, to, tag, MPI_COMM_WORLD);
}

// A blocking receive would hold the lock while other threads need MPI, so: probe, and sleep between probes.
std::string receiveText(int from, int tag, int* sourceOut = nullptr, int* tagOut = nullptr) {
  MPI_Status status;
  while (true) {
    {
      std::lock_guard lock(mpiMutex);
      int ready = 0;
      MPI_Iprobe(from, tag, MPI_COMM_WORLD, &ready, &status);
      if (ready) {
        int count = 0;
        MPI_Get_count(&status, MPI_CHAR, &count);
        std::string text(static_cast<std::size_t>(count), '\0');
        MPI_Recv(text.data(), count, MPI_CHAR, status.MPI_SOURCE, status.MPI_TAG, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
        if (sourceOut) *sourceOut = status.MPI_SOURCE;
        if (tagOut) *tagOut = status.MPI_TAG;
        return text;
      }
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
}

nlohmann::json outcomeJson(const SimulationOutcome& o) {
  return {{"failed", o.failed},       {"reason", o.reason},
          {"perforated", o.perforated}, {"settled", o.settled},
          {"residual_velocity_m_s", o.residualVelocity}, {"wall_time_s", o.wallSeconds},
          {"measurements", o.measurements}};
}

SimulationOutcome outcomeFrom(const nlohmann::json& j) {
  SimulationOutcome o;
  o.failed = j.at("failed").get<bool>();
  o.reason = j.at("reason").get<std::string>();
  o.perforated = j.at("perforated").get<bool>();
  o.settled = j.at("settled").get<bool>();
  o.residualVelocity = j.at("residual_velocity_m_s").get<double>();
  o.wallSeconds = j.at("wall_time_s").get<double>();
  o.measurements = j.at("measurements");
  return o;
}

void workerLoop(const Campaign& campaign) {
  while (true) {
    int tag = 0;
    const std::string message = receiveText(0, MPI_ANY_TAG, nullptr, &tag);
    if (tag == kStop) return;
    SimulationOutcome out;
    try {
      const auto settings = nlohmann::json::parse(message).get<std::vector<std::string>>();
      out = simulateImpact(runScenario(campaign, settings));
    } catch (const std::exception& e) {
      out = SimulationOutcome{};
      out.failed = true;
      out.reason = std::string("the run failed: ") + e.what();
    }
    sendText(outcomeJson(out).dump(-1, ' ', false, nlohmann::json::error_handler_t::replace), 0, kOutcome);
  }
}

// The worker ranks not busy with a run.
class FreeRanks {
 public:
  explicit FreeRanks(int ranks) {
    for (int r = 1; r < ranks; ++r) free_.push_back(r);
  }
  int take() {
    std::unique_lock lock(mutex_);
    ready_.wait(lock, [&] { return !free_.empty(); });
    const int r = free_.back();
    free_.pop_back();
    return r;
  }
  void give(int r) {
    {
      std::lock_guard lock(mutex_);
      free_.push_back(r);
    }
    ready_.notify_one();
  }

 private:
  std::mutex mutex_;
  std::condition_variable ready_;
  std::vector<int> free_;
};

}  // namespace

bool mpiAvailable() { return true; }

MpiRunResult runCampaignMpi(const Campaign& campaign, const std::string& dbPath, CampaignRunOptions options) {
  int provided = 0;
  MPI_Init_thread(nullptr, nullptr, MPI_THREAD_SERIALIZED, &provided);
  MpiRunResult r;
  int rank = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &r.ranks);
  r.coordinator = rank == 0;
  // Every rank gets here with the same campaign, so every rank can refuse alone, without talking.
  if (r.ranks < 2 || provided < MPI_THREAD_SERIALIZED) {
    MPI_Finalize();
    throw InputError(InputLocation::flag("--mpi"),
                     r.ranks < 2 ? "needs at least 2 MPI ranks (one coordinates, the others simulate)"
                                 : "the MPI library does not allow calls from several threads (MPI_THREAD_SERIALIZED)",
                     "mpirun -n K blt campaign run ... --mpi with K >= 2");
  }
  if (!r.coordinator) {
    workerLoop(campaign);
    MPI_Finalize();
    return r;
  }
  FreeRanks ranks(r.ranks);
  options.jobs = r.ranks - 1;
  options.simulator = [&ranks](const sim::ImpactScenario& sc) {
    const int worker = ranks.take();
    sendText(nlohmann::json(sc.settings).dump(), worker, kRun);
    const std::string reply = receiveText(worker, kOutcome);
    ranks.give(worker);
    return outcomeFrom(nlohmann::json::parse(reply));
  };
  std::exception_ptr error;
  try {
    RunDatabase db(dbPath);
    r.result = runCampaign(campaign, db, options);
  } catch (...) {
    error = std::current_exception();
  }
  for (int w = 1; w < r.ranks; ++w) sendText("", w, kStop);
  MPI_Finalize();
  if (error) std::rethrow_exception(error);
  return r;
}

}  // namespace blt::campaign
