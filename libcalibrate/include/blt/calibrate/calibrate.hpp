#pragma once
// The closed loop (issue 7): residuals of the base model at every measured case, each candidate effect fitted
// (one parameter, bounded 1-D search), checked on held-out cases, ranked, and the winner named, or "no effect
// found".
//
// Error measure. Each observation has a residual r (predicted - measured): for residual velocities and hole
// sizes the signed error; for outcomes, when the model gives a margin m = ln(V/V_bl) (or ln(d/d_c)), the
// distance to the right side, min(0, m) for a perforation and max(0, m) for a stop (0 when right); without a
// margin, predicted minus measured outcome (-1, 0, 1; with a perforated share from several runs, that share
// minus the measured outcome). Residuals are grouped (outcomes, residual velocities,
// hole sizes) and divided by the group's scale (outcomes 1, residual velocities and holes the RMS of their
// measured values), and the error is E = sqrt(mean over the groups present of the mean squared scaled
// residual): each kind of measurement weighs the same whatever its count or unit. E is dimensionless; the
// report gives each group's RMS in its unit as well.
//
// Held-out check. Cases (not rows: the holes and outcome of one shot go together) are split into K folds,
// case i in fold i mod K; K is the number of cases (leave-one-out) up to 20 cases, else 10. For each fold
// the effect's parameter is fitted on the other folds and the fold's cases predicted with it; the held-out
// error pools those predictions. The base model has no fitted parameter, so its held-out error is its error.
//
// Decision rule (documented in the report): an effect is accepted when its held-out error is at least
// `minRelativeImprovement` (10 %) below the base's AND the improvement is significant: the paired differences
// d_i = e_i(base) - e_i(effect, held out) of each observation's share of E^2 (each outcome, residual velocity,
// hole extent) have mean / (sd / sqrt(n)) >= `minTStatistic` (2, about 97.5 % one-sided for n >= 10). Of the
// accepted effects the one with the lowest held-out error wins; when none is accepted the answer is "no
// effect found". Each other accepted effect is compared with the winner by the same paired t (its held-out
// shares minus the winner's): below `minTStatistic` the data do not tell the two apart, and the result says so.
//
// Why observations and not cases: hole sizes are often measured on a few shots only (seed 000 Table 5: 2 of
// the 13 Table 1 shots). Over cases, an effect whose evidence is in those shots alone has d_c = 0 on the
// others, and t cannot exceed about 1.48 for 2 equal gains among 13 cases however large the gains are. The
// price: the extents of one shot come from one run and are not independent, so t over observations overstates
// the evidence when one shot carries it. `PairedUnit::cases` keeps the stricter per-case test.

#include <limits>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "blt/calibrate/measured.hpp"
#include "blt/calibrate/model.hpp"

