// blt validate: the solver against the seeds' measurements (and the seeds' own simulations where they have
// them), written as a Markdown report with SVG figures and a JSON document. Not part of CI: the full report
// takes tens of minutes on 2 cores, --quick a few.
//
// Every run is appended to OUT/runs.jsonl as it finishes, keyed by the scenario (its path and the hash of its
// text, so an edited file is run again), the model fingerprint (a changed solver or material card runs again)
// and the settings; a report started again reuses those runs, so an interrupted report loses nothing and a
// finished one is rewritten for free.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include "blt/core/csv.hpp"
#include "blt/core/error.hpp"
#include "blt/core/svg_plot.hpp"
#include "blt/sim/impact.hpp"
#include "blt/sim/run_cache.hpp"
#include "cli_support.hpp"
#include "commands.hpp"

namespace blt::cli {

namespace {

using nlohmann::json;
using namespace blt::sim;
namespace fs = std::filesystem;

const std::vector<std::string> kSections{"table1", "table5", "table6", "table7", "seed003", "weldox", "seed001",
                                         "convergence"};

struct ValidateOptions {
  std::string out = "validation";
  bool quick = false;
  std::vector<std::string> only;
  int threads = 0;
  bool json = false;
  int alignments = 1;  // Table 1 also at grid offsets k/N (the verdict's discretisation noise), when above 1
};

std::string fmt(double v, const char* f = "%.3g") {
  if (!std::isfinite(v)) return "n/a";
  char b[48];
  std::snprintf(b, sizeof b, f, v);
  return b;
}
std::string percent(double error) { return std::isfinite(error) ? fmt(100 * error, "%+.1f") + " %" : "n/a"; }
double relativeError(double ours, double reference) { return reference != 0 ? (ours - reference) / reference : NAN; }

std::string dataFile(const std::string& name) { return std::string(BLT_DATA_DIR) + "/" + name; }

// The runs of this report, remembered in OUT/runs.jsonl (blt/sim/run_cache.hpp).
class RunLog {
 public:
  RunLog(const std::string& path, int threads) : cache_(path), threads_(threads) {}

  // The summary of a run of `scenario` (a data/ path) with these settings: remembered, or run now.
  json run(const std::string& scenario, const std::vector<std::string>& settings, const std::string& label) {
    std::ifstream file(dataFile(scenario));
    const std::string text((std::istreambuf_iterator<char>(file)), std::istreambuf_iterator<char>());
    const std::string key = RunCache::key(scenario, text, settings);
    if (auto found = cache_.find(key)) return *found;
    const ImpactScenario sc = loadScenario(dataFile(scenario), settings);
    ImpactRunOptions ro;
    ro.threads = threads_;
    std::fprintf(stderr, "[validate] %s ...", label.c_str());
    std::fflush(stderr);
    const ImpactResult r = runImpact(sc, ro);
    std::fprintf(stderr, " %s, %.1f s\n", r.summary["perforated"].get<bool>() ? "perforated" : "not perforated",
                 r.wallSeconds);
    cache_.record(key, r.summary);
    ++made_;
    return r.summary;
  }

  std::size_t made() const { return made_; }
  std::size_t reused() const { return cache_.loaded(); }

 private:
  RunCache cache_;
  int threads_;
  std::size_t made_ = 0;
};

// The SI value as a number in `unit`, for a key=value setting ("1.2" for 1.2e-3 m in mm).
std::string inUnit(double v, const char* unit) { return fmt(units::toUnit(v, unit), "%.6g"); }

// A bisection whose runs all go through the log.
struct Limit {
  BisectionResult result;
  double estimate() const { return result.resolved ? result.estimate() : NAN; }
  std::string bracket(const char* unit, double scale) const {
    const BisectionRun* safe = result.largestSafeRun();
    return "[" + fmt(result.largestSafe * scale, "%.4g") + ", " + fmt(result.smallestPerforating * scale, "%.4g") +
           "] " + unit + (safe && !safe->settled ? " (lower end unsettled at the end time)" : "");
  }
};

Limit ballisticLimit(RunLog& log, const std::string& scenario, std::vector<std::string> settings, BisectVariable on,
                     double lo, double hi, double tol, const std::string& label) {
  BisectionOptions bo;
  bo.variable = on;
  bo.lower = lo;
  bo.upper = hi;
  bo.tolerance = tol;
  const char* unit = on == BisectVariable::diameter ? "mm" : "m/s";
  const std::string key = on == BisectVariable::diameter ? "projectile.diameter=" : "projectile.velocity=";
  const auto evaluate = [&](double value) {
    std::vector<std::string> s = settings;
    s.push_back(key + inUnit(value, unit) + unit);
    const json r = log.run(scenario, s, label + " at " + units::format(value, unit, 4));
    BisectionRun br;
    br.perforated = r["perforated"];
    br.settled = r["settled"];
    br.status = r["status"] == "unstable" ? RunStatus::unstable : RunStatus::completed;
    br.residualVelocity = r["residual_velocity_m_s"];
    br.wallSeconds = r["wall_time_s"];
    br.summary = r;
    return br;
  };
  return Limit{bisect(bo, evaluate)};
}

// One compared quantity: the row of a table and its JSON.
struct Comparison {
  Comparison(std::string s, std::string i, std::string q, std::string u)
      : section(std::move(s)), item(std::move(i)), quantity(std::move(q)), unit(std::move(u)) {}
  std::string section, item, quantity, unit;
  double measured = NAN, seedModel = NAN, ours = NAN;
  std::string target;  // e.g. "within 15 %"
  double tolerance = NAN;  // relative; NaN: no numeric target
  std::string note;
  double error() const { return relativeError(ours, std::isfinite(measured) ? measured : seedModel); }
  bool met() const { return std::isfinite(tolerance) && std::isfinite(error()) && std::abs(error()) <= tolerance; }
  json toJson() const {
    auto num = [](double v) { return std::isfinite(v) ? json(v) : json(nullptr); };
    return {{"section", section}, {"item", item}, {"quantity", quantity}, {"unit", unit}, {"measured", num(measured)},
            {"seed_model", num(seedModel)}, {"ours", num(ours)}, {"error", num(error())}, {"target", target},
            {"met", met()}, {"note", note}};
  }
};

struct CriticalDiameterCase {
  std::string section, heading, table, figure;
  std::vector<double> anglesDeg, velocitiesKmS;
  std::vector<std::string> settings;  // before the velocity and angle (a resolution)
  double lower = 0, upper = 0, tolerance = 0;  // m
};

class Report {
 public:
  Report(const ValidateOptions& o) : o_(o), log_((fs::path(o.out) / "runs.jsonl").string(), o.threads) {}

