#include "blt/calibrate/calibrate.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include "blt/campaign/runner.hpp"
#include "blt/core/error.hpp"
#include "blt/core/units.hpp"

namespace blt::calibrate {

const char* toString(PairedUnit u) { return u == PairedUnit::cases ? "cases" : "observations"; }

std::optional<PairedUnit> parsePairedUnit(const std::string& name) {
  if (name == "observations") return PairedUnit::observations;
  if (name == "cases") return PairedUnit::cases;
  return std::nullopt;
}

const char* toString(ErrorGroup g) {
  switch (g) {
    case ErrorGroup::outcome: return "outcome";
    case ErrorGroup::residualVelocity: return "residual_velocity";
    case ErrorGroup::hole: return "hole_size";
  }
  return "?";
}

ErrorGroup groupOf(ObservationKind kind) {
  switch (kind) {
    case ObservationKind::outcome: return ErrorGroup::outcome;
    case ObservationKind::residualVelocity: return ErrorGroup::residualVelocity;
    default: return ErrorGroup::hole;
  }
}

namespace {

std::optional<std::pair<double, double>> holeOf(const Observation& o, const Prediction& p) {
  for (const auto& [layer, size] : p.holes)
    if (layer == o.layer) return size;
  return std::nullopt;
}

}  // namespace

double predictedValue(const Observation& o, const Prediction& p) {
  switch (o.kind) {
    case ObservationKind::outcome: return p.perforatedFraction.value_or(p.perforated ? 1.0 : 0.0);
    case ObservationKind::residualVelocity: return p.residualVelocity.value_or(0.0);
    case ObservationKind::holeHorizontal:
    case ObservationKind::holeVertical: {
      const auto hole = holeOf(o, p);
      if (!hole) throw std::logic_error("the model predicted no hole for layer '" + o.layer + "'");
      return o.kind == ObservationKind::holeHorizontal ? hole->first : hole->second;
    }
  }
  return 0;
}

double residualOf(const Observation& o, const Prediction& p) {
  if (o.kind == ObservationKind::outcome && p.margin) return o.value > 0.5 ? std::min(0.0, *p.margin) : std::max(0.0, *p.margin);
  return predictedValue(o, p) - o.value;
}

namespace {

// Fixed for one calibration: the groups' scales from all measured values, so every fold and effect is
// measured with the same yardstick.
struct Yardstick {
  std::map<ErrorGroup, double> scale;
  explicit Yardstick(const MeasuredData& data) {
    std::map<ErrorGroup, std::pair<double, int>> sums;
    for (const Observation& o : data.observations) {
      auto& s = sums[groupOf(o.kind)];
      s.first += o.value * o.value;
      s.second += 1;
    }
    for (const auto& [g, s] : sums) {
      const double rms = std::sqrt(s.first / s.second);
      // Outcomes are residuals of order one already; all-zero measurements fall back to their unit.
      scale[g] = g == ErrorGroup::outcome ? 1.0 : (rms > 0 ? rms : (g == ErrorGroup::hole ? 1e-3 : 1.0));
    }
  }
};

// Observations of each case, so a case set selects its rows.
std::vector<std::vector<std::size_t>> rowsByCase(const MeasuredData& data) {
  std::vector<std::vector<std::size_t>> rows(data.cases.size());
  for (std::size_t i = 0; i < data.observations.size(); ++i) rows[data.observations[i].caseIndex].push_back(i);
  return rows;
}

// Each case's share of E^2 over the case set `cases`, given a prediction per case (indexed by case).
struct CaseErrors {
  std::vector<double> share;             // per case in `cases`, in order; they sum to E^2
  std::vector<double> observationShare;  // per observation of those cases, case by case; they sum to E^2 too
  double combined() const { return std::sqrt(std::accumulate(share.begin(), share.end(), 0.0)); }
};

CaseErrors caseErrors(const MeasuredData& data, const Yardstick& yard, const std::vector<std::vector<std::size_t>>& rows,
                      const std::vector<std::size_t>& cases, const std::vector<const Prediction*>& predictionOfCase) {
  std::map<ErrorGroup, int> count;
  for (std::size_t c : cases)
    for (std::size_t r : rows[c]) ++count[groupOf(data.observations[r].kind)];
  const double groups = static_cast<double>(count.size());
  CaseErrors out;
  for (std::size_t c : cases) {
    double s = 0;
    for (std::size_t r : rows[c]) {
      const Observation& o = data.observations[r];
      const ErrorGroup g = groupOf(o.kind);
      const double z = residualOf(o, *predictionOfCase[c]) / yard.scale.at(g);
      const double part = z * z / (count[g] * groups);
      out.observationShare.push_back(part);
      s += part;
    }
    out.share.push_back(s);
  }
  return out;
}

// t = mean / (sd / sqrt(n)) of the paired differences before - after; inf when they are all equal and positive.
double pairedTStatistic(const std::vector<double>& before, const std::vector<double>& after) {
  const std::size_t n = before.size();
  if (n < 2) return 0.0;
  std::vector<double> d(n);
  for (std::size_t i = 0; i < n; ++i) d[i] = before[i] - after[i];
  const double mean = std::accumulate(d.begin(), d.end(), 0.0) / n;
  double var = 0;
  for (double v : d) var += (v - mean) * (v - mean);
  var /= (n - 1);
  return var > 0 ? mean / std::sqrt(var / n) : (mean > 0 ? std::numeric_limits<double>::infinity() : 0.0);
}

ErrorSummary summarise(const MeasuredData& data, const Yardstick& yard, const std::vector<Prediction>& predictions) {
  ErrorSummary e;
  std::map<ErrorGroup, double> sq;
  for (const Observation& o : data.observations) {
    const ErrorGroup g = groupOf(o.kind);
    const Prediction& p = predictions[o.caseIndex];
    const double r = residualOf(o, p);
    sq[g] += r * r;
    auto& ge = e.groups[g];
    ge.count += 1;
    ge.scale = yard.scale.at(g);
    if (o.kind == ObservationKind::outcome && p.perforated != (o.value > 0.5)) ge.misclassified += 1;
  }
  double total = 0;
  for (auto& [g, ge] : e.groups) {
    ge.rms = std::sqrt(sq[g] / ge.count);
    total += (ge.rms / ge.scale) * (ge.rms / ge.scale);
  }
  e.combined = e.groups.empty() ? 0 : std::sqrt(total / e.groups.size());
  return e;
}

// Predictions of one effect at parameter values, remembered per (value, case): the grid points are shared by
// the full fit and every fold, so a costly model runs each case at each value once.
class Memo {
 public:
  Memo(Model& model, const MeasuredData& data, const Effect* effect) : model_(model), data_(data), effect_(effect) {}

