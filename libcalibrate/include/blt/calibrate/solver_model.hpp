#pragma once
// The MPM solver as the base model: an impact scenario (data/scenarios) run at every measured case
// (projectile.diameter, .velocity, .angle set from the case), its verdict, residual velocity and hole sizes
// per layer the predictions. Effects are extra scenario settings:
//   interlayer_gaps   g in [0, 3 mm] added to gap_before of every layer between the first and the rear wall
//                     (the coating's layers apart: seed 000's correction)
//   gap:NAME          g in [0, 3 mm] added to gap_before of layer NAME (not the first)
//   thickness:NAME    factor f in [0.5, 1.5] on layer NAME's thickness (a thickness or areal-density error)
//   strength:NAME     factor s in [0.5, 2] on the flow stress of layer NAME's material (Johnson-Cook A and B, or
//                     the bilinear yield stress and tangent modulus): a derived card written to the card
//                     directory and set as the layer's material, so libsim needs no key of its own
//   rate_hardening    Johnson-Cook's rate term 1 + C ln max(rate / 1 1/s, 1), C in [0, 0.15], on every layer whose
//                     flow curve is bilinear (the fabric and laminate cards, whose constants come from
//                     quasi-static tensile tests: seed 000 Table 4); only offered when the target has such a layer
//   fragmentation     factor f in [0.25, 2] on the projectile's failure thresholds (maximum principal stress or
//                     strain, Johnson-Cook D1 and D2): f < 1 breaks it up more easily; only offered when its card
//                     has one of them
//   obliquity         an angle error in [0, 15 deg] added to every case's angle; not in the default list, since
//                     a non-normal impact is a 3D half model (minutes a run): name it in --effects
//   yaw               a yaw psi in [0, 10 deg] added to every shot: the axis of a cylindrical projectile turned off
//                     its flight path in the plane of incidence; offered for cylinders only, and like obliquity a
//                     3D run, so only when named
//   material_strength:MAT  factor s in [0.5, 2] on the flow stress of material MAT in every layer made of it, in
//                     every scenario (one card for all: seed 003's Q235 plates); offered when MAT is used by more
//                     than one layer, or when the data span several scenarios
// Several targets: measured data with a scenario column (measured.hpp) run each shot on its own scenario; the
// layer-named effects (interlayer_gaps, gap:, thickness:, strength:) are then offered only when every scenario
// has the same layers, yaw only when every projectile is a cylinder.
// With `alignments` N > 1 every prediction is the mean of N runs on grids shifted by k/N of a cell.
// Outcomes: by default right or wrong. With `outcomeMargin`, a case the model gets wrong is bisected on the
// diameter (other inputs as measured) for the model's d_c, and its margin ln(d/d_c) says how far wrong it is
// (about 4 to 6 runs a wrong case; a right case needs none, since the calibrator's outcome residual is then 0).
//
// Runs go through the campaign machinery (blt/campaign): each is made by a campaign Simulator (by default in this
// process; the CLI runs each in a process of its own, as campaigns do, so a crash is a failed run with its signal)
// and recorded as it ends in a run database of the campaigns' kind, keyed by the scenario file's name, the hash of
// its text, the model fingerprint and the settings, derived cards by file name (sim::RunCache::key; no path of
// the machine, so runs made in another folder or on another machine are found). A second calibration (or a
// resumed one) with the same build reruns nothing; several calibrations, or machines, may share one file, and
// `blt campaign merge` joins files. The completed runs of the campaigns in that file (and in reuseDatabase) serve
// as well.

#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "blt/calibrate/model.hpp"
#include "blt/campaign/database.hpp"
#include "blt/campaign/runner.hpp"
#include "blt/sim/run_cache.hpp"
#include "blt/sim/scenario.hpp"

namespace blt::calibrate {

struct SolverModelOptions {
  std::vector<std::string> settings;  // key=value applied to the scenario before any case or effect
  // The run database (blt/campaign/database.hpp) the runs are recorded in and recalled from; created if missing.
  // Empty: one in memory, kept for the model's life only.
  std::string database;
  // A run cache of JSON lines (sim::RunCache) that an earlier blt kept the calibration's runs in: its runs are
  // copied into the database when they are not there yet, so nothing computed is lost. Empty or missing: none.
  std::string importCache;
  std::string cardDirectory;          // derived material cards (strength:NAME); empty: beside the database, or a temp dir
  int jobs = 1;                       // runs at once
  int threads = 1;                    // solver threads per run (in process)
  // Makes one run; empty: in this process with `threads` threads (campaign::impactSimulator). A failed run with a
  // summary (gone unstable) is recorded and its summary used, as a campaign records it; one without (a crash) is
  // recorded, stops the calibration, and is made again by the next calibration.
  campaign::Simulator simulator;
  bool outcomeMargin = false;         // bisect the wrongly predicted outcomes for ln(d/d_c)
  // Each prediction averaged over this many alignments of grid and particles (resolution.grid_offset k/N):
  // the outcome becomes the share that perforates, residual velocity and holes the means. Near the limit a
  // single run's verdict turns with the alignment (issue 5); N runs a case smooth that. Not with outcomeMargin.
  int alignments = 1;
  // Another run database to take campaign runs from before simulating (read only; empty: none). A completed run
  // of a campaign's own resolution is reused when its campaign ran the same scenario text with the same --set
  // settings (as strings) and the same model fingerprint, at the same diameter, velocity and angle. The campaigns
  // of `database` itself are searched the same way.
  std::string reuseDatabase;
  double marginTolerance = 0.03;      // the bisection stops when d_hi / d_lo <= 1 + this
  int marginSteps = 6;                // at most this many factors of 1.25 searched for the other side
  std::function<void(const std::string&)> log;  // told each run as it ends
};

// Whether an effect makes every run a 3D half model (obliquity, yaw): such effects are run only when named.
bool turnsRunsThreeD(const std::string& effect);

// The distinct scenarios the data's cases name, in order of first appearance.
std::vector<std::string> scenariosNamedBy(const MeasuredData& data);

class SolverModel : public Model {
 public:
  // scenarioPath: the target of the cases whose data name no scenario ("" when every case names one);
  // otherScenarios: the further targets the data name (scenariosNamedBy).
  SolverModel(const std::string& scenarioPath, SolverModelOptions options,
              const std::vector<std::string>& otherScenarios = {});

