#include "blt/calibrate/solver_model.hpp"

#include <atomic>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <sstream>
#include <thread>

#include "blt/core/error.hpp"
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

}  // namespace

SolverModel::SolverModel(const std::string& scenarioPath, SolverModelOptions options)
    : path_(scenarioPath), options_(std::move(options)) {
  base_ = sim::loadScenario(path_, options_.settings);
  // The text is part of the cache key: an edited scenario must not reuse old runs.
  label_ = std::filesystem::absolute(path_).lexically_normal().string();
  text_ = fileContents(path_);
  const std::size_t layers = base_.target.layers.size();
  constexpr double mm = 1e-3, deg = std::numbers::pi / 180;
  if (layers >= 3)
    effects_.push_back({"interlayer_gaps",
                        "a gap g between every two layers in front of the rear wall (gap_before += g for layers 2 to " +
                            std::to_string(layers - 1) + ")",
                        {"g", "mm", "gap_m", 0.0, 3 * mm, 0.0}});
  for (std::size_t k = 1; k < layers; ++k) {
    const std::string& name = base_.target.layers[k].name;
    effects_.push_back({"gap:" + name, "a gap g in front of layer " + name + " (gap_before += g)",
                        {"g", "mm", "gap_m", 0.0, 3 * mm, 0.0}});
  }
  for (const auto& layer : base_.target.layers)
    effects_.push_back({"thickness:" + layer.name,
                        "layer " + layer.name + "'s thickness (or areal density) is f times the scenario's",
                        {"f", "", "thickness_factor", 0.5, 1.5, 1.0}});
  for (const auto& layer : base_.target.layers)
    effects_.push_back({"strength:" + layer.name,
                        "layer " + layer.name + "'s material has s times the flow stress of " + layer.material,
                        {"s", "", "strength_factor", 0.5, 2.0, 1.0}});
  // The layers whose flow curve is bilinear: the fabric and laminate cards (seed 000 Table 4).
  std::string fabrics;
  for (std::size_t k = 0; k < layers; ++k)
    if (strengthModelOf(k) == "bilinear") {
      rateHardened_.push_back(k);
      fabrics += (fabrics.empty() ? "" : ", ") + base_.target.layers[k].name;
    }
  if (!rateHardened_.empty())
    effects_.push_back({"rate_hardening",
                        "the fabric layers (" + fabrics + ") harden with strain rate: flow stress x (1 + C ln max(rate / " +
                            value(kFabricReferenceRate, " 1/s", 1.0) + ", 1)), Johnson-Cook's rate term",
                        {"C", "", "rate_coefficient", 0.0, 0.15, 0.0}});
  if (!failureKeys(projectileMaterial()).empty())
    effects_.push_back({"fragmentation",
                        "the projectile breaks up at f times the failure threshold of " + base_.projectile.material +
                            " (f < 1: it fragments more easily)",
                        {"f", "", "failure_factor", 0.25, 2.0, 1.0}});
  if (options_.cardDirectory.empty())
    options_.cardDirectory = options_.cacheFile.empty()
                                 ? (std::filesystem::temp_directory_path() / "blt_calibrate_cards").string()
                                 : (std::filesystem::path(options_.cacheFile).parent_path() / "cards").string();
  effects_.push_back({"obliquity", "every shot is delta degrees more oblique than recorded (3D runs)",
                      {"delta", "deg", "angle_error_rad", 0.0, 15 * deg, 0.0}});
  if (base_.projectile.shape == sim::ProjectileShape::cylinder)
    effects_.push_back({"yaw",
                        "every shot has psi degrees more yaw than recorded: the projectile's axis turned off its flight "
                        "path, in the plane of incidence (3D runs)",
                        {"psi", "deg", "yaw_rad", 0.0, 10 * deg, 0.0}});
  cache_ = std::make_unique<sim::RunCache>(options_.cacheFile);
}

bool turnsRunsThreeD(const std::string& effect) { return effect == "obliquity" || effect == "yaw"; }

std::string SolverModel::describe() const {
  std::string s = "scenario " + path_;
  for (const auto& kv : options_.settings) s += " --set " + kv;
  return s;
}

std::size_t SolverModel::layerIndex(const std::string& label) const {
  const auto& layers = base_.target.layers;
  for (std::size_t k = 0; k < layers.size(); ++k)
    if (layers[k].name == label) return k;
  if (!label.empty() && label.find_first_not_of("0123456789") == std::string::npos) {
    const std::size_t k = std::stoul(label);
    if (k >= 1 && k <= layers.size()) return k - 1;
  }
  return std::string::npos;
}