  const Prediction& at(double value, std::size_t c) { return *get(value, {c})[c]; }

  std::vector<const Prediction*> get(double value, const std::vector<std::size_t>& cases) {
    auto& known = table_[value];
    std::vector<std::size_t> missing;
    for (std::size_t c : cases)
      if (!known.count(c)) missing.push_back(c);
    if (!missing.empty()) {
      // At its neutral value the effect is off: the base model's setting, whose runs a solver already has.
      const EffectSetting setting = value == effect_->parameter.neutral ? EffectSetting{} : EffectSetting{effect_, value};
      auto predicted = model_.predict(data_, missing, setting);
      for (std::size_t k = 0; k < missing.size(); ++k) known.emplace(missing[k], std::move(predicted[k]));
    }
    std::vector<const Prediction*> out(data_.cases.size(), nullptr);
    for (std::size_t c : cases) out[c] = &known.at(c);
    return out;
  }
  int evaluations() const { return static_cast<int>(table_.size()); }

 private:
  Model& model_;
  const MeasuredData& data_;
  const Effect* effect_;
  std::map<double, std::map<std::size_t, Prediction>> table_;
};

std::vector<double> gridOf(const EffectParameter& p, int points) {
  std::vector<double> grid;
  points = std::max(points, 2);
  for (int k = 0; k < points; ++k) grid.push_back(p.lower + (p.upper - p.lower) * k / (points - 1));
  const double tol = 1e-9 * (p.upper - p.lower);
  bool hasNeutral = false;
  for (double& x : grid)
    if (std::abs(x - p.neutral) <= tol) x = p.neutral, hasNeutral = true;
  if (!hasNeutral && p.neutral >= p.lower && p.neutral <= p.upper) grid.push_back(p.neutral);
  std::sort(grid.begin(), grid.end());
  return grid;
}

// The parameter minimising E over `cases`: the grid, then golden-section steps inside the best grid point's
// neighbours. The best value seen is kept (a discrete objective, as outcomes without a margin give, may not be
// unimodal). Ties go to the value nearest the neutral one: no change without evidence.
double fit1d(Memo& memo, const MeasuredData& data, const Yardstick& yard, const std::vector<std::vector<std::size_t>>& rows,
             const std::vector<std::size_t>& cases, const EffectParameter& p, const std::vector<double>& grid, int refineSteps) {
  double bestX = p.neutral, bestE = std::numeric_limits<double>::infinity();
  const auto consider = [&](double x) {
    const double e = caseErrors(data, yard, rows, cases, memo.get(x, cases)).combined();
    const bool better = e < bestE * (1 - 1e-12) ||
                        (e <= bestE * (1 + 1e-12) && std::abs(x - p.neutral) < std::abs(bestX - p.neutral));
    if (better) bestE = e, bestX = x;
    return e;
  };
  for (double x : grid) consider(x);
  if (refineSteps <= 0) return bestX;
  const auto it = std::lower_bound(grid.begin(), grid.end(), bestX);
  const std::size_t b = static_cast<std::size_t>(it - grid.begin());
  double lo = grid[b > 0 ? b - 1 : 0], hi = grid[std::min(b + 1, grid.size() - 1)];
  const double g = 0.5 * (std::sqrt(5.0) - 1.0);
  double x1 = hi - g * (hi - lo), x2 = lo + g * (hi - lo);
  double f1 = consider(x1), f2 = consider(x2);
  for (int step = 2; step < refineSteps; ++step) {
    if (f1 <= f2) {
      hi = x2, x2 = x1, f2 = f1, x1 = hi - g * (hi - lo), f1 = consider(x1);
    } else {
      lo = x1, x1 = x2, f1 = f2, x2 = lo + g * (hi - lo), f2 = consider(x2);
    }
  }
  return bestX;
}

double printed(double si, const std::string& unit) { return unit.empty() ? si : units::toUnit(si, unit); }

double pearson(const std::vector<double>& x, const std::vector<double>& y) {
  const double n = static_cast<double>(x.size());
  const double mx = std::accumulate(x.begin(), x.end(), 0.0) / n, my = std::accumulate(y.begin(), y.end(), 0.0) / n;
  double sxy = 0, sxx = 0, syy = 0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    sxy += (x[i] - mx) * (y[i] - my);
    sxx += (x[i] - mx) * (x[i] - mx);
    syy += (y[i] - my) * (y[i] - my);
  }
  return sxx > 0 && syy > 0 ? sxy / std::sqrt(sxx * syy) : 0.0;
}

// The effects a calibration fits: those named, else every effect of the model.
std::vector<const Effect*> selectedEffects(const Model& model, const CalibrationOptions& options) {
  std::vector<const Effect*> effects;
  if (options.effects.empty()) {
    for (const Effect& e : model.effects()) effects.push_back(&e);
  } else {
    for (const std::string& name : options.effects) effects.push_back(&findEffect(model, name, InputLocation::flag("--effects")));
  }
  return effects;
}

void checkCaseCount(const MeasuredData& data) {
  if (data.cases.size() < 3)
    throw InputError(InputLocation::file(data.source), "only " + std::to_string(data.cases.size()) + " case(s) measured",
                     "at least 3 cases, so that an effect can be checked on held-out cases");
}

}  // namespace

