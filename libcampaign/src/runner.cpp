#include "blt/campaign/runner.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <exception>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>

#include "blt/ble/christiansen.hpp"
#include "blt/ble/store.hpp"
#include "blt/core/units.hpp"
#include "blt/sim/impact.hpp"

namespace blt::campaign {

namespace {
SimulationOutcome simulateOn(const sim::ImpactScenario& scenario, int threads) {
  sim::ImpactRunOptions ro;
  ro.threads = threads;
  const sim::ImpactResult r = sim::runImpact(scenario, ro);
  SimulationOutcome o;
  o.failed = r.status == sim::RunStatus::unstable;
  if (o.failed) o.reason = "the run went unstable: " + r.message;
  o.perforated = r.verdict.perforated;
  o.settled = r.verdict.settled;
  o.residualVelocity = r.verdict.residualVelocity;
  o.wallSeconds = r.wallSeconds;
  o.measurements = r.summary;
  return o;
}
}  // namespace

// One thread: the campaign runs points side by side instead.
SimulationOutcome simulateImpact(const sim::ImpactScenario& scenario) { return simulateOn(scenario, 1); }

Simulator impactSimulator(int threads) {
  if (threads == 1) return simulateImpact;
  return [threads](const sim::ImpactScenario& scenario) { return simulateOn(scenario, threads); };
}

bool ownsPoint(int index, int taskIndex, int taskCount) { return index % taskCount == taskIndex - 1; }

std::pair<int, int> parseTask(const std::string& text, const InputLocation& where) {
  const auto slash = text.find('/');
  int i = 0, n = 0;
  std::size_t usedI = 0, usedN = 0;
  try {
    if (slash != std::string::npos) {
      i = std::stoi(text.substr(0, slash), &usedI);
      n = std::stoi(text.substr(slash + 1), &usedN);
    }
  } catch (const std::exception&) {
    usedI = 0;
  }
  if (slash == std::string::npos || usedI != slash || usedN != text.size() - slash - 1 || n < 1 || i < 1 || i > n)
    throw InputError(where, "'" + text + "' is not a task of a split", "I/N with 1 <= I <= N, e.g. 3/8");
  return {i, n};
}

namespace {

// Thrown inside a point's bisection when the session is asked to stop before a simulation: the point is left
// as far as it got, and the next session replays it to there.
struct Interrupted {};

using Clock = std::chrono::steady_clock;

class Session {
 public:
  Session(const Campaign& c, RunDatabase& db, const CampaignRunOptions& o) : c_(c), db_(db), o_(o) {
    simulator_ = o.simulator ? o.simulator : Simulator(simulateImpact);
  }

  CampaignRunResult run() {
    const auto start = Clock::now();
    start_ = start;
    // The projectile's density goes with the exported points (the BLE needs it); from the base scenario.
    const sim::ImpactScenario base = runScenario(c_, c_.settings);
    density_ = sim::resolveMaterial(base.projectile.material,
                                    InputLocation::file(c_.scenarioPath, std::nullopt, "projectile.material"))
                   .density;
    campaign_ = db_.ensureCampaign(c_, density_, o_.taskIndex, o_.taskCount);

    for (int k = 0; k < static_cast<int>(c_.points.size()); ++k)
      if (ownsPoint(k, o_.taskIndex, o_.taskCount)) mine_.push_back(k);
    records_.resize(mine_.size());
    // Register every point (and its first bracket) before any run, so that status shows the whole task.
    // A point recorded before keeps its first bracket, so the BLE store is not read for it.
    std::map<int, PointRecord> recorded;
    for (PointRecord& p : db_.points(campaign_)) recorded[p.index] = std::move(p);
    for (std::size_t i = 0; i < mine_.size(); ++i) {
      const auto it = recorded.find(mine_[i]);
      records_[i] = it != recorded.end() ? it->second : db_.ensurePoint(campaign_, firstRecord(mine_[i]));
    }
    runsSoFar_.assign(mine_.size(), 0);
    finished_.assign(mine_.size(), false);
    progress_.pointsTotal = static_cast<int>(mine_.size());

    std::atomic<std::size_t> next{0};
    std::exception_ptr error;
    std::mutex errorMutex;
    const auto worker = [&] {
      for (std::size_t i = next++; i < mine_.size() && !stopRequested(); i = next++) {
        try {
          runPoint(i);
        } catch (const Interrupted&) {
          return;
        } catch (...) {
          std::lock_guard lock(errorMutex);
          if (!error) error = std::current_exception();
          abort_ = true;
          return;
        }
      }
    };
    const int threads = std::max(1, std::min<int>(o_.jobs, static_cast<int>(mine_.size())));
    std::vector<std::thread> pool;
    for (int t = 0; t < threads; ++t) pool.emplace_back(worker);
    for (auto& t : pool) t.join();
    if (error) std::rethrow_exception(error);

    CampaignRunResult result;
    result.points = records_;
    result.simulated = progress_.simulated;
    result.replayed = progress_.replayed;
    result.replayedFromOtherBuild = progress_.replayedFromOtherBuild;
    result.failed = progress_.failed;
    result.simulatedSeconds = simulatedSeconds_;
    result.wallSeconds = std::chrono::duration<double>(Clock::now() - start).count();
    result.interrupted = std::find(finished_.begin(), finished_.end(), false) != finished_.end();
    return result;
  }