void SolverModel::check(const MeasuredData& data) const {
  if (!data.hasDiameters)
    throw InputError(InputLocation::file(data.source, std::nullopt, "diameter_mm"), "the solver model needs each shot's diameter",
                     "a diameter_mm column");
  std::string names;
  for (const auto& l : base_.target.layers) names += (names.empty() ? "" : ", ") + l.name;
  for (const Observation& o : data.observations)
    if (!o.layer.empty() && layerIndex(o.layer) == std::string::npos)
      throw InputError(InputLocation::file(data.source, o.line, "layer"),
                       "'" + o.layer + "' is not a layer of " + path_,
                       "a layer name (" + names + ") or a number 1 to " + std::to_string(base_.target.layers.size()));
}

std::vector<std::string> SolverModel::settingsFor(const MeasuredCase& c, const EffectSetting& setting) const {
  std::vector<std::string> s = options_.settings;
  double angle = c.angle;
  s.push_back("projectile.diameter=" + value(c.diameter, "mm", 1e3));
  s.push_back("projectile.velocity=" + value(c.velocity, "m/s", 1.0));
  if (const Effect* e = setting.effect) {
    const auto& layers = base_.target.layers;
    const auto gap = [&](std::size_t k) {
      s.push_back("target.layer." + std::to_string(k + 1) + ".gap_before=" +
                  value(layers[k].gapBefore + setting.value, "mm", 1e3));
    };
    if (e->name == "interlayer_gaps") {
      for (std::size_t k = 1; k + 1 < layers.size(); ++k) gap(k);
    } else if (e->name.rfind("gap:", 0) == 0) {
      gap(layerIndex(e->name.substr(4)));
    } else if (e->name.rfind("thickness:", 0) == 0) {
      const std::size_t k = layerIndex(e->name.substr(10));
      s.push_back("target.layer." + std::to_string(k + 1) + ".thickness=" + value(layers[k].thickness * setting.value, "mm", 1e3));
    } else if (e->name.rfind("strength:", 0) == 0) {
      const std::size_t k = layerIndex(e->name.substr(9));
      s.push_back("target.layer." + std::to_string(k + 1) + ".material=" + strengthCard(k, setting.value));
    } else if (e->name == "rate_hardening") {
      for (std::size_t k : rateHardened_)
        s.push_back("target.layer." + std::to_string(k + 1) + ".material=" + rateHardenedCard(k, setting.value));
    } else if (e->name == "fragmentation") {
      s.push_back("projectile.material=" + fragmentationCard(setting.value));
    } else if (e->name == "obliquity") {
      angle += setting.value;
    } else if (e->name == "yaw") {
      s.push_back("projectile.yaw=" + value(base_.projectile.yaw + setting.value, "deg", 180 / std::numbers::pi));
    }
  }
  s.push_back("projectile.angle=" + value(angle, "deg", 180 / std::numbers::pi));
  return s;
}

Material SolverModel::projectileMaterial() const {
  return sim::resolveMaterial(base_.projectile.material, InputLocation::file(path_, std::nullopt, "projectile.material"));
}

Material SolverModel::layerMaterial(std::size_t k) const {
  const auto& layer = base_.target.layers[k];
  return sim::resolveMaterial(layer.material,
                              InputLocation::file(path_, std::nullopt, "target.layer." + layer.name + ".material"));
}

std::string SolverModel::strengthModelOf(std::size_t k) const {
  const Material m = layerMaterial(k);
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
  std::ofstream out(card);
  if (!out) throw InputError(InputLocation::file(card), "cannot write the derived material card", "a writable card directory");
  out << materialToToml(m);
  return card;
}

std::string SolverModel::strengthCard(std::size_t k, double factor) const {
  const auto& layer = base_.target.layers[k];
  Material m = layerMaterial(k);
  if (!m.has("strength"))
    throw InputError(InputLocation::file(path_, std::nullopt, "target.layer." + layer.name + ".material"),
                     "material " + layer.material + " has no [strength] section to scale", "a layer with a strength model");
  // The stresses of the flow curve; rate and temperature terms are ratios and stay.
  int scaled = 0;
  for (const char* key : {"A", "B", "yield_stress", "tangent_modulus"}) {
    auto& params = m.sections["strength"].params;
    if (auto it = params.find(key); it != params.end()) it->second *= factor, ++scaled;
  }
  if (scaled == 0)
    throw InputError(InputLocation::file(m.path, std::nullopt, "strength"),
                     "the strength model of " + layer.material + " has none of A, B, yield_stress, tangent_modulus",
                     "a Johnson-Cook or bilinear strength model");
  return writeDerivedCard(m, layer.material, "strength x", factor);
}