std::vector<PlannedPrediction> plannedPredictions(const Model& model, const MeasuredData& data,
                                                  const CalibrationOptions& options) {
  checkCaseCount(data);
  model.check(data);
  const int refineSteps = options.refineSteps >= 0 ? options.refineSteps : model.suggestedRefineSteps();
  if (refineSteps > 0)
    throw InputError(InputLocation::flag("--refine"), "a fit with " + std::to_string(refineSteps) +
                         " golden-section steps picks its parameter values from the errors it finds, so its "
                         "predictions cannot be shared out beforehand",
                     "--refine 0 (the grid only)");
  const int gridPoints = options.gridPoints > 0 ? options.gridPoints : model.suggestedGridPoints();
  std::vector<PlannedPrediction> plan;
  for (std::size_t c = 0; c < data.cases.size(); ++c) plan.push_back({{}, c});
  for (const Effect* effect : selectedEffects(model, options))
    for (double x : gridOf(effect->parameter, gridPoints))
      if (x != effect->parameter.neutral)
        for (std::size_t c = 0; c < data.cases.size(); ++c) plan.push_back({{effect, x}, c});
  return plan;
}

std::size_t predictShare(Model& model, const MeasuredData& data, const std::vector<PlannedPrediction>& plan,
                         int taskIndex, int taskCount) {
  if (taskCount < 1 || taskIndex < 1 || taskIndex > taskCount)
    throw InputError(InputLocation::flag("--task"),
                     "task " + std::to_string(taskIndex) + "/" + std::to_string(taskCount) + " does not exist",
                     "I/N with 1 <= I <= N");
  // Grouped by setting, so that the model can run one setting's cases at once (its --jobs).
  std::vector<std::pair<EffectSetting, std::vector<std::size_t>>> groups;
  std::size_t made = 0;
  for (std::size_t k = 0; k < plan.size(); ++k) {
    if (!campaign::ownsPoint(static_cast<int>(k), taskIndex, taskCount)) continue;
    const PlannedPrediction& p = plan[k];
    if (groups.empty() || groups.back().first.effect != p.setting.effect || groups.back().first.value != p.setting.value)
      groups.push_back({p.setting, {}});
    groups.back().second.push_back(p.caseIndex);
    ++made;
  }
  for (const auto& [setting, cases] : groups) model.predict(data, cases, setting);
  return made;
}