 private:
  bool stopRequested() const { return abort_ || (o_.stop && o_.stop->load()); }

  double campaignLower(const CampaignPoint& p) const { return std::isnan(p.lower) ? c_.lower : p.lower; }
  double campaignUpper(const CampaignPoint& p) const { return std::isnan(p.upper) ? c_.upper : p.upper; }
  const char* unit() const { return c_.variable == sim::BisectVariable::diameter ? "mm" : "m/s"; }

  // The point as first recorded: its bracket from the point, the BLE fit or the campaign.
  PointRecord firstRecord(int k) {
    const CampaignPoint& p = c_.points[k];
    PointRecord r;
    r.index = k;
    r.label = describePoint(c_, p);
    r.velocity = p.velocity;
    r.diameter = p.diameter;
    r.angle = p.angle;
    r.bracketLower = campaignLower(p);
    r.bracketUpper = campaignUpper(p);
    r.bracketOrigin = std::isnan(p.lower) ? "campaign" : "point";
    if (c_.ble && std::isnan(p.lower)) {
      const double density = c_.ble->density > 0 ? c_.ble->density : density_;
      const double dc = ble::criticalDiameter(fit().coefficients, p.velocity, p.angle, density);
      const double lo = std::clamp(dc * (1 - c_.ble->halfWidth), r.bracketLower, r.bracketUpper);
      const double hi = std::clamp(dc * (1 + c_.ble->halfWidth), r.bracketLower, r.bracketUpper);
      if (std::isfinite(dc) && lo < hi) {
        r.bracketLower = lo;
        r.bracketUpper = hi;
        r.bracketOrigin = "ble fit " + c_.ble->fit + ": d_c " + units::format(dc, "mm", 4);
      } else {
        r.bracketOrigin = "campaign (ble fit " + c_.ble->fit + " predicts d_c " + units::format(dc, "mm", 4) +
                          ", outside it)";
      }
    }
    return r;
  }

  // Read only when a point is registered for the first time: a resumed campaign needs no BLE store.
  const ble::FitResult& fit() {
    if (!fit_) {
      const InputLocation where = InputLocation::file(c_.path, std::nullopt, "ble.db");
      if (!std::filesystem::exists(c_.ble->db))
        throw InputError(where, "no BLE store '" + c_.ble->db + "'",
                         "a store made by blt ble fit (path relative to the campaign file), or --ble-db FILE");
      const ble::BleStore store(c_.ble->db);
      fit_ = store.loadFit(c_.ble->fit).result;
    }
    return *fit_;
  }

  std::vector<std::string> settingsFor(const CampaignPoint& p, double value, bool finer) const {
    std::vector<std::string> s = c_.settings;
    for (auto& extra : pointSettings(c_, p)) s.push_back(std::move(extra));
    s.push_back(variableSetting(c_, value));
    if (finer) {
      // The resolution does not depend on the bisected value: read it from the point's scenario.
      std::vector<std::string> base = c_.settings;
      for (auto& extra : pointSettings(c_, p)) base.push_back(std::move(extra));
      const sim::ImpactScenario sc = runScenario(c_, base);
      s.push_back("resolution.particle_spacing=" + exactNumber(0.5 * sc.resolution.particleSpacing) + "m");
      s.push_back("resolution.cell_size=" + exactNumber(0.5 * sc.cellSize()) + "m");
    }
    return s;
  }