std::string SolverModel::rateHardenedCard(std::size_t k, double coefficient) const {
  Material m = layerMaterial(k);
  auto& params = m.sections["strength"].params;
  params["C"] = coefficient;
  params["reference_strain_rate"] = kFabricReferenceRate;
  return writeDerivedCard(m, base_.target.layers[k].material, "rate C", coefficient);
}

std::string SolverModel::fragmentationCard(double factor) const {
  Material m = projectileMaterial();
  for (const std::string& key : failureKeys(m)) m.sections["failure"].params[key] *= factor;
  return writeDerivedCard(m, base_.projectile.material, "failure x", factor);
}

nlohmann::json SolverModel::runOrRecall(const std::vector<std::string>& settings) {
  const std::string key = sim::RunCache::key(label_, text_, settings);
  if (auto found = cache_->find(key)) return *found;
  const sim::ImpactScenario scenario = sim::loadScenario(path_, settings);
  sim::ImpactRunOptions runOptions;
  runOptions.threads = options_.threads;
  const sim::ImpactResult r = sim::runImpact(scenario, runOptions);
  nlohmann::json kept = {{"perforated", r.summary["perforated"]},
                         {"residual_velocity_m_s", r.summary["residual_velocity_m_s"]},
                         {"layers", r.summary["layers"]},
                         {"hole_size_mm", r.summary["hole_size_mm"]},
                         {"status", r.summary["status"]},
                         {"wall_time_s", r.summary["wall_time_s"]}};
  cache_->record(key, kept);
  std::lock_guard lock(mutex_);
  ++runsMade_;
  if (options_.log) {
    std::string line = kept["perforated"].get<bool>() ? "perforated" : "stopped";
    for (const auto& kv : settings) line += " " + kv;
    options_.log(line);
  }
  return kept;
}

double SolverModel::margin(const MeasuredCase& c, const EffectSetting& setting, bool perforatedAtMeasured) {
  // Geometric steps away from the measured diameter until the verdict turns, then bisection in ln d.
  const auto perforates = [&](double d) {
    MeasuredCase probe = c;
    probe.diameter = d;
    return runOrRecall(settingsFor(probe, setting))["perforated"].get<bool>();
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
  std::vector<std::optional<double>> margins(cases.size());
  std::vector<nlohmann::json> runs(cases.size());
  std::atomic<std::size_t> next{0};
  std::exception_ptr failure;
  std::mutex failureMutex;
  const auto worker = [&] {
    for (std::size_t k; (k = next++) < cases.size();) {
      try {
        const MeasuredCase& c = data.cases.at(cases[k]);
        runs[k] = runOrRecall(settingsFor(c, setting));
        const auto measured = measuredOutcome.find(cases[k]);
        const bool perforated = runs[k]["perforated"].get<bool>();
        if (measured != measuredOutcome.end() && measured->second != perforated)
          margins[k] = margin(c, setting, perforated);
      } catch (...) {
        std::lock_guard lock(failureMutex);
        if (!failure) failure = std::current_exception();
        next = cases.size();
      }
    }
  };
  const int jobs = std::max(1, std::min<int>(options_.jobs, static_cast<int>(cases.size())));
  std::vector<std::thread> pool;
  for (int j = 1; j < jobs; ++j) pool.emplace_back(worker);
  worker();
  for (auto& t : pool) t.join();
  if (failure) std::rethrow_exception(failure);

  std::vector<Prediction> out;
  for (std::size_t k = 0; k < runs.size(); ++k) {
    const nlohmann::json& r = runs[k];
    Prediction p;
    p.perforated = r["perforated"].get<bool>();
    p.margin = margins[k];
    // A stopped shot has no residual velocity; the measured data write it as 0.
    p.residualVelocity = p.perforated ? r["residual_velocity_m_s"].get<double>() : 0.0;
    // Every label the data may use for a layer gets that layer's hole.
    for (const Observation& o : data.observations) {
      if (o.layer.empty()) continue;
      const auto& h = r["hole_size_mm"].at(layerIndex(o.layer));
      p.holes.push_back({o.layer, {h.at(0).get<double>() * 1e-3, h.at(1).get<double>() * 1e-3}});
    }
    out.push_back(std::move(p));
  }
  return out;
}

}  // namespace blt::calibrate