CalibrationResult calibrate(Model& model, const MeasuredData& data, const CalibrationOptions& options) {
  checkCaseCount(data);
  model.check(data);
  const std::vector<const Effect*> effects = selectedEffects(model, options);

  CalibrationResult result;
  result.model = model.describe();
  result.source = data.source;
  result.options = options;
  const std::size_t n = data.cases.size();
  const int folds = options.folds > 0 ? std::min<int>(options.folds, static_cast<int>(n)) : (n <= 20 ? static_cast<int>(n) : 10);
  result.folds = folds;
  const int gridPoints = options.gridPoints > 0 ? options.gridPoints : model.suggestedGridPoints();
  const int refineSteps = options.refineSteps >= 0 ? options.refineSteps : model.suggestedRefineSteps();

  const Yardstick yard(data);
  const auto rows = rowsByCase(data);
  std::vector<std::size_t> all(n);
  std::iota(all.begin(), all.end(), 0);

  result.basePredictions = model.predict(data, all, {});
  result.before = summarise(data, yard, result.basePredictions);
  std::vector<const Prediction*> baseOfCase;
  for (const auto& p : result.basePredictions) baseOfCase.push_back(&p);
  const CaseErrors baseShares = caseErrors(data, yard, rows, all, baseOfCase);

  // Diagnosis: do the base residuals follow a feature of the cases?
  for (const auto& [name, feature] : std::vector<std::pair<std::string, double MeasuredCase::*>>{
           {"diameter", &MeasuredCase::diameter}, {"velocity", &MeasuredCase::velocity}, {"angle", &MeasuredCase::angle}}) {
    std::vector<double> x, y;
    for (const Observation& o : data.observations) {
      x.push_back(data.cases[o.caseIndex].*feature);
      y.push_back(residualOf(o, result.basePredictions[o.caseIndex]) / yard.scale.at(groupOf(o.kind)));
    }
    const auto [mn, mx] = std::minmax_element(x.begin(), x.end());
    if (*mx > *mn) result.features.push_back({name, pearson(x, y), static_cast<int>(x.size())});
  }

  for (const Effect* effect : effects) {
    EffectFit fit;
    fit.effect = *effect;
    Memo memo(model, data, effect);
    const EffectParameter& p = effect->parameter;
    const auto grid = gridOf(p, gridPoints);
    fit.parameter = fit1d(memo, data, yard, rows, all, p, grid, refineSteps);
    for (std::size_t c : all) fit.predictions.push_back(memo.at(fit.parameter, c));
    for (double x : grid) fit.profile.emplace_back(x, caseErrors(data, yard, rows, all, memo.get(x, all)).combined());
    fit.fitted = summarise(data, yard, fit.predictions);
    fit.explainedShare = result.before.combined > 0
                             ? 1 - std::pow(fit.fitted.combined / result.before.combined, 2)
                             : 0.0;

    // Sensitivity from the neutral value to its nearest grid neighbour (both already run).
    const auto at0 = std::find(grid.begin(), grid.end(), p.neutral);
    if (at0 != grid.end() && grid.size() > 1) {
      const double x1 = at0 + 1 != grid.end() ? *(at0 + 1) : *(at0 - 1);
      double s = 0;
      int count = 0;
      for (const Observation& o : data.observations) {
        const double d = (predictedValue(o, memo.at(x1, o.caseIndex)) - predictedValue(o, memo.at(p.neutral, o.caseIndex))) /
                         yard.scale.at(groupOf(o.kind));
        s += d * d;
        ++count;
      }
      fit.sensitivity = std::sqrt(s / count) / std::abs(printed(x1, p.unit) - printed(p.neutral, p.unit));
    }

    // Held out: fit without each fold, predict the fold.
    fit.heldoutPredictions.resize(n);
    std::vector<const Prediction*> heldoutOfCase(n, nullptr);
    for (int k = 0; k < folds; ++k) {
      std::vector<std::size_t> train, test;
      for (std::size_t c : all) (static_cast<int>(c % folds) == k ? test : train).push_back(c);
      const double x = fit1d(memo, data, yard, rows, train, p, grid, refineSteps);
      fit.foldParameters.push_back(x);
      for (std::size_t c : test) fit.heldoutPredictions[c] = memo.at(x, c);
    }
    for (std::size_t c : all) heldoutOfCase[c] = &fit.heldoutPredictions[c];
    const CaseErrors heldout = caseErrors(data, yard, rows, all, heldoutOfCase);
    fit.heldoutError = heldout.combined();
    fit.relativeImprovement = result.before.combined > 0 ? 1 - fit.heldoutError / result.before.combined : 0.0;

    const bool overCases = options.pairedOver == PairedUnit::cases;
    const std::vector<double>& before = overCases ? baseShares.share : baseShares.observationShare;
    const std::vector<double>& after = overCases ? heldout.share : heldout.observationShare;
    fit.tStatistic = pairedTStatistic(before, after);
    fit.heldoutShares = after;
    fit.evaluations = memo.evaluations();

    const bool enough = fit.relativeImprovement >= options.minRelativeImprovement;
    const bool significant = fit.tStatistic >= options.minTStatistic;
    fit.accepted = enough && significant;
    char buf[256];
    std::snprintf(buf, sizeof buf, "held-out error %s by %.1f %% (needs >= %.0f %%), t = %.2f (needs >= %.1f)",
                  fit.relativeImprovement >= 0 ? "lower" : "higher", 100 * std::abs(fit.relativeImprovement),
                  100 * options.minRelativeImprovement, fit.tStatistic, options.minTStatistic);
    fit.verdict = std::string(fit.accepted ? "accepted: " : "rejected: ") + buf;
    result.ranking.push_back(std::move(fit));
  }
  std::stable_sort(result.ranking.begin(), result.ranking.end(),
                   [](const EffectFit& a, const EffectFit& b) { return a.heldoutError < b.heldoutError; });
  for (std::size_t i = 0; i < result.ranking.size(); ++i) {
    if (!result.ranking[i].accepted) continue;
    if (result.winner) result.alsoAccepted.push_back(i);
    else result.winner = i;
  }
  for (std::size_t i : result.alsoAccepted)
    result.ranking[i].tAgainstWinner =
        pairedTStatistic(result.ranking[i].heldoutShares, result.ranking[*result.winner].heldoutShares);
  return result;
}