namespace blt::calibrate {

// The units of the paired significance test (see the decision rule above).
enum class PairedUnit { observations, cases };
const char* toString(PairedUnit u);  // "observations", "cases"
std::optional<PairedUnit> parsePairedUnit(const std::string& name);

struct CalibrationOptions {
  std::vector<std::string> effects;  // names; empty: every effect of the model
  int gridPoints = 0;                // 0: the model's suggestion
  int refineSteps = -1;              // golden-section steps after the grid; -1: the model's suggestion
  int folds = 0;                     // 0: leave-one-out up to 20 cases, else 10
  double minRelativeImprovement = 0.10;
  double minTStatistic = 2.0;
  PairedUnit pairedOver = PairedUnit::observations;
};

// Residual groups: outcomes, residual velocities, hole sizes (D_h and D_v together).
enum class ErrorGroup { outcome, residualVelocity, hole };
const char* toString(ErrorGroup g);  // "outcome", "residual_velocity", "hole_size"
ErrorGroup groupOf(ObservationKind kind);

struct GroupError {
  int count = 0;
  double rms = 0;        // RMS residual in SI (outcomes: in margin units, or -1/0/1)
  double scale = 1;      // SI
  int misclassified = 0; // outcomes only: predicted the other way
};

struct ErrorSummary {
  double combined = 0;  // E, dimensionless
  std::map<ErrorGroup, GroupError> groups;
};

struct EffectFit {
  Effect effect;  // a copy: the result outlives the model
  double parameter = 0;                // SI, fitted on all cases
  std::vector<double> foldParameters;  // SI, fitted without each fold
  double sensitivity = 0;              // RMS scaled prediction change per unit of the parameter (as printed)
  ErrorSummary fitted;                 // all cases, at `parameter`
  double heldoutError = 0;             // E of the pooled held-out predictions
  double explainedShare = 0;           // 1 - E_fitted^2 / E_base^2
  double relativeImprovement = 0;      // 1 - heldout / heldout_base
  double tStatistic = 0;               // of the paired differences (inf when all equal and positive)
  bool accepted = false;
  std::string verdict;                 // why accepted or rejected
  // Held-out share of E^2 of each paired unit (observation or case, as the rule pairs them).
  std::vector<double> heldoutShares;
  // For an accepted effect that did not win: the paired t of its held-out shares minus the winner's (> 0 when the
  // winner is better); NaN otherwise.
  double tAgainstWinner = std::numeric_limits<double>::quiet_NaN();
  std::vector<Prediction> predictions;         // every case at `parameter`
  std::vector<Prediction> heldoutPredictions;  // every case predicted by the fit without its fold
  int evaluations = 0;                          // parameter values at which the model was run
  // E on all cases at each grid value (SI parameter, error): how the fit sees the parameter.
  std::vector<std::pair<double, double>> profile;
};

struct FeatureCorrelation {
  std::string feature;  // "diameter", "velocity", "angle"
  double correlation = 0;
  int count = 0;
};

struct CalibrationResult {
  std::string model, source;
  CalibrationOptions options;
  int folds = 0;
  ErrorSummary before;
  std::vector<Prediction> basePredictions;  // every case
  std::vector<FeatureCorrelation> features; // of the base residuals
  std::vector<EffectFit> ranking;           // lowest held-out error first
  std::optional<std::size_t> winner;        // index into ranking
  // The other accepted effects (indices into ranking): when there are any, the data do not single out one effect,
  // and the report says so instead of presenting the winner as the only explanation.
  std::vector<std::size_t> alsoAccepted;

  const EffectFit* winningFit() const { return winner ? &ranking[*winner] : nullptr; }
  // The also-accepted effects whose held-out error is not significantly above the winner's (tAgainstWinner below
  // the rule's minTStatistic): rival explanations the data cannot tell from the winner.
  std::vector<std::size_t> indistinguishable() const;
};

CalibrationResult calibrate(Model& model, const MeasuredData& data, const CalibrationOptions& options = {});

// Splitting one calibration over machines. Every prediction calibrate() asks of the model, in the order it asks:
// the base at each case, then each effect at each grid value but its neutral one (there the effect is off and
// the base serves). The list is fixed by the data and the options, not by what the model predicts, only when
// the fit has no golden-section steps (the solver model's default): otherwise an InputError naming --refine.
struct PlannedPrediction {
  EffectSetting setting;  // effect nullptr: the base model
  std::size_t caseIndex = 0;
};
std::vector<PlannedPrediction> plannedPredictions(const Model& model, const MeasuredData& data,
                                                  const CalibrationOptions& options = {});

// Makes task `taskIndex`'s share of `plan` (1-based, of `taskCount`): prediction k belongs to task k mod N + 1, as
// a campaign's points do. Worth it for a model that records what it computes (the solver model's run database):
// each task records its runs in a database of its own, the parts merged (blt campaign merge) let calibrate() on
// the merged file run nothing. Returns the number of predictions made.
std::size_t predictShare(Model& model, const MeasuredData& data, const std::vector<PlannedPrediction>& plan,
                         int taskIndex, int taskCount);

// The residual of one observation (SI, see above) and its prediction as a number (outcome 1/0, v_r, hole size).
double residualOf(const Observation& o, const Prediction& p);
double predictedValue(const Observation& o, const Prediction& p);

// effect, parameters, error_before, error_after, heldout_error_before, heldout_error_after, the ranking, the
// errors per group, the rule and the thresholds.
nlohmann::json toJson(const CalibrationResult& result, const MeasuredData& data);

}  // namespace blt::calibrate
