#include "blt/calibrate/report.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "blt/core/error.hpp"
#include "blt/core/svg_plot.hpp"
#include "blt/core/units.hpp"

namespace blt::calibrate {

namespace {

std::string num(double v, int digits = 4) {
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  std::ostringstream out;
  out.precision(digits);
  out << v;
  return out.str();
}

std::string withUnit(double si, const std::string& unit) {
  return unit.empty() ? num(si) : num(units::toUnit(si, unit)) + " " + unit;
}

std::string groupLine(ErrorGroup g, const GroupError& e) {
  switch (g) {
    case ErrorGroup::outcome:
      return std::to_string(e.misclassified) + " of " + std::to_string(e.count) + " outcomes wrong (RMS margin " +
             num(e.rms) + ")";
    case ErrorGroup::residualVelocity:
      return "residual velocity RMS " + num(e.rms) + " m/s over " + std::to_string(e.count);
    case ErrorGroup::hole:
      return "hole size RMS " + num(e.rms * 1e3) + " mm over " + std::to_string(e.count);
  }
  return "";
}

std::string errorsText(const ErrorSummary& e) {
  std::string s = "E = " + num(e.combined);
  for (const auto& [g, ge] : e.groups) s += "; " + groupLine(g, ge);
  return s;
}

// Predicted against measured, before (open) and after (filled), for the observations of one group.
void plotGroup(const std::string& path, ErrorGroup group, const CalibrationResult& r, const MeasuredData& data) {
  const double factor = group == ErrorGroup::hole ? 1e3 : 1.0;
  const std::string unit = group == ErrorGroup::hole ? "mm" : "m/s";
  svg::Series before, after;
  before.label = "base model";
  before.style = svg::Style::openPoints;
  after.label = r.winningFit() ? "with " + r.winningFit()->effect.name : "";
  after.style = svg::Style::points;
  for (const Observation& o : data.observations) {
    if (groupOf(o.kind) != group) continue;
    const std::string tip = "case " + data.cases[o.caseIndex].id + (o.layer.empty() ? "" : ", " + o.layer + " " + toString(o.kind));
    before.x.push_back(o.value * factor);
    before.y.push_back(predictedValue(o, r.basePredictions[o.caseIndex]) * factor);
    before.tooltips.push_back(tip);
    if (const EffectFit* w = r.winningFit()) {
      after.x.push_back(o.value * factor);
      after.y.push_back(predictedValue(o, w->predictions[o.caseIndex]) * factor);
      after.tooltips.push_back(tip);
    }
  }
  std::vector<svg::Series> series{before};
  if (!after.x.empty()) series.push_back(after);
  svg::PlotOptions options;
  options.title = std::string(group == ErrorGroup::hole ? "Hole sizes" : "Residual velocities") + ": predicted against measured";
  options.subtitle = r.model;
  options.xLabel = "measured (" + unit + ")";
  options.yLabel = "predicted (" + unit + ")";
  options.identityLine = true;
  svg::writePlot(path, series, options);
}

}  // namespace

std::vector<std::string> writeReport(const std::string& directory, const CalibrationResult& r, const MeasuredData& data) {
  namespace fs = std::filesystem;
  std::error_code ec;
  fs::create_directories(directory, ec);
  if (ec) throw InputError(InputLocation::flag("--report"), "cannot create the directory " + directory + ": " + ec.message(),
                           "a writable directory");
  std::vector<std::string> written;
  const auto path = [&](const std::string& name) { return (fs::path(directory) / name).string(); };

  {
    std::ofstream out(path("calibration.json"));
    if (!out) throw InputError(InputLocation::flag("--report"), "cannot write " + path("calibration.json"), "a writable directory");
    out << toJson(r, data).dump(2) << "\n";
    written.push_back(path("calibration.json"));
  }
  std::vector<std::pair<ErrorGroup, std::string>> plots;
  for (ErrorGroup g : {ErrorGroup::residualVelocity, ErrorGroup::hole})
    if (r.before.groups.count(g)) {
      const std::string name = std::string(toString(g)) + ".svg";
      plotGroup(path(name), g, r, data);
      written.push_back(path(name));
      plots.emplace_back(g, name);
    }

  const EffectFit* w = r.winningFit();
  std::ostringstream md;
  md << "# Calibration against measured data\n\n";
  md << "- measured: `" << r.source << "` (" << data.cases.size() << " cases, " << data.observations.size()
     << " observations)\n";
  md << "- base model: " << r.model << "\n";
  md << "- held-out check: " << r.folds << "-fold cross-validation over cases (case i in fold i mod " << r.folds
     << (r.folds == static_cast<int>(data.cases.size()) ? "; leave-one-out" : "") << ")\n\n";
  md << "## Result\n\n";
  if (w) {
    md << "**Effect found: `" << w->effect.name << "`** (" << w->effect.description << "), "
       << w->effect.parameter.name << " = " << withUnit(w->parameter, w->effect.parameter.unit) << ".\n\n";
    const std::vector<std::size_t> rivals = r.indistinguishable();
    const auto listFits = [&](const std::vector<std::size_t>& which) {
      for (std::size_t k = 0; k < which.size(); ++k) {
        const EffectFit& f = r.ranking[which[k]];
        md << (k ? ", " : "") << "`" << f.effect.name << "` (" << f.effect.parameter.name << " = "
           << withUnit(f.parameter, f.effect.parameter.unit) << ", held-out error " << num(f.heldoutError)
           << ", t = " << num(f.tAgainstWinner) << " against the winner)";
      }
    };
    if (!rivals.empty()) {
      md << "**Not the only explanation:** also accepted, and not significantly worse than the winner (paired t "
            "of their held-out errors below "
         << num(r.options.minTStatistic) << "): ";
      listFits(rivals);
      md << ". The data do not single out one effect; a case where their predictions differ would.\n\n";
    }
    std::vector<std::size_t> worse;
    for (std::size_t i : r.alsoAccepted)
      if (std::find(rivals.begin(), rivals.end(), i) == rivals.end()) worse.push_back(i);
    if (!worse.empty()) {
      md << "Also accepted against the base model, but significantly worse than the winner: ";
      listFits(worse);
      md << ".\n\n";
    }
  } else {
    md << "**No effect found**: no candidate lowers the held-out error enough and significantly (rule below).\n\n";
  }
  md << "| | fitted cases | held out |\n|---|---|---|\n";
  md << "| before (base) | " << num(r.before.combined) << " | " << num(r.before.combined) << " |\n";
  md << "| after | " << num(w ? w->fitted.combined : r.before.combined) << " | "
     << num(w ? w->heldoutError : r.before.combined) << " |\n\n";
  md << "Before: " << errorsText(r.before) << ".\n\n";
  if (w) md << "After: " << errorsText(w->fitted) << ".\n\n";
  md << "The base model has no fitted parameter, so its held-out error is its error.\n\n";

  md << "## Error measure and decision rule\n\n";
  md << "Residual = predicted - measured (residual velocities, hole sizes); for outcomes the margin to the right side "
        "(ln(V/V_bl) or ln(d/d_c) when the model has one), else predicted - measured outcome (-1, 0, 1). Each group "
        "(outcomes, residual velocities, hole sizes) is scaled (outcomes by 1, the others by the RMS of their "
        "measured values) and E = sqrt(mean over groups of the mean squared scaled residual).\n\n";
  md << "An effect is accepted when its held-out error is at least " << num(100 * r.options.minRelativeImprovement)
     << " % below the base's and the paired improvement over " << toString(r.options.pairedOver)
     << " (each one's share of E^2, base minus held out) has t = mean/(sd/sqrt(n)) >= " << num(r.options.minTStatistic)
     << ". The accepted effect with the lowest held-out error wins. Each other accepted effect is compared with the "
        "winner by the same paired t (its held-out shares minus the winner's); below the threshold the data do not "
        "tell the two apart.\n\n";

  md << "## Diagnosis: base residuals against the cases' features\n\n";
  if (r.features.empty()) md << "No feature varies over the cases.\n\n";
  else {
    md << "| feature | correlation with the scaled residual | rows |\n|---|---|---|\n";
    for (const auto& f : r.features) md << "| " << f.feature << " | " << num(f.correlation, 3) << " | " << f.count << " |\n";
    md << "\n";
  }

  md << "## Candidate effects, ranked by held-out error\n\n";
  md << "| rank | effect | fitted parameter | sensitivity | error (fitted) | explained | held-out error | t | runs | decision |\n";
  md << "|---|---|---|---|---|---|---|---|---|---|\n";
  for (std::size_t i = 0; i < r.ranking.size(); ++i) {
    const EffectFit& f = r.ranking[i];
    const auto& p = f.effect.parameter;
    md << "| " << i + 1 << " | `" << f.effect.name << "` | " << p.name << " = " << withUnit(f.parameter, p.unit) << " | "
       << num(f.sensitivity, 3) << (p.unit.empty() ? "" : " /" + p.unit) << " | " << num(f.fitted.combined) << " | "
       << num(100 * f.explainedShare, 3) << " % | " << num(f.heldoutError) << " | " << num(f.tStatistic, 3) << " | "
       << f.evaluations << " | " << f.verdict << " |\n";
  }
  md << "\nSensitivity: RMS change of the scaled predictions per unit of the parameter, from its neutral value to the "
        "next grid point. Runs: parameter values at which the model was evaluated.\n\n";
  for (const EffectFit& f : r.ranking) {
    md << "- `" << f.effect.name << "`: " << f.effect.description << "; range "
       << withUnit(f.effect.parameter.lower, f.effect.parameter.unit) << " to "
       << withUnit(f.effect.parameter.upper, f.effect.parameter.unit) << ", off at "
       << withUnit(f.effect.parameter.neutral, f.effect.parameter.unit) << "; fold fits:";
    for (double x : f.foldParameters) md << " " << withUnit(x, f.effect.parameter.unit);
    md << "; error on all cases over the grid:";
    for (const auto& [x, e] : f.profile) md << " " << withUnit(x, f.effect.parameter.unit) << ": " << num(e, 3) << ",";
    md << "\n";
  }
  md << "\n## Predicted against measured\n\n";
  for (const auto& [g, name] : plots) md << "![" << toString(g) << "](" << name << ")\n\n";
  md << "| case | quantity | measured | base | after |\n|---|---|---|---|---|\n";
  for (const Observation& o : data.observations) {
    const bool hole = groupOf(o.kind) == ErrorGroup::hole;
    const auto show = [&](double v) {
      return o.kind == ObservationKind::outcome ? std::string(v > 0.5 ? "perforated" : "stopped") : num(hole ? v * 1e3 : v);
    };
    md << "| " << data.cases[o.caseIndex].id << " | " << toString(o.kind) << (o.layer.empty() ? "" : " " + o.layer)
       << (hole ? " (mm)" : o.kind == ObservationKind::residualVelocity ? " (m/s)" : "") << " | " << show(o.value) << " | "
       << show(predictedValue(o, r.basePredictions[o.caseIndex])) << " | "
       << show(predictedValue(o, w ? w->predictions[o.caseIndex] : r.basePredictions[o.caseIndex])) << " |\n";
  }
  std::ofstream out(path("report.md"));
  if (!out) throw InputError(InputLocation::flag("--report"), "cannot write " + path("report.md"), "a writable directory");
  out << md.str();
  written.push_back(path("report.md"));
  return written;
}

}  // namespace blt::calibrate