  bool wanted(const std::string& s) const {
    return o_.only.empty() || std::find(o_.only.begin(), o_.only.end(), s) != o_.only.end();
  }

  void table1();
  struct Table1Shot {
    std::string id;
    double diameter, velocity;  // m, m/s
    bool measured, correctedAtZero;  // perforated in the test; by the corrected model at grid offset 0
  };
  void table1Alignments(const std::vector<Table1Shot>& shots);
  void table5();
  void table6();
  void table7();
  void criticalDiameters(const CriticalDiameterCase& c);
  void seed003();
  void weldox();
  void seed001();
  void convergence();
  void write(double seconds);

 private:
  // The fabric target's settings of this report's resolution (quick: the seed's, which is cheap in 2D).
  std::vector<std::string> shot(double d, double v, double angleDeg = 0) const {
    return {"projectile.diameter=" + inUnit(d, "mm") + "mm", "projectile.velocity=" + inUnit(v, "km/s") + "km/s",
            "projectile.angle=" + fmt(angleDeg, "%.6g") + "deg"};
  }
  // The scenario's particle spacing and cell size, both times `factor`; no settings at factor 1, so that a run at the
  // scenario's own resolution keeps the key it has in runs.jsonl.
  std::vector<std::string> scaledResolution(const std::string& scenario, double factor) const {
    if (factor == 1.0) return {};
    const ImpactScenario sc = loadScenario(dataFile(scenario));
    return {"resolution.particle_spacing=" + inUnit(factor * sc.resolution.particleSpacing, "mm") + "mm",
            "resolution.cell_size=" + inUnit(factor * sc.cellSize(), "mm") + "mm"};
  }
  // Coarser (twice the spacing) in --quick mode for the costly scenarios.
  std::vector<std::string> coarse(const std::string& scenario) const {
    return scaledResolution(scenario, o_.quick ? 2.0 : 1.0);
  }
  void figure(const std::string& name, const svg::Plot& plot) {
    svg::writeSvg((fs::path(o_.out) / name).string(), plot);
    md_ << "\n![" << plot.options.title << "](" << name << ")\n";
  }
  void comparisonTable(const std::vector<Comparison>& rows, bool withSeedModel);
  // Simulated against measured, with the y = x line.
  void parityFigure(const std::string& name, const std::string& title, const std::string& quantity,
                    const std::vector<svg::Series>& series) {
    svg::Plot p{{}, series, {}};
    p.options.title = title;
    p.options.xLabel = "Measured " + quantity;
    p.options.yLabel = "Simulated " + quantity;
    p.options.identityLine = true;
    figure(name, p);
  }
  static json toJson(const std::vector<Comparison>& rows) {
    json j = json::array();
    for (const auto& k : rows) j.push_back(k.toJson());
    return j;
  }

