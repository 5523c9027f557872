#include "blt/campaign/campaign.hpp"

#include <toml++/toml.h>

#include <charconv>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include "blt/core/toml_keys.hpp"
#include "blt/core/units.hpp"

namespace blt::campaign {

namespace {

std::string fixedKey(const Campaign& c) {
  return c.variable == sim::BisectVariable::diameter ? "velocity" : "diameter";
}
units::Dimension fixedDimension(const Campaign& c) {
  return c.variable == sim::BisectVariable::diameter ? units::velocity : units::length;
}
units::Dimension variableDimension(const Campaign& c) {
  return c.variable == sim::BisectVariable::diameter ? units::length : units::velocity;
}
double fixedValue(const Campaign& c, const CampaignPoint& p) {
  return c.variable == sim::BisectVariable::diameter ? p.velocity : p.diameter;
}

void readBisect(TomlKeys k, Campaign& c) {
  const std::string variable = k.string("variable", "diameter");
  if (variable != "diameter" && variable != "velocity")
    throw InputError(k.at("variable"), "unknown variable '" + variable + "'", "diameter or velocity");
  c.variable = variable == "diameter" ? sim::BisectVariable::diameter : sim::BisectVariable::velocity;
  const units::Dimension dim = variableDimension(c);
  c.lower = k.positive("lower", dim, std::nan(""), true);
  c.upper = k.positive("upper", dim, std::nan(""), true);
  if (!(c.lower < c.upper))
    throw InputError(k.at("upper"), "the bracket's upper end must lie above its lower end", "upper > lower");
  c.tolerance = k.positive("tolerance", dim, std::nan(""), true);
  c.maxRuns = k.integer("max_runs", c.maxRuns, 3);
  k.finish();
}

CampaignPoint readPoint(TomlKeys k, const Campaign& c, int line) {
  CampaignPoint p;
  p.line = line;
  const double fixed = k.positive(fixedKey(c), fixedDimension(c), std::nan(""), true);
  (c.variable == sim::BisectVariable::diameter ? p.velocity : p.diameter) = fixed;
  p.angle = k.quantity("angle", units::angle, std::nan(""), false);
  if (std::isnan(p.angle)) p.angle = 0;
  p.lower = k.positive("lower", variableDimension(c), std::nan(""), false);
  p.upper = k.positive("upper", variableDimension(c), std::nan(""), false);
  if (std::isnan(p.lower) != std::isnan(p.upper))
    throw InputError(k.at(std::isnan(p.lower) ? "upper" : "lower"), "a point's bracket needs both ends",
                     "lower and upper, or neither (the campaign's bracket)");
  if (!std::isnan(p.lower) && !(p.lower < p.upper))
    throw InputError(k.at("upper"), "the bracket's upper end must lie above its lower end", "upper > lower");
  k.finish();
  return p;
}

void checkAngle(double angle, const InputLocation& where) {
  if (!(angle >= 0 && angle < 0.5 * M_PI - 1e-9))
    throw InputError(where, "the angle from the target normal is out of range", "0 deg to 89 deg");
}

void readBle(TomlKeys k, Campaign& c, const std::filesystem::path& dir) {
  BleSeed s;
  s.db = (dir / k.string("db", "", true)).lexically_normal().string();
  s.fit = k.string("fit", "", true);
  const double density = k.positive("density", units::density, std::nan(""), false);
  s.density = std::isnan(density) ? 0 : density;
  const double w = k.quantity("half_width", units::dimensionless, std::nan(""), false);
  if (!std::isnan(w)) {
    if (!(w > 0 && w < 1)) throw InputError(k.at("half_width"), "out of range", "a fraction 0 < half_width < 1, e.g. 0.1");
    s.halfWidth = w;
  }
  k.finish();
  if (c.variable != sim::BisectVariable::diameter)
    throw InputError(InputLocation::file(c.path, std::nullopt, "ble"),
                     "a BLE fit predicts critical diameters, so it can only seed a diameter campaign",
                     "bisect.variable = \"diameter\", or no [ble] table");
  c.ble = s;
}

}  // namespace

std::string exactNumber(double v) {
  char buf[40];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

std::vector<std::string> pointSettings(const Campaign& c, const CampaignPoint& p) {
  std::vector<std::string> s;
  if (c.variable == sim::BisectVariable::diameter) s.push_back("projectile.velocity=" + exactNumber(p.velocity) + "m/s");
  else s.push_back("projectile.diameter=" + exactNumber(p.diameter) + "m");
  s.push_back("projectile.angle=" + exactNumber(p.angle) + "rad");
  return s;
}

std::string variableSetting(const Campaign& c, double value) {
  return c.variable == sim::BisectVariable::diameter ? "projectile.diameter=" + exactNumber(value) + "m"
                                                     : "projectile.velocity=" + exactNumber(value) + "m/s";
}

std::string describePoint(const Campaign& c, const CampaignPoint& p) {
  const std::string fixed = c.variable == sim::BisectVariable::diameter ? units::format(p.velocity, "km/s", 4)
                                                                         : units::format(p.diameter, "mm", 4);
  return fixed + ", " + units::format(p.angle, "deg", 4);
}


nlohmann::json Campaign::definition() const {
  nlohmann::json list = nlohmann::json::array();
  for (const auto& p : points) {
    nlohmann::json j = {{"angle_rad", p.angle}};
    j[variable == sim::BisectVariable::diameter ? "velocity_m_s" : "diameter_m"] = fixedValue(*this, p);
    if (!std::isnan(p.lower)) j["bracket"] = {p.lower, p.upper};
    list.push_back(j);
  }
  nlohmann::json d = {{"name", name},
                      {"scenario_hash", scenarioHash(scenarioText, {})},
                      {"settings", settings},
                      {"variable", sim::toString(variable)},
                      {"bracket", {lower, upper}},
                      {"tolerance", tolerance},
                      {"max_runs", maxRuns},
                      {"points", list}};
  d["ble"] = ble ? nlohmann::json{{"fit", ble->fit}, {"density_kg_m3", ble->density}, {"half_width", ble->halfWidth}}
                 : nlohmann::json();
  return d;
}

std::string Campaign::definitionHash() const { return scenarioHash(definition().dump(), {}); }

sim::ImpactScenario runScenario(const Campaign& c, const std::vector<std::string>& settings) {
  return sim::parseScenario(c.scenarioText, c.scenarioPath, settings);
}

Campaign parseCampaign(const std::string& text, const std::string& sourceName) {
  toml::table root = parseTomlText(text, sourceName);
  const std::filesystem::path dir = std::filesystem::path(sourceName).parent_path();
  Campaign c;
  c.path = sourceName;
  TomlKeys k(root, "", sourceName);
  c.name = k.string("name", std::filesystem::path(sourceName).stem().string());
  if (c.name.empty()) throw InputError(k.at("name"), "must not be empty");
  c.description = k.string("description", "");
  const std::string scenario = k.string("scenario", "", true);
  c.scenarioPath = (dir / scenario).lexically_normal().string();
  {
    std::ifstream in(c.scenarioPath);
    if (!in)
      throw InputError(k.at("scenario"), "cannot open the scenario file '" + c.scenarioPath + "'",
                       "a path relative to the campaign file, e.g. \"../scenarios/fabric_al_corrected.toml\"");
    std::stringstream buf;
    buf << in.rdbuf();
    c.scenarioText = buf.str();
  }
  if (const toml::node* n = k.get("settings")) {
    const toml::array* a = n->as_array();
    if (!a) throw InputError(k.at("settings"), "must be a list of strings", "[\"resolution.particle_spacing=0.2mm\", ...]");
    for (const toml::node& e : *a) {
      const auto s = e.value<std::string>();
      if (!s || s->find('=') == std::string::npos || s->front() == '=')
        throw InputError(k.at("settings"), "every entry must be a \"key=value\" string",
                         "e.g. \"resolution.particle_spacing=0.2mm\"");
      c.settings.push_back(*s);
    }
  }
  const toml::table* bisect = k.table("bisect");
  if (!bisect) throw InputError(k.at("bisect"), "the required table is missing", "[bisect] with variable, lower, upper, tolerance");
  readBisect(TomlKeys(*bisect, "bisect", sourceName), c);

  if (const toml::node* n = k.get("point")) {
    const toml::array* a = n->as_array();
    if (!a) throw InputError(k.at("point"), "must be an array of tables", "[[point]] tables");
    for (std::size_t i = 0; i < a->size(); ++i) {
      const toml::table* t = (*a)[i].as_table();
      if (!t) throw InputError(k.at("point"), "every point must be a table", "[[point]]");
      const CampaignPoint p = readPoint(TomlKeys(*t, "point." + std::to_string(i + 1), sourceName), c,
                                        static_cast<int>(t->source().begin.line));
      checkAngle(p.angle, InputLocation::file(sourceName, p.line > 0 ? std::optional<int>(p.line) : std::nullopt,
                                              "point." + std::to_string(i + 1) + ".angle"));
      c.points.push_back(p);
    }
  }
  if (const toml::table* g = k.table("grid")) {
    TomlKeys gk(*g, "grid", sourceName);
    const std::vector<double> fixed = gk.quantities(fixedKey(c), fixedDimension(c));
    std::vector<double> angles = gk.quantities("angle", units::angle);
    if (fixed.empty()) throw InputError(gk.at(fixedKey(c)), "the required key is missing", "a list such as [\"2 km/s\", \"3 km/s\"]");
    if (angles.empty()) angles.push_back(0);
    for (double v : fixed)
      if (!(v > 0)) throw InputError(gk.at(fixedKey(c)), "every value must be positive");
    for (double a : angles) checkAngle(a, gk.at("angle"));
    gk.finish();
    for (double a : angles)
      for (double v : fixed) {
        CampaignPoint p;
        (c.variable == sim::BisectVariable::diameter ? p.velocity : p.diameter) = v;
        p.angle = a;
        c.points.push_back(p);
      }
  }
  if (c.points.empty())
    throw InputError(InputLocation::file(sourceName), "the campaign has no points", "[[point]] tables and/or a [grid] table");
  if (const toml::table* b = k.table("ble")) readBle(TomlKeys(*b, "ble", sourceName), c, dir);
  k.finish();

  // Two points that fix the same values would bisect the same runs twice.
  std::map<std::vector<std::string>, std::size_t> seen;
  for (std::size_t i = 0; i < c.points.size(); ++i) {
    const auto [it, fresh] = seen.emplace(pointSettings(c, c.points[i]), i);
    if (fresh) continue;
    // Name the one written out as a [[point]] (a grid point has no line of its own).
    const CampaignPoint& named = c.points[i].line > 0 ? c.points[i] : c.points[it->second];
    throw InputError(InputLocation::file(sourceName, named.line > 0 ? std::optional<int>(named.line) : std::nullopt,
                                         named.line > 0 ? "point" : "grid"),
                     "point " + describePoint(c, c.points[i]) + " is given twice", "each velocity and angle once");
  }

  // Each point's scenario at both ends of its bracket, so that settings the scenario refuses fail now.
  for (const auto& p : c.points) {
    const double ends[2] = {std::isnan(p.lower) ? c.lower : p.lower, std::isnan(p.upper) ? c.upper : p.upper};
    for (double end : ends) {
      std::vector<std::string> s = c.settings;
      for (const auto& extra : pointSettings(c, p)) s.push_back(extra);
      s.push_back(variableSetting(c, end));
      try {
        (void)runScenario(c, s);
      } catch (const InputError& e) {
        throw InputError(InputLocation::file(sourceName, p.line > 0 ? std::optional<int>(p.line) : std::nullopt),
                         "the scenario " + c.scenarioPath + " refuses point " + describePoint(c, p) + " at " +
                             units::format(end, c.variable == sim::BisectVariable::diameter ? "mm" : "km/s", 5) +
                             ": " + e.what());
      }
    }
  }
  return c;
}

Campaign loadCampaign(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError(InputLocation::file(path), "cannot open the campaign file");
  std::stringstream text;
  text << in.rdbuf();
  return parseCampaign(text.str(), path);
}

}  // namespace blt::campaign