std::vector<std::size_t> CalibrationResult::indistinguishable() const {
  std::vector<std::size_t> out;
  for (std::size_t i : alsoAccepted)
    if (!(ranking[i].tAgainstWinner >= options.minTStatistic)) out.push_back(i);
  return out;
}

namespace {

nlohmann::json errorsJson(const ErrorSummary& e) {
  nlohmann::json groups = nlohmann::json::object();
  for (const auto& [g, ge] : e.groups) {
    nlohmann::json j = {{"count", ge.count}};
    if (g == ErrorGroup::outcome) {
      j["rms_margin"] = ge.rms;
      j["misclassified"] = ge.misclassified;
    } else if (g == ErrorGroup::residualVelocity) {
      j["rms_m_s"] = ge.rms;
      j["scale_m_s"] = ge.scale;
    } else {
      j["rms_m"] = ge.rms;
      j["scale_m"] = ge.scale;
    }
    groups[toString(g)] = j;
  }
  return groups;
}

nlohmann::json predictionsJson(const MeasuredData& data, const std::vector<Prediction>& p) {
  nlohmann::json rows = nlohmann::json::array();
  for (const Observation& o : data.observations)
    rows.push_back({{"case", data.cases[o.caseIndex].id}, {"kind", toString(o.kind)}, {"layer", o.layer},
                    {"measured", o.value}, {"predicted", predictedValue(o, p[o.caseIndex])}});
  return rows;
}

}  // namespace

