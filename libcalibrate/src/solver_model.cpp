#include "blt/calibrate/solver_model.hpp"

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <numbers>
#include <sstream>
#include <thread>

#include <unistd.h>

#include "blt/campaign/database.hpp"
#include "blt/core/error.hpp"
#include "blt/core/units.hpp"
#include "blt/sim/impact.hpp"

namespace blt::calibrate {

namespace {

// A setting's value with its unit, exact enough to be a cache key and to round-trip.
std::string value(double si, const char* unit, double factor) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.9g%s", si * factor, unit);
  return buf;
}

std::string fileContents(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// A scenario as the run cache and the case lookup name it: its absolute, normalised path.
std::string scenarioLabel(const std::string& path) { return std::filesystem::absolute(path).lexically_normal().string(); }

}  // namespace

SolverModel::Target SolverModel::loadTarget(const std::string& path) const {
  Target t;
  t.path = path;
  t.base = sim::loadScenario(path, options_.settings);
  // The text is part of the cache key: an edited scenario must not reuse old runs.
  t.label = scenarioLabel(path);
  t.text = fileContents(path);
  for (std::size_t k = 0; k < t.base.target.layers.size(); ++k)
    if (strengthModelOf(t, k) == "bilinear") t.rateHardened.push_back(k);
  return t;
}

std::vector<std::string> scenariosNamedBy(const MeasuredData& data) {
  std::vector<std::string> paths;
  for (const MeasuredCase& c : data.cases)
    if (!c.scenario.empty() && std::find(paths.begin(), paths.end(), c.scenario) == paths.end())
      paths.push_back(c.scenario);
  return paths;
}

SolverModel::SolverModel(const std::string& scenarioPath, SolverModelOptions options,
                         const std::vector<std::string>& otherScenarios)
    : options_(std::move(options)) {
  if (options_.alignments < 1 || (options_.alignments > 1 && options_.outcomeMargin))
    throw InputError(InputLocation::flag("--alignments"),
                     std::to_string(options_.alignments) + " alignments" + (options_.outcomeMargin ? " with --outcome-margin" : ""),
                     "1 or more; above 1 the outcome is the perforating share, so without --outcome-margin");
  hasDefault_ = !scenarioPath.empty();
  if (hasDefault_) targets_.push_back(loadTarget(scenarioPath));
  for (const std::string& path : otherScenarios) {
    if (!findTarget(path)) targets_.push_back(loadTarget(path));
  }
  if (targets_.empty())
    throw InputError(InputLocation::flag("--scenario"), "no scenario to run the shots on",
                     "--scenario FILE, or a scenario column in the measured data");
  const Target& first = targets_.front();
  const auto layerNames = [](const Target& t) {
    std::vector<std::string> names;
    for (const auto& layer : t.base.target.layers) names.push_back(layer.name);
    return names;
  };
  const std::vector<std::string> firstNames = layerNames(first);
  const bool sameLayers = std::all_of(targets_.begin(), targets_.end(),
                                      [&](const Target& t) { return layerNames(t) == firstNames; });
  const std::size_t layers = first.base.target.layers.size();
  constexpr double mm = 1e-3, deg = std::numbers::pi / 180;
  if (sameLayers) {
    if (layers >= 3)
      effects_.push_back({"interlayer_gaps",
                          "a gap g between every two layers in front of the rear wall (gap_before += g for layers 2 to " +
                              std::to_string(layers - 1) + ")",
                          {"g", "mm", "gap_m", 0.0, 3 * mm, 0.0}});
    for (std::size_t k = 1; k < layers; ++k) {
      const std::string& name = first.base.target.layers[k].name;
      effects_.push_back({"gap:" + name, "a gap g in front of layer " + name + " (gap_before += g)",
                          {"g", "mm", "gap_m", 0.0, 3 * mm, 0.0}});
    }
    for (const auto& layer : first.base.target.layers)
      effects_.push_back({"thickness:" + layer.name,
                          "layer " + layer.name + "'s thickness (or areal density) is f times the scenario's",
                          {"f", "", "thickness_factor", 0.5, 1.5, 1.0}});
    for (const auto& layer : first.base.target.layers)
      effects_.push_back({"strength:" + layer.name,
                          "layer " + layer.name + "'s material has s times the flow stress of " + layer.material,
                          {"s", "", "strength_factor", 0.5, 2.0, 1.0}});
  }
  // A material's strength as one effect: the same card in every layer made of it.
  std::vector<std::pair<std::string, int>> materialUses;
  for (const Target& t : targets_)
    for (std::size_t k = 0; k < t.base.target.layers.size(); ++k) {
      if (strengthModelOf(t, k).empty()) continue;
      const std::string& material = t.base.target.layers[k].material;
      auto it = std::find_if(materialUses.begin(), materialUses.end(), [&](const auto& u) { return u.first == material; });
      if (it == materialUses.end()) materialUses.emplace_back(material, 1);
      else ++it->second;
    }
  for (const auto& [material, uses] : materialUses)
    if (uses > 1 || targets_.size() > 1)
      effects_.push_back({"material_strength:" + material,
                          "every layer made of " + material + " has s times its flow stress" +
                              (targets_.size() > 1 ? ", in every scenario" : ""),
                          {"s", "", "strength_factor", 0.5, 2.0, 1.0}});
  std::vector<std::string> fabricNames;
  for (const Target& t : targets_)
    for (std::size_t k : t.rateHardened)
      if (std::find(fabricNames.begin(), fabricNames.end(), t.base.target.layers[k].name) == fabricNames.end())
        fabricNames.push_back(t.base.target.layers[k].name);
  std::string fabrics;
  for (const std::string& name : fabricNames) fabrics += (fabrics.empty() ? "" : ", ") + name;
  if (!fabrics.empty())
    effects_.push_back({"rate_hardening",
                        "the fabric layers (" + fabrics + ") harden with strain rate: flow stress x (1 + C ln max(rate / " +
                            value(kFabricReferenceRate, " 1/s", 1.0) + ", 1)), Johnson-Cook's rate term",
                        {"C", "", "rate_coefficient", 0.0, 0.15, 0.0}});
  if (!failureKeys(projectileMaterial(first)).empty())
    effects_.push_back({"fragmentation",
                        "the projectile breaks up at f times the failure threshold of " + first.base.projectile.material +
                            " (f < 1: it fragments more easily)",
                        {"f", "", "failure_factor", 0.25, 2.0, 1.0}});
  if (options_.cardDirectory.empty())
    options_.cardDirectory = options_.database.empty()
                                 ? (std::filesystem::temp_directory_path() / "blt_calibrate_cards").string()
                                 : (std::filesystem::path(options_.database).parent_path() / "cards").string();
  effects_.push_back({"obliquity", "every shot is delta degrees more oblique than recorded (3D runs)",
                      {"delta", "deg", "angle_error_rad", 0.0, 15 * deg, 0.0}});
  if (std::all_of(targets_.begin(), targets_.end(),
                  [](const Target& t) { return t.base.projectile.shape == sim::ProjectileShape::cylinder; }))
    effects_.push_back({"yaw",
                        "every shot has psi degrees more yaw than recorded: the projectile's axis turned off its flight "
                        "path, in the plane of incidence (3D runs)",
                        {"psi", "deg", "yaw_rad", 0.0, 10 * deg, 0.0}});
  if (!options_.simulator) options_.simulator = campaign::impactSimulator(options_.threads);
  runs_ = std::make_unique<campaign::RunDatabase>(options_.database.empty() ? ":memory:" : options_.database);
  if (!options_.importCache.empty() && std::filesystem::is_regular_file(options_.importCache))
    importRunCache(options_.importCache);
  loadReusableRuns(*runs_);
  if (!options_.reuseDatabase.empty()) {
    if (!std::filesystem::is_regular_file(options_.reuseDatabase))
      throw InputError(InputLocation::flag("--reuse-runs"), "no run database " + options_.reuseDatabase,
                       "a campaign's SQLite file (blt campaign run --db FILE)");
    loadReusableRuns(campaign::RunDatabase(options_.reuseDatabase));
  }
}

void SolverModel::importRunCache(const std::string& path) {
  const std::string imported = "imported from " + path;
  for (const auto& [key, summary] : sim::RunCache(path).runs()) {
    if (runs_->findCalibrationRun(key)) continue;
    campaign::CalibrationRunRecord r;
    r.key = key;
    r.summary = summary;
    r.wallSeconds = summary.value("wall_time_s", 0.0);
    // The cache kept only the key and the summary; the key names the scenario, the model and the settings.
    r.toolVersion = imported;
    runs_->recordCalibrationRun(r);
    ++runsImported_;
  }
}

bool turnsRunsThreeD(const std::string& effect) { return effect == "obliquity" || effect == "yaw"; }

std::string SolverModel::describe() const {
  std::string s = targets_.size() == 1 ? "scenario " : "scenarios ";
  for (std::size_t i = 0; i < targets_.size(); ++i) s += (i ? ", " : "") + targets_[i].path;
  for (const auto& kv : options_.settings) s += " --set " + kv;
  if (options_.alignments > 1) s += ", each prediction the mean of " + std::to_string(options_.alignments) + " grid alignments";
  return s;
}

const SolverModel::Target* SolverModel::findTarget(const std::string& scenario) const {
  const std::string label = scenarioLabel(scenario);
  for (const Target& t : targets_)
    if (t.label == label) return &t;
  return nullptr;
}

const SolverModel::Target& SolverModel::targetOf(const MeasuredCase& c) const {
  if (c.scenario.empty()) {
    if (!hasDefault_) throw std::logic_error("case " + c.id + " has no scenario (SolverModel::check lets none through)");
    return targets_.front();
  }
  if (const Target* t = findTarget(c.scenario)) return *t;
  throw std::logic_error("case " + c.id + "'s scenario " + c.scenario + " was not given to the SolverModel");
}

MeasuredCase SolverModel::withDiameter(const MeasuredCase& c) const {
  MeasuredCase out = c;
  if (!(out.diameter > 0)) out.diameter = targetOf(c).base.projectile.diameter;
  return out;
}

std::size_t SolverModel::layerIndex(const Target& t, const std::string& label) {
  const auto& layers = t.base.target.layers;
  for (std::size_t k = 0; k < layers.size(); ++k)
    if (layers[k].name == label) return k;
  if (!label.empty() && label.find_first_not_of("0123456789") == std::string::npos) {
    const std::size_t k = std::stoul(label);
    if (k >= 1 && k <= layers.size()) return k - 1;
  }
  return std::string::npos;
}

void SolverModel::check(const MeasuredData& data) const {
  if (!data.hasDiameters && !data.hasScenarios)
    throw InputError(InputLocation::file(data.source, std::nullopt, "diameter_mm"), "the solver model needs each shot's diameter",
                     "a diameter_mm column (or a scenario column, whose scenarios give the diameter)");
  for (const MeasuredCase& c : data.cases) {
    if (c.scenario.empty() && !hasDefault_)
      throw InputError(InputLocation::file(data.source, c.line, "scenario"),
                       "case '" + c.id + "' names no scenario and no --scenario was given",
                       "a scenario file in the scenario column, or --scenario FILE for such cases");
    if (c.scenario.empty()) continue;
    if (!findTarget(c.scenario))
      throw InputError(InputLocation::file(data.source, c.line, "scenario"),
                       "case '" + c.id + "'s scenario " + c.scenario + " is not one the model was given",
                       "the scenarios of scenariosNamedBy(data)");
  }
  for (const Observation& o : data.observations) {
    if (o.layer.empty()) continue;
    const Target& t = targetOf(data.cases.at(o.caseIndex));
    if (layerIndex(t, o.layer) != std::string::npos) continue;
    std::string names;
    for (const auto& l : t.base.target.layers) names += (names.empty() ? "" : ", ") + l.name;
    throw InputError(InputLocation::file(data.source, o.line, "layer"), "'" + o.layer + "' is not a layer of " + t.path,
                     "a layer name (" + names + ") or a number 1 to " + std::to_string(t.base.target.layers.size()));
  }
}

std::vector<std::string> SolverModel::settingsFor(const MeasuredCase& measured, const EffectSetting& setting) const {
  const MeasuredCase c = withDiameter(measured);
  const Target& t = targetOf(c);
  std::vector<std::string> s = options_.settings;
  double angle = c.angle;
  s.push_back("projectile.diameter=" + value(c.diameter, "mm", 1e3));
  s.push_back("projectile.velocity=" + value(c.velocity, "m/s", 1.0));
  if (const Effect* e = setting.effect) {
    const auto& layers = t.base.target.layers;
    const auto material = [&](std::size_t k, const std::string& card) {
      s.push_back("target.layer." + std::to_string(k + 1) + ".material=" + card);
    };
    const auto gap = [&](std::size_t k) {
      s.push_back("target.layer." + std::to_string(k + 1) + ".gap_before=" +
                  value(layers[k].gapBefore + setting.value, "mm", 1e3));
    };
    const auto afterPrefix = [&](std::size_t prefix) { return e->name.substr(prefix); };
    if (e->name == "interlayer_gaps") {
      for (std::size_t k = 1; k + 1 < layers.size(); ++k) gap(k);
    } else if (e->name.rfind("gap:", 0) == 0) {
      gap(layerIndex(t, afterPrefix(4)));
    } else if (e->name.rfind("thickness:", 0) == 0) {
      const std::size_t k = layerIndex(t, afterPrefix(10));
      s.push_back("target.layer." + std::to_string(k + 1) + ".thickness=" + value(layers[k].thickness * setting.value, "mm", 1e3));
    } else if (e->name.rfind("strength:", 0) == 0) {
      const std::size_t k = layerIndex(t, afterPrefix(9));
      material(k, strengthCard(t, layers[k].material, "target.layer." + layers[k].name + ".material", setting.value));
    } else if (e->name.rfind("material_strength:", 0) == 0) {
      const std::string id = afterPrefix(18);
      for (std::size_t k = 0; k < layers.size(); ++k)
        if (layers[k].material == id)
          material(k, strengthCard(t, id, "target.layer." + layers[k].name + ".material", setting.value));
    } else if (e->name == "rate_hardening") {
      for (std::size_t k : t.rateHardened) material(k, rateHardenedCard(t, k, setting.value));
    } else if (e->name == "fragmentation") {
      s.push_back("projectile.material=" + fragmentationCard(t, setting.value));
    } else if (e->name == "obliquity") {
      angle += setting.value;
    } else if (e->name == "yaw") {
      s.push_back("projectile.yaw=" + value(t.base.projectile.yaw + setting.value, "deg", 180 / std::numbers::pi));
    }
  }
  s.push_back("projectile.angle=" + value(angle, "deg", 180 / std::numbers::pi));
  return s;
}

Material SolverModel::projectileMaterial(const Target& t) const {
  return sim::resolveMaterial(t.base.projectile.material, InputLocation::file(t.path, std::nullopt, "projectile.material"));
}

Material SolverModel::layerMaterial(const Target& t, std::size_t k) const {
  const auto& layer = t.base.target.layers[k];
  return sim::resolveMaterial(layer.material,
                              InputLocation::file(t.path, std::nullopt, "target.layer." + layer.name + ".material"));
}

std::string SolverModel::strengthModelOf(const Target& t, std::size_t k) const {
  const Material m = layerMaterial(t, k);
  return m.has("strength") ? m.sections.at("strength").model : "";
}

// The projectile card's failure thresholds that `fragmentation` scales (Johnson-Cook's D1 and D2 scale its
// failure strain at every stress state).
std::vector<std::string> SolverModel::failureKeys(const Material& m) {
  std::vector<std::string> keys;
  if (!m.has("failure")) return keys;
  for (const char* key : {"max_principal_stress", "max_principal_strain", "D1", "D2"})
    if (m.sections.at("failure").params.count(key)) keys.push_back(key);
  return keys;
}

std::string SolverModel::writeDerivedCard(Material m, const std::string& material, const std::string& change,
                                          double amount) const {
  m.notes += " Derived by blt calibrate: " + change + " " + value(amount, "", 1.0) + ".";
  std::filesystem::create_directories(options_.cardDirectory);
  const auto fileNamePart = [](std::string text) {
    for (char& c : text)
      if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
    return text;
  };
  const std::string card = (std::filesystem::path(options_.cardDirectory) /
                            (fileNamePart(material) + "_" + fileNamePart(change) + value(amount, "", 1.0) + ".toml"))
                               .string();
  // Written whole under a name of its own, then renamed: another run (of this calibration's jobs, or of another
  // task sharing the card directory) may be reading the card while it is written again, and must see the old
  // text or the new one (the same), never a truncated file.
  const std::string part = card + ".part." + std::to_string(::getpid()) + "." +
                           std::to_string(std::hash<std::thread::id>{}(std::this_thread::get_id()));
  {
    std::ofstream out(part);
    out << materialToToml(m);
    out.close();
    if (!out) {
      std::error_code ignored;
      std::filesystem::remove(part, ignored);
      throw InputError(InputLocation::file(card), "cannot write the derived material card", "a writable card directory");
    }
  }
  std::error_code renamed;
  std::filesystem::rename(part, card, renamed);
  if (renamed) {
    std::error_code ignored;
    std::filesystem::remove(part, ignored);
    throw InputError(InputLocation::file(card), "cannot put the derived material card in place: " + renamed.message(),
                     "a writable card directory");
  }
  return card;
}

std::string SolverModel::strengthCard(const Target& t, const std::string& material, const std::string& where,
                                      double factor) const {
  Material m = sim::resolveMaterial(material, InputLocation::file(t.path, std::nullopt, where));
  if (!m.has("strength"))
    throw InputError(InputLocation::file(t.path, std::nullopt, where),
                     "material " + material + " has no [strength] section to scale", "a layer with a strength model");
  // The stresses of the flow curve; rate and temperature terms are ratios and stay.
  int scaled = 0;
  for (const char* key : {"A", "B", "yield_stress", "tangent_modulus"}) {
    auto& params = m.sections["strength"].params;
    if (auto it = params.find(key); it != params.end()) it->second *= factor, ++scaled;
  }
  if (scaled == 0)
    throw InputError(InputLocation::file(m.path, std::nullopt, "strength"),
                     "the strength model of " + material + " has none of A, B, yield_stress, tangent_modulus",
                     "a Johnson-Cook or bilinear strength model");
  return writeDerivedCard(m, material, "strength x", factor);
}

std::string SolverModel::rateHardenedCard(const Target& t, std::size_t k, double coefficient) const {
  Material m = layerMaterial(t, k);
  auto& params = m.sections["strength"].params;
  params["C"] = coefficient;
  params["reference_strain_rate"] = kFabricReferenceRate;
  return writeDerivedCard(m, t.base.target.layers[k].material, "rate C", coefficient);
}

std::string SolverModel::fragmentationCard(const Target& t, double factor) const {
  Material m = projectileMaterial(t);
  for (const std::string& key : failureKeys(m)) m.sections["failure"].params[key] *= factor;
  return writeDerivedCard(m, t.base.projectile.material, "failure x", factor);
}

namespace {

// The fields of a run's summary the cache keeps and the predictions read.
nlohmann::json keptFields(const nlohmann::json& summary) {
  return {{"perforated", summary.at("perforated")},
          {"residual_velocity_m_s", summary.at("residual_velocity_m_s")},
          {"layers", summary.at("layers")},
          {"hole_size_mm", summary.at("hole_size_mm")},
          {"status", summary.at("status")},
          {"wall_time_s", summary.at("wall_time_s")}};
}

bool sameValue(double a, double b) { return std::abs(a - b) <= 1e-8 * std::max(std::abs(a), std::abs(b)) + 1e-15; }

}  // namespace

void SolverModel::loadReusableRuns(const campaign::RunDatabase& db) {
  const std::string fingerprint = "+model." + sim::modelFingerprint();
  for (const campaign::CampaignRecord& c : db.campaigns()) {
    const std::string hash = c.definition.value("scenario_hash", std::string());
    const auto target = std::find_if(targets_.begin(), targets_.end(),
                                     [&](const Target& t) { return sim::scenarioHash(t.text, {}) == hash; });
    if (target == targets_.end()) continue;
    std::vector<std::string> settings = c.definition.value("settings", std::vector<std::string>());
    std::sort(settings.begin(), settings.end());
    for (const campaign::RunRecord& r : db.runs(c.id)) {
      const bool sameBuild = r.toolVersion.size() >= fingerprint.size() &&
                             r.toolVersion.compare(r.toolVersion.size() - fingerprint.size(), fingerprint.size(), fingerprint) == 0;
      if (r.state != campaign::RunState::completed || r.attempt != 0 || !sameBuild) continue;
      try {
        reusable_.push_back({&*target, settings, r.diameter, r.velocity, r.angle, keptFields(r.measurements)});
      } catch (const nlohmann::json::exception&) {
        // A run recorded without the fields a prediction needs cannot serve one.
      }
    }
  }
}

std::optional<nlohmann::json> SolverModel::reusedRun(const Target& t, const std::vector<std::string>& settings) const {
  if (reusable_.empty()) return std::nullopt;
  double d = NAN, v = NAN, angle = NAN;
  std::vector<std::string> rest;
  for (const std::string& kv : settings) {
    const auto eq = kv.find('=');
    const std::string key = kv.substr(0, eq), text = kv.substr(eq + 1);
    double* shot = key == "projectile.diameter" ? &d : key == "projectile.velocity" ? &v : key == "projectile.angle" ? &angle : nullptr;
    if (shot) *shot = units::parseQuantity(text).si;
    else rest.push_back(kv);
  }
  std::sort(rest.begin(), rest.end());
  for (const ReusableRun& r : reusable_)
    if (r.target == &t && r.settings == rest && sameValue(r.diameter, d) && sameValue(r.velocity, v) &&
        sameValue(r.angle, angle))
      return r.summary;
  return std::nullopt;
}

std::string SolverModel::portableKey(const Target& t, const std::vector<std::string>& settings) const {
  namespace fs = std::filesystem;
  const fs::path cards = fs::absolute(options_.cardDirectory).lexically_normal();
  std::vector<std::string> portable;
  for (const std::string& kv : settings) {
    const auto eq = kv.find('=');
    bool derivedCard = false;
    fs::path card;
    if (eq != std::string::npos && kv.substr(0, eq).ends_with(".material")) {
      card = fs::absolute(kv.substr(eq + 1)).lexically_normal();
      derivedCard = card.parent_path() == cards;
    }
    portable.push_back(derivedCard ? kv.substr(0, eq + 1) + "derived-card:" + card.filename().string() : kv);
  }
  return sim::RunCache::key(fs::path(t.path).filename().string(), t.text, portable);
}

std::string SolverModel::legacyKey(const Target& t, const std::vector<std::string>& settings) const {
  return sim::RunCache::key(t.label, t.text, settings);
}

nlohmann::json SolverModel::runOrRecall(const Target& t, const std::vector<std::string>& settings) {
  const std::string key = portableKey(t, settings);
  std::optional<campaign::CalibrationRunRecord> found = runs_->findCalibrationRun(key);
  if (!found) found = runs_->findCalibrationRun(legacyKey(t, settings));
  // A run without a summary crashed (or its output was lost): made again. One that went unstable has one.
  if (found && found->summary.contains("perforated")) return found->summary;
  const auto logRun = [&](const nlohmann::json& kept, const std::string& how) {
    if (!options_.log) return;
    std::string line = std::string(kept["perforated"].get<bool>() ? "perforated" : "stopped") + how;
    for (const auto& kv : settings) line += " " + kv;
    options_.log(line);
  };
  campaign::CalibrationRunRecord record;
  record.key = key;
  record.scenario = t.path;
  record.settings = settings;
  record.scenarioHash = sim::scenarioHash(t.text, settings);
  if (auto reused = reusedRun(t, settings)) {
    record.summary = *reused;
    record.wallSeconds = reused->value("wall_time_s", 0.0);
    record.toolVersion = sim::buildVersion();
    runs_->recordCalibrationRun(record);
    std::lock_guard lock(mutex_);
    ++runsReused_;
    logRun(*reused, " (campaign run)");
    return *reused;
  }
  const campaign::SimulationOutcome outcome = options_.simulator(sim::loadScenario(t.path, settings));
  const bool summarised = outcome.measurements.is_object() && outcome.measurements.contains("perforated");
  record.state = outcome.failed ? campaign::RunState::failed : campaign::RunState::completed;
  record.reason = outcome.reason;
  if (summarised) record.summary = keptFields(outcome.measurements);
  record.wallSeconds = outcome.wallSeconds;
  record.toolVersion = sim::buildVersion();
  runs_->recordCalibrationRun(record);
  std::lock_guard lock(mutex_);
  ++runsMade_;
  if (!summarised) {
    std::string shot;
    for (const auto& kv : settings) shot += " --set " + kv;
    throw std::runtime_error("the run of " + t.path + shot + " failed: " + outcome.reason +
                             " (recorded as failed in the run database; calibrating again makes it again)");
  }
  logRun(record.summary, outcome.failed ? " (" + outcome.reason + ")" : "");
  return record.summary;
}

double SolverModel::margin(const MeasuredCase& measured, const EffectSetting& setting, bool perforatedAtMeasured) {
  // Geometric steps away from the measured diameter until the verdict turns, then bisection in ln d.
  const MeasuredCase c = withDiameter(measured);
  const Target& t = targetOf(c);
  const auto perforates = [&](double d) {
    MeasuredCase probe = c;
    probe.diameter = d;
    return runOrRecall(t, settingsFor(probe, setting))["perforated"].get<bool>();
  };
  double near = c.diameter, far = c.diameter;
  const double step = perforatedAtMeasured ? 1.0 / 1.25 : 1.25;
  bool turned = false;
  for (int k = 0; k < options_.marginSteps && !turned; ++k) {
    near = far;
    far *= step;
    turned = perforates(far) != perforatedAtMeasured;
  }
  // Not turned within the search: the margin is at least the distance searched.
  if (!turned) return std::log(c.diameter / far);
  double perforating = perforatedAtMeasured ? near : far, safe = perforatedAtMeasured ? far : near;
  while (perforating / safe > 1.0 + options_.marginTolerance) {
    const double mid = std::sqrt(perforating * safe);
    (perforates(mid) ? perforating : safe) = mid;
  }
  return std::log(c.diameter / std::sqrt(perforating * safe));
}

std::vector<Prediction> SolverModel::predict(const MeasuredData& data, const std::vector<std::size_t>& cases,
                                             const EffectSetting& setting) {
  // The measured outcome of each case, for the margin of the ones the model gets wrong.
  std::map<std::size_t, bool> measuredOutcome;
  if (options_.outcomeMargin)
    for (const Observation& o : data.observations)
      if (o.kind == ObservationKind::outcome) measuredOutcome[o.caseIndex] = o.value > 0.5;
  const std::size_t alignments = static_cast<std::size_t>(std::max(1, options_.alignments));
  std::vector<std::optional<double>> margins(cases.size());
  std::vector<nlohmann::json> runs(cases.size() * alignments);  // case k's alignment a at k * alignments + a
  const std::size_t tasks = runs.size();
  std::atomic<std::size_t> next{0};
  std::exception_ptr failure;
  std::mutex failureMutex;
  const auto worker = [&] {
    for (std::size_t task; (task = next++) < tasks;) {
      try {
        const std::size_t k = task / alignments, a = task % alignments;
        const MeasuredCase& c = data.cases.at(cases[k]);
        std::vector<std::string> settings = settingsFor(c, setting);
        // Offset 0 adds no setting, so a single-alignment model's runs serve as alignment 0.
        if (a > 0) settings.push_back("resolution.grid_offset=" + value(static_cast<double>(a) / alignments, "", 1.0));
        runs[task] = runOrRecall(targetOf(c), settings);
        if (alignments > 1) continue;
        const auto measured = measuredOutcome.find(cases[k]);
        const bool perforated = runs[task]["perforated"].get<bool>();
        if (measured != measuredOutcome.end() && measured->second != perforated)
          margins[k] = margin(c, setting, perforated);
      } catch (...) {
        std::lock_guard lock(failureMutex);
        if (!failure) failure = std::current_exception();
        next = tasks;
      }
    }
  };
  const int jobs = std::max(1, std::min<int>(options_.jobs, static_cast<int>(tasks)));
  std::vector<std::thread> pool;
  for (int j = 1; j < jobs; ++j) pool.emplace_back(worker);
  worker();
  for (auto& t : pool) t.join();
  if (failure) std::rethrow_exception(failure);

  // Means over the alignments (one alignment: the run itself).
  std::vector<Prediction> out;
  const double n = static_cast<double>(alignments);
  for (std::size_t k = 0; k < cases.size(); ++k) {
    Prediction p;
    int perforating = 0;
    double residual = 0;
    for (std::size_t a = 0; a < alignments; ++a) {
      const nlohmann::json& r = runs[k * alignments + a];
      // A stopped shot has no residual velocity; the measured data write it as 0.
      if (r["perforated"].get<bool>()) ++perforating, residual += r["residual_velocity_m_s"].get<double>();
    }
    p.perforated = 2 * perforating >= static_cast<int>(alignments);
    if (alignments > 1) p.perforatedFraction = perforating / n;
    p.margin = margins[k];
    p.residualVelocity = residual / n;
    // Every label the data may use for a layer of this case's target gets that layer's hole.
    const Target& t = targetOf(data.cases.at(cases[k]));
    for (const Observation& o : data.observations) {
      if (o.layer.empty()) continue;
      const std::size_t layer = layerIndex(t, o.layer);
      if (layer == std::string::npos) continue;
      double h = 0, v = 0;
      for (std::size_t a = 0; a < alignments; ++a) {
        const auto& hole = runs[k * alignments + a]["hole_size_mm"].at(layer);
        h += hole.at(0).get<double>() * 1e-3 / n;
        v += hole.at(1).get<double>() * 1e-3 / n;
      }
      p.holes.push_back({o.layer, {h, v}});
    }
    out.push_back(std::move(p));
  }
  return out;
}

}  // namespace blt::calibrate