  const ValidateOptions& o_;
  RunLog log_;
  std::ostringstream md_;
  std::vector<Comparison> all_;
  json sections_ = json::object();
};

void Report::comparisonTable(const std::vector<Comparison>& rows, bool withSeedModel) {
  md_ << "\n| item | quantity | measured | " << (withSeedModel ? "seed's model | " : "") << "ours | error | target |\n"
      << "|---|---|---|" << (withSeedModel ? "---|" : "") << "---|---|---|\n";
  for (const Comparison& c : rows) {
    md_ << "| " << c.item << " | " << c.quantity << " (" << c.unit << ") | " << fmt(c.measured, "%.4g") << " | "
        << (withSeedModel ? fmt(c.seedModel, "%.4g") + " | " : "") << fmt(c.ours, "%.4g")
        << (c.note.empty() ? "" : " (" + c.note + ")") << " | " << percent(c.error()) << " | " << c.target
        << (std::isfinite(c.tolerance) ? (c.met() ? " met" : " **missed**") : "") << " |\n";
    all_.push_back(c);
  }
}

// Issue 5's target for seed 000 Table 1: right outcomes of the corrected model, of 13.
constexpr int kTable1RightTarget = 11;

// seed 000 Table 1: the 13 test outcomes with the corrected model (the target), the same with the multi-field
// contact instead of the scenario's single-field one (the sensitivity to that choice), and the original model.
void Report::table1() {
  const auto t = csv::Table::read(dataFile("seed/seed000_table1_tests.csv"));
  struct Model {
    const char* name;
    std::string scenario;
    std::vector<std::string> settings;
  };
  const std::vector<Model> models{{"corrected", "scenarios/fabric_al_corrected.toml", {}},
                                  {"corrected, multi-field contact", "scenarios/fabric_al_corrected.toml",
                                   {"solver.contact=multi-field"}},
                                  {"original", "scenarios/fabric_al_original.toml", {}}};
  md_ << "\n## Seed 000 Table 1: test outcomes (target: at least " << kTable1RightTarget
      << " of 13 right with the corrected model)\n\n"
      << "| test | d (mm) | V (km/s) | measured |";
  for (const auto& m : models) md_ << " " << m.name << " |";
  md_ << "\n|---|---|---|---|---|---|---|\n";
  std::vector<int> right(models.size(), 0);
  std::vector<Table1Shot> shots;
  json rows = json::array();
  svg::Series ok, wrong;
  ok.label = "corrected model right";
  ok.colour = "#009E73";
  wrong.label = "corrected model wrong";
  wrong.colour = "#D55E00";
  auto word = [](bool p) { return std::string(p ? "perforated" : "stopped"); };
  for (std::size_t r = 0; r < t.rowCount(); ++r) {
    const std::string id = t.text(r, t.column("test_id"));
    const double d = t.quantity(r, t.column("diameter_mm"), "mm"), v = t.quantity(r, t.column("velocity_km_s"), "km/s");
    const bool measured = t.flag(r, t.column("perforated"));
    md_ << "| " << id << " | " << fmt(d * 1e3) << " | " << fmt(v / 1e3) << " | " << word(measured) << " |";
    json row{{"test", id}, {"diameter_mm", d * 1e3}, {"velocity_km_s", v / 1e3}, {"measured_perforated", measured}};
    std::vector<bool> predicted;
    for (std::size_t m = 0; m < models.size(); ++m) {
      std::vector<std::string> s = shot(d, v);
      s.insert(s.end(), models[m].settings.begin(), models[m].settings.end());
      const json run = log_.run(models[m].scenario, s, "Table 1 test " + id + ", " + models[m].name);
      predicted.push_back(run["perforated"].get<bool>());
      right[m] += predicted[m] == measured;
      md_ << " " << word(predicted[m]) << (predicted[m] == measured ? "" : " (wrong)") << " |";
      row[std::string(models[m].name) + " perforated"] = predicted[m];
    }
    md_ << "\n";
    shots.push_back({id, d, v, measured, predicted[0]});
    svg::Series& s = predicted[0] == measured ? ok : wrong;
    s.x.push_back(v / 1e3);
    s.y.push_back(d * 1e3);
    s.open.push_back(!measured);
    s.tooltips.push_back("test " + id + ": measured " + word(measured) + ", corrected model " + word(predicted[0]));
    rows.push_back(row);
  }
  const int n = static_cast<int>(t.rowCount());
  md_ << "\nRight: ";
  json counts = json::object();
  for (std::size_t m = 0; m < models.size(); ++m) {
    md_ << (m ? ", " : "") << models[m].name << " " << right[m] << " of " << n;
    counts[models[m].name] = right[m];
  }
  md_ << ". Target (corrected model, at least " << kTable1RightTarget
      << "): " << (right[0] >= kTable1RightTarget ? "met" : "**missed**") << ".\n";
  svg::Plot p{{}, {ok, wrong}, {}};
  p.options.title = "Seed 000 Table 1: outcomes, corrected model";
  p.options.subtitle = "filled: perforated in the test, open: stopped; colour: model right or wrong";
  p.options.xLabel = "Impact velocity V (km/s)";
  p.options.yLabel = "Projectile diameter d (mm)";
  figure("table1_outcomes.svg", p);
  sections_["table1"] = {{"tests", n}, {"right", counts}, {"right_corrected", right[0]}, {"target_right", kTable1RightTarget},
                         {"met", right[0] >= kTable1RightTarget}, {"cases", rows}};
  if (o_.alignments > 1) table1Alignments(shots);
}

// The corrected model's Table 1 again with the grid shifted along the normal by k/N of a cell
// (resolution.grid_offset): near the limit the verdict turns with the alignment of grid and particles, and the
// spread of the count says how much of "11 of 13" is the discretisation. Offset 0 is the table above.
void Report::table1Alignments(const std::vector<Table1Shot>& shots) {
  const int n = o_.alignments;
  std::vector<double> offsets;
  for (int k = 0; k < n; ++k) offsets.push_back(static_cast<double>(k) / n);
  md_ << "\n### The corrected model at " << n << " alignments of grid and particles\n\n"
      << "The grid shifted along the target normal by a fraction of a cell (`resolution.grid_offset`); offset 0 is the "
         "table above. P: perforated, S: stopped.\n\n| test | measured |";
  for (double f : offsets) md_ << " " << fmt(f) << " |";
  md_ << " right |\n|---|---|";
  for (int k = 0; k <= n; ++k) md_ << "---|";
  md_ << "\n";
  std::vector<int> rightAt(n, 0);
  json cases = json::array();
  for (const Table1Shot& test : shots) {
    md_ << "| " << test.id << " | " << (test.measured ? "P" : "S") << " |";
    int right = 0;
    json verdicts = json::array();
    for (int k = 0; k < n; ++k) {
      bool perforated = test.correctedAtZero;
      if (k > 0) {
        std::vector<std::string> s = shot(test.diameter, test.velocity);
        s.push_back("resolution.grid_offset=" + fmt(offsets[k], "%.6g"));
        perforated = log_.run("scenarios/fabric_al_corrected.toml", s,
                              "Table 1 test " + test.id + ", corrected, grid offset " + fmt(offsets[k]))["perforated"];
      }
      right += perforated == test.measured;
      rightAt[k] += perforated == test.measured;
      verdicts.push_back(perforated);
      md_ << " " << (perforated ? "P" : "S") << (perforated == test.measured ? "" : "*") << " |";
    }
    md_ << " " << right << " of " << n << " |\n";
    cases.push_back({{"test", test.id}, {"perforated", verdicts}, {"right", right}});
  }
  const auto [least, most] = std::minmax_element(rightAt.begin(), rightAt.end());
  md_ << "\n\\* wrong. Right outcomes at each alignment: ";
  for (int k = 0; k < n; ++k) md_ << (k ? ", " : "") << rightAt[k];
  md_ << " of " << shots.size() << " (" << *least << " to " << *most << "); the target is judged at offset 0, as "
      << "above, and holds at " << std::count_if(rightAt.begin(), rightAt.end(), [](int c) { return c >= kTable1RightTarget; }) << " of "
      << n << " alignments.\n";
  sections_["table1"]["alignments"] = {{"grid_offsets", offsets}, {"right", rightAt}, {"cases", cases}};
}

// seed 000 Table 5: hole sizes of cases 03 and 05, original against corrected model.
void Report::table5() {
  const auto t = csv::Table::read(dataFile("seed/seed000_table5_holes.csv"));
  const auto tests = csv::Table::read(dataFile("seed/seed000_table1_tests.csv"));
  md_ << "\n## Seed 000 Table 5: hole sizes (target: within 30 %, the corrected model closer to the test than the "
         "original)\n\nAxisymmetric runs give D_h = D_v; the mean of the printed D_h and D_v is compared. Ours is the hole in "
         "the layer's intact material (the verdict's definition); in brackets its opening, where nothing of the layer is "
         "left, failed points included.\n";
  // Measured and the seed's models by (case, layer, result).
  std::map<std::string, double> printed;
  for (std::size_t r = 0; r < t.rowCount(); ++r)
    printed[t.text(r, t.column("case")) + "/" + t.text(r, t.column("layer")) + "/" + t.text(r, t.column("result"))] =
        0.5 * (t.number(r, t.column("hole_h_mm")) + t.number(r, t.column("hole_v_mm")));
  std::vector<Comparison> rows;
  svg::Series orig, corr;
  orig.label = "original model";
  corr.label = "corrected model";
  int closer = 0, pairs = 0;
  for (const std::string c : {"03", "05"}) {
    std::size_t row = 0;
    while (row < tests.rowCount() && tests.text(row, tests.column("test_id")) != c) ++row;
    const double d = tests.quantity(row, tests.column("diameter_mm"), "mm");
    const double v = tests.quantity(row, tests.column("velocity_km_s"), "km/s");
    for (const std::string layer : {"outer_layer", "aluminum_plate"}) {
      const int index = layer == "outer_layer" ? 0 : 3;  // outer fabric, 5A06 plate (the scenario's layers 1 and 4)
      double ours[2];
      const char* models[2] = {"original", "corrected"};
      for (int m = 0; m < 2; ++m) {
        const json s = log_.run(std::string("scenarios/fabric_al_") + models[m] + ".toml", shot(d, v),
                                "Table 5 case " + c + ", " + models[m] + " model");
        ours[m] = 0.5 * (s["hole_size_mm"][index][0].get<double>() + s["hole_size_mm"][index][1].get<double>());
        Comparison k{"table5", "case " + c + " " + layer + ", " + models[m], "hole D", "mm"};
        k.measured = printed[c + "/" + layer + "/test"];
        k.seedModel = printed[c + "/" + layer + "/" + models[m] + "_mpm"];
        k.ours = ours[m];
        if (s.contains("opening_size_mm"))  // where nothing of the layer is left: failed points count as material
          k.note = "opening " + fmt(0.5 * (s["opening_size_mm"][index][0].get<double>() +
                                           s["opening_size_mm"][index][1].get<double>())) + " mm";
        k.target = m == 1 ? "within 30 %" : "";
        k.tolerance = m == 1 ? 0.30 : NAN;
        rows.push_back(k);
        (m ? corr : orig).x.push_back(k.measured);
        (m ? corr : orig).y.push_back(k.ours);
        (m ? corr : orig).tooltips.push_back(k.item);
      }
      const double measured = printed[c + "/" + layer + "/test"];
      ++pairs;
      closer += std::abs(ours[1] - measured) < std::abs(ours[0] - measured);
    }
  }
  comparisonTable(rows, true);
  md_ << "\nCorrected model closer to the test than the original in " << closer << " of " << pairs << " holes.\n";
  parityFigure("table5_holes.svg", "Seed 000 Table 5: hole diameters", "hole D (mm)", {orig, corr});
  sections_["table5"] = {{"comparisons", toJson(rows)}, {"corrected_closer", closer}, {"holes", pairs}};
}

// seed 000 Tables 6 and 7: critical diameters (the seed's own simulations; no test goes there). The seed's d_c
// is the mean of its d_Ymin and d_Nmax rows.

void Report::criticalDiameters(const CriticalDiameterCase& c) {
  const auto t = csv::Table::read(dataFile(c.table));
  md_ << "\n## " << c.heading << "\n\nBisection on the diameter from [" << fmt(c.lower * 1e3) << ", "
      << fmt(c.upper * 1e3) << "] mm to \u00b1" << fmt(c.tolerance * 1e3) << " mm; the seed's d_c is the mean of its "
      << "d_Ymin and d_Nmax.\n";
  const std::string scenario = "scenarios/fabric_al_corrected.toml";
  const double normalEnd = loadScenario(dataFile(scenario)).run.maxTime;
  std::vector<Comparison> rows;
  std::vector<svg::Series> series;
  for (double angle : c.anglesDeg) {
    svg::Series seed, ours;
    seed.label = "seed 000, " + fmt(angle) + " deg";
    seed.style = svg::Style::line;
    ours.label = "ours, " + fmt(angle) + " deg";
    seed.colour = ours.colour = svg::paletteColour(series.size() / 2);
    for (double vKms : c.velocitiesKmS) {
      double sum = 0;
      int n = 0;
      for (std::size_t r = 0; r < t.rowCount(); ++r)
        if (std::abs(t.number(r, t.column("velocity_km_s")) - vKms) < 1e-9 &&
            std::abs(t.number(r, t.column("angle_deg")) - angle) < 1e-9)
          sum += t.number(r, t.column("diameter_mm")), ++n;
      std::vector<std::string> s = c.settings;
      s.push_back("projectile.velocity=" + fmt(vKms, "%.6g") + "km/s");
      if (angle != 0) {
        s.push_back("projectile.angle=" + fmt(angle) + "deg");
        // The scenario's end time is for normal impact. Oblique, the debris crosses the stack at V cos(theta)
        // over a path 1/cos(theta) longer: 1/cos^2 the time. A run that settles earlier (its rearward kinetic
        // energy spent, verdict.hpp) stops there.
        const double cosine = std::cos(angle * M_PI / 180);
        s.push_back("run.max_time=" + fmt(normalEnd / (cosine * cosine) * 1e6, "%.6g") + "us");
      }
      const std::string item = fmt(vKms) + " km/s, " + fmt(angle) + " deg";
      const Limit l = ballisticLimit(log_, scenario, s, BisectVariable::diameter, c.lower,
                                     c.upper, c.tolerance, c.section + " at " + item);
      Comparison k{c.section, item, "d_c", "mm"};
      k.seedModel = n ? sum / n : NAN;
      k.ours = l.estimate() * 1e3;
      k.target = "within 15 %";
      k.tolerance = 0.15;
      k.note = l.result.resolved ? l.bracket("mm", 1e3) : l.result.message;
      rows.push_back(k);
      seed.x.push_back(vKms);
      seed.y.push_back(k.seedModel);
      ours.x.push_back(vKms);
      ours.y.push_back(k.ours);
    }
    series.push_back(seed);
    series.push_back(ours);
  }
  comparisonTable(rows, true);
  svg::Plot p{{}, series, {}};
  p.options.title = c.heading.substr(0, c.heading.find(" ("));
  p.options.xLabel = "Impact velocity V (km/s)";
  p.options.yLabel = "Critical diameter d_c (mm)";
  figure(c.figure, p);
  sections_[c.section] = {{"comparisons", toJson(rows)}, {"settings", c.settings}};
}

void Report::table6() {
  criticalDiameters({"table6", "Seed 000 Table 6: critical diameters at normal impact (target: within 15 % of the seed's simulation)",
                     "seed/seed000_table6_mpm.csv", "table6_critical_diameter.svg", {0.0}, {3.0, 5.0, 7.0, 9.0}, {},
                     0.5e-3, 2.5e-3, o_.quick ? 0.05e-3 : 0.02e-3});
}

void Report::table7() {
  // 3D half models: at the seed's 0.1 mm a run takes 20 to 70 min on 2 cores, so this section runs at 0.2 mm (and
  // says so). The 0.1 mm runs made one at a time are in docs/validation/table7.md.
  criticalDiameters({"table7",
                     "Seed 000 Table 7: critical diameters at 45 and 60 deg (3D half model at 0.2 mm spacing, twice the "
                     "seed's; end time 12 us / cos^2 of the angle; target: within 15 %)",
                     "seed/seed000_table7_mpm.csv", "table7_critical_diameter.svg", {45.0, 60.0}, {3.0, 6.0, 9.0},
                     scaledResolution("scenarios/fabric_al_corrected.toml", 2.0), 0.6e-3, 2.6e-3,
                     o_.quick ? 0.1e-3 : 0.04e-3});
}

// seed 003 Table 6: ballistic limit velocities of the Q235 targets (experiment), Table 7 (the seed's SPH-FEM).
void Report::seed003() {
  const auto exp = csv::Table::read(dataFile("seed/seed003_table6_recht_ipson_experiment.csv"));
  const auto sim = csv::Table::read(dataFile("seed/seed003_table7_recht_ipson_simulation.csv"));
  md_ << "\n## Seed 003 Table 6: ballistic limits of the Q235 targets (target: within 15 %, same order)\n\n"
      << "Bisection on the velocity from [0.5, 1.6] x the measured limit to " << (o_.quick ? "±5" : "±2") << " m/s"
      << (o_.quick ? ", at twice the scenarios' particle spacing (--quick)" : "") << ".\n";
  std::vector<Comparison> rows;
  std::vector<std::pair<double, std::string>> measuredOrder, oursOrder;
  svg::Series pts;
  pts.label = "ours against the experiment";
  for (std::size_t r = 0; r < exp.rowCount(); ++r) {
    const std::string target = exp.text(r, exp.column("target"));
    const double vbl = exp.number(r, exp.column("v_bl_m_s"));
    double seedSim = NAN;
    for (std::size_t q = 0; q < sim.rowCount(); ++q)
      if (sim.text(q, sim.column("target")) == target) seedSim = sim.number(q, sim.column("v_bl_m_s"));
    const std::string scenario = "scenarios/q235_" + target + ".toml";
    const Limit l = ballisticLimit(log_, scenario, coarse(scenario), BisectVariable::velocity, 0.5 * vbl, 1.6 * vbl,
                                   o_.quick ? 5.0 : 2.0, "seed 003 " + target);
    Comparison k{"seed003", target, "v_bl", "m/s"};
    k.measured = vbl;
    k.seedModel = seedSim;
    k.ours = l.estimate();
    k.target = "within 15 %";
    k.tolerance = 0.15;
    k.note = l.result.resolved ? l.bracket("m/s", 1) : l.result.message;
    rows.push_back(k);
    measuredOrder.push_back({vbl, target});
    oursOrder.push_back({std::isfinite(k.ours) ? k.ours : 1e9, target});
    pts.x.push_back(vbl);
    pts.y.push_back(k.ours);
    pts.tooltips.push_back(target);
  }
  comparisonTable(rows, true);
  std::sort(measuredOrder.begin(), measuredOrder.end());
  std::sort(oursOrder.begin(), oursOrder.end());
  std::string mo, oo;
  bool same = true;
  for (std::size_t i = 0; i < measuredOrder.size(); ++i) {
    mo += (i ? " < " : "") + measuredOrder[i].second;
    oo += (i ? " < " : "") + oursOrder[i].second;
    same &= measuredOrder[i].second == oursOrder[i].second;
  }
  md_ << "\nOrder, measured: " << mo << "; ours: " << oo << " (" << (same ? "same" : "**different**") << ").\n";
  parityFigure("seed003_ballistic_limits.svg", "Seed 003: ballistic limit velocities", "v_bl (m/s)", {pts});
  sections_["seed003"] = {{"comparisons", toJson(rows)}, {"same_order", same}};
}

// seed 002: Weldox 460E 10 mm, blunt projectile at 277.5 m/s, measured residual 197.9 m/s. The plug is sheared
// off in a band a few cells wide, so the residual velocity depends on the resolution: the scenario's and half its
// spacing are both run (in --quick twice the scenario's and the scenario's), and the target is judged on the finer,
// as seed 002 judged its own mesh study (ch. 5, Table 1) by its finest mesh.
void Report::weldox() {
  const std::string scenario = "scenarios/weldox_10mm_blunt.toml";
  const ImpactScenario sc = loadScenario(dataFile(scenario));
  // seed 002 Table 1: AUTODYN's residual velocity by element size (m -> m/s), the mesh study of this very shot.
  const std::map<double, double> seedByElement{{0.1e-3, 201.6}, {0.2e-3, 202.2}, {0.25e-3, 206.7},
                                               {0.5e-3, 211.8}, {1.2e-3, 252.6}};
  auto seedAt = [&](double cell) {
    for (const auto& [element, vr] : seedByElement)
      if (std::abs(element - cell) < 1e-9) return vr;
    return double(NAN);
  };
  md_ << "\n## Seed 002: Weldox 460E 10 mm, blunt projectile at 277.5 m/s (target: residual velocity within 10 %)\n\n"
      << "At two resolutions; the seed's model is its AUTODYN run with elements of our cell size "
         "(seed 002 Table 1).\n\n"
      << "| particle spacing (mm) | cell (mm) | perforated | v_r (m/s) | of | seed's model (m/s) | wall time (s) |\n"
      << "|---|---|---|---|---|---|---|\n";
  json runs = json::array();
  Comparison k{"weldox", "10 mm, 277.5 m/s", "v_r", "m/s"};
  k.measured = 197.9;  // seed 002 ch. 5, Table 1 (Borvik's experiment)
  for (double scale : {o_.quick ? 2.0 : 1.0, o_.quick ? 1.0 : 0.5}) {
    const double spacing = scale * sc.resolution.particleSpacing, cell = scale * sc.cellSize();
    const json s = log_.run(scenario, scaledResolution(scenario, scale),
                            "Weldox 460E 10 mm at 277.5 m/s, " + inUnit(spacing, "mm") + " mm");
    const bool perforated = s["perforated"].get<bool>();
    const double vr = perforated ? s["residual_velocity_m_s"].get<double>() : 0.0;
    const std::string of = s["residual_velocity_of"].get<std::string>();
    md_ << "| " << inUnit(spacing, "mm") << " | " << inUnit(cell, "mm") << " | " << (perforated ? "yes" : "no") << " | "
        << fmt(vr, "%.1f") << " | " << of << " | " << fmt(seedAt(cell), "%.1f") << " | "
        << fmt(s["wall_time_s"].get<double>(), "%.0f") << " |\n";
    runs.push_back({{"particle_spacing_mm", units::toUnit(spacing, "mm")}, {"cell_size_mm", units::toUnit(cell, "mm")},
                    {"perforated", perforated}, {"residual_velocity_m_s", vr}, {"residual_velocity_of", of},
                    {"seed_model_m_s", std::isfinite(seedAt(cell)) ? json(seedAt(cell)) : json(nullptr)}});
    // The finer run (the loop's last) is the one judged.
    k.seedModel = seedAt(cell);
    k.ours = vr;
    k.note = of + ", " + inUnit(spacing, "mm") + " mm particles, " + inUnit(cell, "mm") + " mm cells";
  }
  k.target = "within 10 %";
  k.tolerance = 0.10;
  comparisonTable({k}, true);
  sections_["weldox"] = {{"comparisons", json::array({k.toJson()})}, {"runs", runs}};
}

// seed 001 Table 3: punch-hole diameters of the first bumper.
void Report::seed001() {
  const auto t = csv::Table::read(dataFile("seed/seed001_table3_holes.csv"));
  md_ << "\n## Seed 001 Table 3: first-bumper hole diameters (target: within 15 %)\n";
  std::vector<Comparison> rows;
  std::map<double, double> simulated;
  for (std::size_t r = 0; r < t.rowCount(); ++r)
    if (t.text(r, t.column("layer")) == "first_bumper" && t.text(r, t.column("method")) == "mpm")
      simulated[t.number(r, t.column("impact_velocity_m_s"))] = t.number(r, t.column("hole_diameter_mm"));
  const std::string scenario = "scenarios/whipple_first_bumper.toml";
  svg::Series pts;
  pts.label = "ours against the experiment";
  for (std::size_t r = 0; r < t.rowCount(); ++r) {
    if (t.text(r, t.column("layer")) != "first_bumper" || t.text(r, t.column("method")) != "experiment") continue;
    const double v = t.number(r, t.column("impact_velocity_m_s"));
    std::vector<std::string> s = coarse(scenario);
    s.push_back("projectile.velocity=" + fmt(v, "%.6g") + "m/s");
    const json run = log_.run(scenario, s, "seed 001 first bumper at " + fmt(v, "%.6g") + " m/s");
    Comparison k{"seed001", fmt(v, "%.6g") + " m/s", "hole D", "mm"};
    k.measured = t.number(r, t.column("hole_diameter_mm"));
    k.seedModel = simulated[v];
    k.ours = 0.5 * (run["hole_size_mm"][0][0].get<double>() + run["hole_size_mm"][0][1].get<double>());
    k.target = "within 15 %";
    k.tolerance = 0.15;
    rows.push_back(k);
    pts.x.push_back(k.measured);
    pts.y.push_back(k.ours);
  }
  comparisonTable(rows, true);
  parityFigure("seed001_holes.svg", "Seed 001 Table 3: first-bumper holes", "hole D (mm)", {pts});
  sections_["seed001"] = {{"comparisons", toJson(rows)}};
}

// The same quantities at the seed's resolution and at half its spacing.
void Report::convergence() {
  md_ << "\n## Convergence: seed 000 Table 5 cases at 0.1 mm (the seed's) and 0.05 mm particle spacing\n\n"
      << "| case | model | spacing (mm) | perforated | outer hole (mm) | plate hole (mm) | wall time (s) |\n"
      << "|---|---|---|---|---|---|---|\n";
  json rows = json::array();
  const std::vector<std::pair<std::string, std::pair<double, double>>> cases{{"03", {1.4e-3, 3020}}, {"05", {1.2e-3, 4030}}};
  for (const auto& [id, dv] : cases) {
    if (o_.quick && id == "03") continue;
    for (const char* model : {"original", "corrected"})
      for (double scale : {1.0, 0.5}) {
        const std::string scenario = std::string("scenarios/fabric_al_") + model + ".toml";
        const double h = units::toUnit(scale * loadScenario(dataFile(scenario)).resolution.particleSpacing, "mm");
        std::vector<std::string> s = shot(dv.first, dv.second);
        for (const std::string& setting : scaledResolution(scenario, scale)) s.push_back(setting);
        const json r = log_.run(scenario, s,
                                "convergence case " + id + " " + model + " at " + fmt(h) + " mm");
        md_ << "| " << id << " | " << model << " | " << fmt(h) << " | " << (r["perforated"].get<bool>() ? "yes" : "no")
            << " | " << fmt(r["hole_size_mm"][0][0].get<double>()) << " | " << fmt(r["hole_size_mm"][3][0].get<double>())
            << " | " << fmt(r["wall_time_s"].get<double>(), "%.1f") << " |\n";
        rows.push_back({{"case", id}, {"model", model}, {"spacing_mm", h}, {"perforated", r["perforated"]},
                        {"outer_hole_mm", r["hole_size_mm"][0][0]}, {"plate_hole_mm", r["hole_size_mm"][3][0]}});
      }
  }
  sections_["convergence"] = {{"runs", rows}};
}

void Report::write(double seconds) {
  int met = 0, targets = 0;
  for (const auto& c : all_)
    if (std::isfinite(c.tolerance)) ++targets, met += c.met();
  std::ofstream out(fs::path(o_.out) / "validation.md");
  out << "# blt validation report\n\nblt " << BLT_VERSION << ", model " << modelFingerprint()
      << (o_.quick ? ", --quick" : "") << "; " << log_.made()
      << " runs made, " << log_.reused() << " reused from runs.jsonl; " << fmt(seconds, "%.0f") << " s.\n"
      << "Numeric targets met: " << met << " of " << targets << ". Errors are against the measurement where there is "
      << "one, else against the seed's simulation.\n"
      << md_.str();
  json doc{{"tool_version", BLT_VERSION},  {"model_fingerprint", modelFingerprint()},
           {"quick", o_.quick},           {"runs_made", log_.made()},
           {"runs_reused", log_.reused()}, {"wall_time_s", seconds}, {"targets", targets}, {"targets_met", met},
           {"sections", sections_}};
  std::ofstream(fs::path(o_.out) / "validation.json") << doc.dump(2) << "\n";
  if (o_.json) printJson(doc);
  else
    std::printf("validation report: %s/validation.md (%d of %d numeric targets met; %zu runs made, %zu reused)\n",
                o_.out.c_str(), met, targets, log_.made(), log_.reused());
}

void runValidate(const ValidateOptions& o) {
  for (const auto& s : o.only)
    if (std::find(kSections.begin(), kSections.end(), s) == kSections.end()) {
      std::string allowed;
      for (const auto& k : kSections) allowed += (allowed.empty() ? "" : ", ") + k;
      throw InputError(InputLocation::flag("--only"), "no section '" + s + "'", allowed);
    }
  std::error_code ec;
  fs::create_directories(o.out, ec);
  if (ec) throw InputError(InputLocation::flag("--out"), "cannot create the folder " + o.out + ": " + ec.message());
  const auto start = std::chrono::steady_clock::now();
  Report report(o);
  if (report.wanted("table1")) report.table1();
  if (report.wanted("table5")) report.table5();
  if (report.wanted("table6")) report.table6();
  // The oblique 3D runs are the costly part: only when asked for by name.
  if (!o.only.empty() && report.wanted("table7")) report.table7();
  // The Q235 bisections are the longest of the default sections (minutes a run): last.
  if (report.wanted("weldox")) report.weldox();
  if (report.wanted("seed001")) report.seed001();
  if (report.wanted("convergence")) report.convergence();
  if (report.wanted("seed003")) report.seed003();
  report.write(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
}

}  // namespace

void registerValidateCommand(CLI::App& app) {
  auto o = std::make_shared<ValidateOptions>();
  auto* cmd = app.add_subcommand(
      "validate",
      "Run the seed validation cases and write a report (Markdown + SVG + JSON): seed 000 Tables 1, 5, 6, 7, seed 003 "
      "Table 6, seed 002 Weldox, seed 001 Table 3, convergence. Runs are kept in OUT/runs.jsonl and reused when "
      "started again.");
  cmd->add_option("--out", o->out, "Report folder (validation.md, *.svg, validation.json, runs.jsonl)")
      ->capture_default_str();
  cmd->add_flag("--quick", o->quick,
                "Looser bisection tolerances and twice the particle spacing for the costly scenarios (minutes)");
  cmd->add_option("--only", o->only,
                  "Sections to run (default: all but table7, whose 3D oblique bisections take hours): table1, table5, "
                  "table6, table7, seed003, weldox, seed001, convergence")
      ->delimiter(',');
  cmd->add_option("--threads", o->threads, "OpenMP threads per run (default: all cores)");
  cmd->add_option("--alignments", o->alignments,
                  "Table 1 also at N alignments of grid and particles (grid offsets k/N of a cell): how many of its "
                  "verdicts are the discretisation's (default 1: not run)")
      ->check(CLI::Range(1, 64));
  addJsonFlag(*cmd, o->json);
  cmd->callback([o] { runValidate(*o); });
}

}  // namespace blt::cli