  void report(std::size_t slot, const std::string& event) {
    // Caller holds progressMutex_.
    progress_.elapsedSeconds = std::chrono::duration<double>(Clock::now() - start_).count();
    progress_.event = event;
    if (progress_.simulated > 0) {
      double remaining = 0;
      int open = 0;
      for (std::size_t i = 0; i < mine_.size(); ++i) {
        if (finished_[i]) continue;
        ++open;
        const PointRecord& r = records_[i];
        const double width = r.bracketUpper - r.bracketLower;
        const double expected = 2 + std::max(0.0, std::ceil(std::log2(width / (2 * c_.tolerance))));
        remaining += std::max(1.0, expected - runsSoFar_[i]);
      }
      const double perRun = simulatedSeconds_ / progress_.simulated;
      progress_.etaSeconds = open == 0 ? 0 : remaining * perRun / std::min(open, std::max(1, o_.jobs));
    }
    (void)slot;
    if (o_.progress) o_.progress(progress_);
  }

  // One run at `value`: replayed from the database when there, else simulated and recorded.
  RunRecord attempt(std::size_t slot, double value, bool finer) {
    const CampaignPoint& p = c_.points[mine_[slot]];
    RunRecord r;
    r.point = mine_[slot];
    r.value = value;
    r.attempt = finer ? 1 : 0;
    r.diameter = c_.variable == sim::BisectVariable::diameter ? value : p.diameter;
    r.velocity = c_.variable == sim::BisectVariable::velocity ? value : p.velocity;
    r.angle = p.angle;
    r.toolVersion = sim::buildVersion();
    const std::string what = records_[slot].label + ", " + sim::toString(c_.variable) + " " +
                             units::format(value, unit(), 5) + (finer ? " (half spacing)" : "");
    r.settings = settingsFor(p, value, finer);
    r.scenarioHash = scenarioHash(c_.scenarioText, r.settings);
    if (auto found = db_.findRun(campaign_, r.scenarioHash)) {
      std::lock_guard lock(progressMutex_);
      ++progress_.replayed;
      ++runsSoFar_[slot];
      const bool otherBuild = found->toolVersion != r.toolVersion;
      progress_.replayedFromOtherBuild += otherBuild;
      report(slot, "replayed " + what + ": " + verdictText(*found) +
                       (otherBuild ? " (recorded by blt " + found->toolVersion + ")" : ""));
      return *found;
    }
    if (stopRequested()) throw Interrupted{};
    {
      SimulationOutcome out;
      try {
        out = simulator_(runScenario(c_, r.settings));
      } catch (const std::exception& e) {
        out = SimulationOutcome{};
        out.failed = true;
        out.reason = std::string("the run failed: ") + e.what();
      }
      r.state = out.failed ? RunState::failed : RunState::completed;
      r.reason = out.reason;
      r.perforated = !out.failed && out.perforated;
      r.settled = !out.failed && out.settled;
      r.residualVelocity = out.residualVelocity;
      r.wallSeconds = out.wallSeconds;
      r.measurements = out.measurements;
    }
    const RunRecord recorded = db_.recordRun(campaign_, r);
    std::lock_guard lock(progressMutex_);
    ++progress_.simulated;
    if (recorded.state == RunState::failed) ++progress_.failed;
    simulatedSeconds_ += r.wallSeconds;
    ++runsSoFar_[slot];
    report(slot, what + ": " + verdictText(recorded) + " (" + units::format(r.wallSeconds, "s", 3) + ")");
    return recorded;
  }

  static std::string verdictText(const RunRecord& r) {
    if (r.state == RunState::failed) return "FAILED (" + r.reason + ")";
    return std::string(r.perforated ? "perforated" : "not perforated") + (r.settled ? "" : ", not settled");
  }

  sim::BisectionRun evaluate(std::size_t slot, double value) {
    RunRecord r = attempt(slot, value, false);
    std::string failures;
    if (r.state == RunState::failed) {
      failures = r.reason;
      r = attempt(slot, value, true);
      if (r.state == RunState::failed) failures += "; again at half the spacing: " + r.reason;
    }
    sim::BisectionRun b;
    b.value = value;
    if (r.state == RunState::failed) {
      b.status = sim::RunStatus::unstable;
      b.summary = {{"message", failures}};
      return b;
    }
    b.perforated = r.perforated;
    b.settled = r.settled;
    b.residualVelocity = r.residualVelocity;
    b.wallSeconds = r.wallSeconds;
    b.summary = r.measurements;
    return b;
  }