  std::string describe() const override;
  const std::vector<Effect>& effects() const override { return effects_; }
  void check(const MeasuredData& data) const override;
  std::vector<Prediction> predict(const MeasuredData& data, const std::vector<std::size_t>& cases,
                                  const EffectSetting& setting) override;
  int suggestedGridPoints() const override { return 7; }
  int suggestedRefineSteps() const override { return 0; }

  // The settings of one run: the base settings, the case's shot, the effect's.
  std::vector<std::string> settingsFor(const MeasuredCase& c, const EffectSetting& setting) const;
  // Runs made (not found in the database) since construction.
  int runsMade() const { return runsMade_; }
  // Campaign runs taken (from the database's campaigns or reuseDatabase) since construction, then recorded as the
  // calibration's.
  int runsReused() const { return runsReused_; }
  // Runs copied from importCache at construction.
  int runsImported() const { return runsImported_; }

 private:
  // One scenario the shots are run on, with what the run cache and the effects need of it.
  struct Target {
    std::string path;
    std::string label, text;  // the scenario's absolute path (case lookup, earlier builds' keys) and its text
    sim::ImpactScenario base;
    std::vector<std::size_t> rateHardened;  // the layers rate_hardening acts on (bilinear flow curves)
  };
  Target loadTarget(const std::string& path) const;
  const Target* findTarget(const std::string& scenario) const;  // nullptr when not one of targets_
  const Target& targetOf(const MeasuredCase& c) const;
  MeasuredCase withDiameter(const MeasuredCase& c) const;  // a case without a diameter gets its scenario's
  static std::size_t layerIndex(const Target& t, const std::string& label);  // npos when not a layer
  // Derived material cards, written to the card directory; each returns the card's path.
  std::string strengthCard(const Target& t, const std::string& material, const std::string& where, double factor) const;
  std::string rateHardenedCard(const Target& t, std::size_t layer, double coefficient) const;
  std::string fragmentationCard(const Target& t, double factor) const;
  std::string writeDerivedCard(Material m, const std::string& material, const std::string& change,
                               double amount) const;
  Material projectileMaterial(const Target& t) const;
  Material layerMaterial(const Target& t, std::size_t layer) const;
  std::string strengthModelOf(const Target& t, std::size_t layer) const;  // "" when the card has no [strength]
  // The failure thresholds of a card that `fragmentation` scales.
  static std::vector<std::string> failureKeys(const Material& m);

  // The reference rate of rate_hardening, 1/s: the cards do not say at which rate their tensile tests were made,
  // so Johnson-Cook's usual 1 1/s.
  static constexpr double kFabricReferenceRate = 1.0;
  nlohmann::json runOrRecall(const Target& t, const std::vector<std::string>& settings);
  // A run's key that holds no path of this machine: the scenario by its file name (its text by hash), a derived
  // card by its file name in the card directory, so that runs made elsewhere (another folder, another machine)
  // are found. Keys made before it held the absolute paths (legacyKey); those runs are still found.
  std::string portableKey(const Target& t, const std::vector<std::string>& settings) const;
  std::string legacyKey(const Target& t, const std::vector<std::string>& settings) const;
  // A campaign run of reuseDatabase, as its shot and its other settings.
  struct ReusableRun {
    const Target* target;
    std::vector<std::string> settings;  // the campaign's --set settings, sorted
    double diameter, velocity, angle;   // SI
    nlohmann::json summary;             // the fields the cache keeps
  };
  void loadReusableRuns(const campaign::RunDatabase& db);
  void importRunCache(const std::string& path);
  std::optional<nlohmann::json> reusedRun(const Target& t, const std::vector<std::string>& settings) const;
  std::vector<ReusableRun> reusable_;
  // ln(d/d_c) of the model for case c under `setting`, from the run at the measured diameter (`atMeasured`).
  double margin(const MeasuredCase& c, const EffectSetting& setting, bool perforatedAtMeasured);

  SolverModelOptions options_;
  std::vector<Target> targets_;  // the first is the default target when hasDefault_
  bool hasDefault_ = false;
  std::vector<Effect> effects_;
  std::unique_ptr<campaign::RunDatabase> runs_;
  std::mutex mutex_;
  int runsMade_ = 0;
  int runsReused_ = 0;
  int runsImported_ = 0;
};

}  // namespace blt::calibrate