nlohmann::json toJson(const CalibrationResult& r, const MeasuredData& data) {
  nlohmann::json ranking = nlohmann::json::array();
  for (const EffectFit& f : r.ranking) {
    nlohmann::json folds = nlohmann::json::array();
    for (double x : f.foldParameters) folds.push_back(x);
    nlohmann::json profile = nlohmann::json::array();
    for (const auto& [x, e] : f.profile) profile.push_back({{"parameter", x}, {"error", e}});
    ranking.push_back({{"effect", f.effect.name},
                       {"description", f.effect.description},
                       {"parameters", {{f.effect.parameter.jsonKey, f.parameter}}},
                       {"fold_parameters", folds},
                       {"range", {f.effect.parameter.lower, f.effect.parameter.upper}},
                       {"neutral", f.effect.parameter.neutral},
                       {"sensitivity_per_unit", f.sensitivity},
                       {"sensitivity_unit", f.effect.parameter.unit},
                       {"error", f.fitted.combined},
                       {"errors", errorsJson(f.fitted)},
                       {"heldout_error", f.heldoutError},
                       {"explained_share", f.explainedShare},
                       {"relative_improvement_heldout", f.relativeImprovement},
                       {"t_statistic", std::isfinite(f.tStatistic) ? nlohmann::json(f.tStatistic) : nlohmann::json("inf")},
                       {"accepted", f.accepted},
                       {"verdict", f.verdict},
                       {"evaluations", f.evaluations},
                       {"profile", profile}});
  }
  const EffectFit* w = r.winningFit();
  const auto alsoAcceptedNames = [](const CalibrationResult& c) {
    nlohmann::json names = nlohmann::json::array();
    for (std::size_t i : c.alsoAccepted) names.push_back(c.ranking[i].effect.name);
    return names;
  };
  const auto alsoAcceptedT = [](const CalibrationResult& c) {
    nlohmann::json t = nlohmann::json::array();
    for (std::size_t i : c.alsoAccepted) {
      const double v = c.ranking[i].tAgainstWinner;
      t.push_back(std::isfinite(v) ? nlohmann::json(v) : nlohmann::json("inf"));  // pairedTStatistic: never -inf
    }
    return t;
  };
  nlohmann::json features = nlohmann::json::array();
  for (const auto& f : r.features) features.push_back({{"feature", f.feature}, {"correlation", f.correlation}, {"count", f.count}});
  nlohmann::json doc = {
      {"measured", r.source},
      {"model", r.model},
      {"cases", data.cases.size()},
      {"observations", data.observations.size()},
      {"folds", r.folds},
      {"effect", w ? nlohmann::json(w->effect.name) : nlohmann::json("none")},
      {"no_effect_found", w == nullptr},
      {"also_accepted", alsoAcceptedNames(r)},
      {"also_accepted_t_against_winner", alsoAcceptedT(r)},
      {"winner_singled_out", w != nullptr && r.indistinguishable().empty()},
      {"parameters", w ? nlohmann::json{{w->effect.parameter.jsonKey, w->parameter}} : nlohmann::json::object()},
      {"error_before", r.before.combined},
      {"error_after", w ? w->fitted.combined : r.before.combined},
      {"heldout_error_before", r.before.combined},
      {"heldout_error_after", w ? w->heldoutError : r.before.combined},
      {"errors_before", errorsJson(r.before)},
      {"errors_after", errorsJson(w ? w->fitted : r.before)},
      {"residual_features", features},
      {"rule",
       {{"min_relative_improvement", r.options.minRelativeImprovement},
        {"min_t_statistic", r.options.minTStatistic},
        {"paired_over", toString(r.options.pairedOver)}}},
      {"ranking", ranking},
      {"predictions_before", predictionsJson(data, r.basePredictions)},
      {"predictions_after", predictionsJson(data, w ? w->predictions : r.basePredictions)}};
  return doc;
}

}  // namespace blt::calibrate