  // The bracket runs (widening a seeded bracket that does not hold, by steps doubling from its width, no further
  // than the campaign's bracket), then the bisection inside it.
  void runPoint(std::size_t slot) {
    PointRecord rec = records_[slot];
    const CampaignPoint& p = c_.points[rec.index];
    const double floor = campaignLower(p), ceiling = campaignUpper(p);
    if (rec.state == PointState::pending) {
      rec.state = PointState::started;
      db_.updatePoint(campaign_, rec);
    }
    int runs = 0;
    std::string problem;
    double lo = rec.bracketLower, hi = rec.bracketUpper, step = hi - lo;
    const auto probe = [&](double value) -> std::optional<bool> {
      ++runs;
      const sim::BisectionRun b = evaluate(slot, value);
      if (b.status == sim::RunStatus::unstable) {
        problem = "the run at " + units::format(value, unit(), 5) + " failed: " + b.summary.value("message", "");
        return std::nullopt;
      }
      return b.perforated;
    };
    const auto outOfRuns = [&] {
      if (runs < c_.maxRuns) return false;
      problem = "stopped at the limit of " + std::to_string(c_.maxRuns) + " runs";
      return true;
    };
    bool hiKnown = false;
    std::optional<bool> atLo = probe(lo);
    while (problem.empty() && atLo && *atLo) {
      if (lo <= floor) {
        problem = "the bracket does not hold: perforated already at the lower end " + units::format(lo, unit(), 5);
        break;
      }
      if (outOfRuns()) break;
      hi = lo;
      hiKnown = true;
      lo = std::max(floor, lo - step);
      step *= 2;
      atLo = probe(lo);
    }
    if (problem.empty() && !hiKnown) {
      std::optional<bool> atHi = probe(hi);
      while (problem.empty() && atHi && !*atHi) {
        if (hi >= ceiling) {
          problem = "the bracket does not hold: not perforated at the upper end " + units::format(hi, unit(), 5);
          break;
        }
        if (outOfRuns()) break;
        lo = hi;
        hi = std::min(ceiling, hi + step);
        step *= 2;
        atHi = probe(hi);
      }
    }
    rec.largestSafe.reset();
    rec.smallestPerforating.reset();
    if (problem.empty()) {
      sim::BisectionOptions bo;
      bo.variable = c_.variable;
      bo.lower = lo;
      bo.upper = hi;
      bo.tolerance = c_.tolerance;
      bo.checkBracket = false;
      bo.maxRuns = c_.maxRuns - runs;
      const sim::BisectionResult b = sim::bisect(bo, [&](double v) { return evaluate(slot, v); });
      runs += static_cast<int>(b.runs.size());
      problem = b.resolved ? "" : b.message;
      if (!std::isnan(b.largestSafe)) rec.largestSafe = b.largestSafe;
      if (!std::isnan(b.smallestPerforating)) rec.smallestPerforating = b.smallestPerforating;
    }
    rec.state = problem.empty() ? PointState::resolved : PointState::unresolved;
    rec.message = problem;
    rec.runs = runs;
    db_.updatePoint(campaign_, rec);
    std::lock_guard lock(progressMutex_);
    records_[slot] = rec;
    finished_[slot] = true;
    ++progress_.pointsDone;
    report(slot, "point " + rec.label + ": " +
                     (problem.empty() ? "d = " + units::format(0.5 * (*rec.largestSafe + *rec.smallestPerforating),
                                                               unit(), 5) +
                                            " +- " +
                                            units::format(0.5 * (*rec.smallestPerforating - *rec.largestSafe),
                                                          unit(), 3)
                                      : "UNRESOLVED: " + problem) +
                     " after " + std::to_string(runs) + " runs");
  }

  const Campaign& c_;
  RunDatabase& db_;
  const CampaignRunOptions& o_;
  Simulator simulator_;
  std::int64_t campaign_ = 0;
  double density_ = 0;
  std::optional<ble::FitResult> fit_;
  std::vector<int> mine_;              // campaign indices of this task's points
  std::vector<PointRecord> records_;   // by slot (position in mine_)
  std::vector<int> runsSoFar_;         // runs made or replayed this session, by slot
  std::vector<bool> finished_;
  std::atomic<bool> abort_{false};
  std::mutex progressMutex_;
  CampaignProgress progress_;
  double simulatedSeconds_ = 0;
  Clock::time_point start_;
};

}  // namespace

CampaignRunResult runCampaign(const Campaign& campaign, RunDatabase& db, const CampaignRunOptions& options) {
  if (options.jobs < 1)
    throw InputError(InputLocation::flag("--jobs"), "must be at least 1", "1, 2, ... (points at once)");
  if (options.taskCount < 1 || options.taskIndex < 1 || options.taskIndex > options.taskCount)
    throw InputError(InputLocation::flag("--task"), "task " + std::to_string(options.taskIndex) + "/" +
                                                         std::to_string(options.taskCount) + " is not a task of a split",
                     "I/N with 1 <= I <= N");
  Session s(campaign, db, options);
  return s.run();
}

}  // namespace blt::campaign
