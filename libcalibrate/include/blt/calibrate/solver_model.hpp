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
//   obliquity         an angle error in [0, 15 deg] added to every case's angle; not in the default list, since
//                     a non-normal impact is a 3D half model (minutes a run): name it in --effects
// No margin: an outcome is right or wrong (a bisection per case would give ln(d/d_c), at ~6 runs a case).
//
// Runs are kept in a run cache (blt/sim/run_cache.hpp) keyed by the scenario file's path, the hash of its text
// and the settings, so a second calibration (or a resumed one) reruns nothing.

#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "blt/calibrate/model.hpp"
#include "blt/sim/run_cache.hpp"
#include "blt/sim/scenario.hpp"

namespace blt::calibrate {

struct SolverModelOptions {
  std::vector<std::string> settings;  // key=value applied to the scenario before any case or effect
  std::string cacheFile;              // run cache (JSON lines); empty: no cache kept between calls
  std::string cardDirectory;          // derived material cards (strength:NAME); empty: beside the cache, or a temp dir
  int jobs = 1;                       // runs at once
  int threads = 1;                    // solver threads per run
  std::function<void(const std::string&)> log;  // told each run as it ends
};

class SolverModel : public Model {
 public:
  SolverModel(const std::string& scenarioPath, SolverModelOptions options);

  std::string describe() const override;
  const std::vector<Effect>& effects() const override { return effects_; }
  void check(const MeasuredData& data) const override;
  std::vector<Prediction> predict(const MeasuredData& data, const std::vector<std::size_t>& cases,
                                  const EffectSetting& setting) override;
  int suggestedGridPoints() const override { return 7; }
  int suggestedRefineSteps() const override { return 0; }

  // The settings of one run: the base settings, the case's shot, the effect's.
  std::vector<std::string> settingsFor(const MeasuredCase& c, const EffectSetting& setting) const;
  // Runs made (not taken from the cache) since construction.
  int runsMade() const { return runsMade_; }

 private:
  std::size_t layerIndex(const std::string& label) const;  // npos when not a layer
  std::string strengthCard(std::size_t layer, double factor) const;  // path of the derived card
  nlohmann::json runOrRecall(const std::vector<std::string>& settings);

  std::string path_;
  std::string label_, text_;  // the scenario's absolute path and its text, for the run cache's keys
  SolverModelOptions options_;
  sim::ImpactScenario base_;
  std::vector<Effect> effects_;
  std::unique_ptr<sim::RunCache> cache_;
  std::mutex mutex_;
  int runsMade_ = 0;
};

}  // namespace blt::calibrate
