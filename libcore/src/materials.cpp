#include "blt/core/materials.hpp"

#include <toml++/toml.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "blt/core/units.hpp"

namespace blt {

namespace {

using units::Dimension;

struct ParamSpec {
  const char* key;
  Dimension dim;
  const char* unit;  // unit used when writing the value back
};
struct ModelSpec {
  const char* section;
  const char* model;  // "" for sections without a model key
  std::vector<ParamSpec> params;
};

// The schema: which parameters each section's model takes and their dimensions.
const std::vector<ModelSpec>& schema() {
  // Johnson-Cook and Borvik's modified form take the same parameters (C differs in meaning, not in kind).
  static const std::vector<ParamSpec> johnsonCook = {
      {"A", units::pressure, "MPa"},
      {"B", units::pressure, "MPa"},
      {"n", units::dimensionless, ""},
      {"C", units::dimensionless, ""},
      {"m", units::dimensionless, ""},
      {"reference_strain_rate", units::rate, "1/s"},
      {"room_temperature", units::temperature, "K"},
      {"melt_temperature", units::temperature, "K"}};
  static const std::vector<ModelSpec> specs = {
      {"elastic", "",
       {{"youngs_modulus", units::pressure, "MPa"},
        {"poisson_ratio", units::dimensionless, ""},
        {"shear_modulus", units::pressure, "MPa"},
        {"bulk_modulus", units::pressure, "MPa"}}},
      {"strength", "elastic", {}},
      // Optional rate hardening: the flow stress times 1 + C ln max(rate/reference_strain_rate, 1), Johnson-Cook's
      // rate term; without C the curve is rate independent.
      {"strength", "bilinear",
       {{"yield_stress", units::pressure, "MPa"},
        {"tangent_modulus", units::pressure, "MPa"},
        {"C", units::dimensionless, ""},
        {"reference_strain_rate", units::rate, "1/s"}}},
      {"strength", "johnson-cook", johnsonCook},
      // Borvik's modification (LS-DYNA material 107, seed 003 Eq. 18): rate term (1 + rate/reference)^C instead of
      // 1 + C ln(rate/reference); kept apart from johnson-cook because C means something else in it.
      {"strength", "modified-johnson-cook", johnsonCook},
      // Zerilli-Armstrong for fcc metals: C0 + C2 sqrt(ep) exp(-C3 T + C4 T ln(rate/reference)), T absolute.
      {"strength", "zerilli-armstrong-fcc",
       {{"C0", units::pressure, "MPa"},
        {"C2", units::pressure, "MPa"},
        {"C3", Dimension{0, 0, 0, -1, 0}, "1/K"},
        {"C4", Dimension{0, 0, 0, -1, 0}, "1/K"},
        {"reference_strain_rate", units::rate, "1/s"},
        {"room_temperature", units::temperature, "K"}}},
      // Johnson-Holmquist 1 for ceramics (seed 002 sec. 3.7): intact strength piecewise linear in pressure through
      // (P1, S1), (P2, S2), zero at -T (hydrostatic tensile strength); failed strength = slope * pressure capped at
      // max_failed_strength.
      {"strength", "johnson-holmquist-1",
       {{"S1", units::pressure, "GPa"},
        {"P1", units::pressure, "GPa"},
        {"S2", units::pressure, "GPa"},
        {"P2", units::pressure, "GPa"},
        {"C", units::dimensionless, ""},
        {"hydrostatic_tensile_strength", units::pressure, "GPa"},
        {"max_failed_strength", units::pressure, "GPa"},
        {"failed_strength_slope", units::dimensionless, ""},
        {"reference_strain_rate", units::rate, "1/s"}}},
      // A fluid without shear strength (water in seed 003 Table 3, LS-DYNA MAT_NULL): viscosity and a tensile
      // pressure cut-off (negative).
      {"strength", "fluid",
       {{"dynamic_viscosity", Dimension{1, -1, -1, 0, 0}, "Pa s"}, {"pressure_cutoff", units::pressure, "Pa"}}},
      {"eos", "mie-grueneisen",
       {{"c0", units::velocity, "m/s"}, {"s", units::dimensionless, ""}, {"gamma0", units::dimensionless, ""},
        {"a", units::dimensionless, ""}}},
      // p = k1 mu + k2 mu^2 + k3 mu^3 (+ bulking pressure), mu = rho/rho0 - 1 (seed 002 Eq. 13).
      {"eos", "polynomial",
       {{"k1", units::pressure, "GPa"},
        {"k2", units::pressure, "GPa"},
        {"k3", units::pressure, "GPa"},
        {"bulking_factor", units::dimensionless, ""}}},
      {"failure", "max-principal-stress", {{"max_principal_stress", units::pressure, "MPa"}}},
      {"failure", "max-principal-strain", {{"max_principal_strain", units::dimensionless, ""}}},
      {"failure", "johnson-cook-damage",
       {{"D1", units::dimensionless, ""},
        {"D2", units::dimensionless, ""},
        {"D3", units::dimensionless, ""},
        {"D4", units::dimensionless, ""},
        {"D5", units::dimensionless, ""},
        {"critical_damage", units::dimensionless, ""}}},
      // Johnson-Holmquist 1 damage (seed 002 sec. 3.7.2): plastic strain to fracture up to max_fracture_strain.
      {"failure", "johnson-holmquist-1", {{"max_fracture_strain", units::dimensionless, ""}}},
      {"thermal", "",
       {{"specific_heat", units::specificHeat, "J/kg/K"},
        {"taylor_quinney", units::dimensionless, ""},
        {"thermal_expansion", Dimension{0, 0, 0, -1, 0}, "1/K"}}},
      {"properties", "",
       {{"yield_stress", units::pressure, "MPa"},
        {"tensile_strength", units::pressure, "MPa"},
        {"compressive_strength", units::pressure, "MPa"},
        {"failure_strain", units::dimensionless, ""},
        {"brinell_hardness", units::dimensionless, ""},
        {"hugoniot_elastic_limit", units::pressure, "GPa"},
        {"thickness", units::length, "mm"}}},
  };
  return specs;
}

std::string allowedModels(const std::string& section) {
  std::string list;
  for (const auto& s : schema())
    if (section == s.section && *s.model) list += (list.empty() ? "" : ", ") + std::string(s.model);
  return list;
}

std::string allowedSections() {
  std::string list;
  for (const auto& s : schema())
    if (list.find(s.section) == std::string::npos) list += (list.empty() ? "" : ", ") + std::string(s.section);
  return list;
}

const ModelSpec* findSpec(const std::string& section, const std::string& model) {
  for (const auto& s : schema())
    if (section == s.section && model == s.model) return &s;
  return nullptr;
}

int lineOf(const toml::node& n) { return static_cast<int>(n.source().begin.line); }

double readValue(const toml::node& node, const ParamSpec& spec, const InputLocation& where) {
  if (auto s = node.as_string()) return units::parse(s->get(), spec.dim, where);
  if (auto v = node.value<double>()) {
    if (spec.dim == units::dimensionless) return *v;
    throw InputError(where, "the number " + std::to_string(*v) + " has no unit; a unit is required",
                     "a " + units::describe(spec.dim) + " as a string, e.g. \"" + units::example(spec.dim) + "\"");
  }
  throw InputError(where, "not a number or a quantity", "a number, or a string such as \"490 MPa\"");
}

std::string requireString(const toml::table& t, const char* key, const InputLocation& at) {
  auto node = t.get(key);
  if (!node) throw InputError(at.withField(key), "the required key is missing");
  if (auto s = node->as_string()) return s->get();
  throw InputError(at.withLine(lineOf(*node)).withField(key), "must be a string");
}

}  // namespace

bool Material::has(const std::string& sec, const std::string& key) const {
  auto it = sections.find(sec);
  return it != sections.end() && it->second.params.count(key) != 0;
}

const MaterialSection& Material::section(const std::string& sec) const {
  auto it = sections.find(sec);
  if (it == sections.end())
    throw InputError(InputLocation::file(path, std::nullopt, sec), "material '" + id + "' has no [" + sec + "] section");
  return it->second;
}

double Material::param(const std::string& sec, const std::string& key) const {
  const MaterialSection& s = section(sec);
  auto it = s.params.find(key);
  if (it == s.params.end())
    throw InputError(InputLocation::file(path, std::nullopt, sec + "." + key),
                     "material '" + id + "' does not give this parameter" +
                         (s.model.empty() ? "" : " (model '" + s.model + "')"));
  return it->second;
}

Material parseMaterial(const std::string& text, const std::string& sourceName, const std::string& id) {
  const auto at = InputLocation::file(sourceName);
  toml::table root;
  try {
    root = toml::parse(text, sourceName);
  } catch (const toml::parse_error& e) {
    throw InputError(at.withLine(static_cast<int>(e.source().begin.line)),
                     "not valid TOML: " + std::string(e.description()));
  }
  Material m;
  m.id = id;
  m.path = sourceName;
  m.name = requireString(root, "name", at);
  m.source = requireString(root, "source", at);
  if (root.contains("notes")) m.notes = requireString(root, "notes", at);
  auto densityNode = root.get("density");
  if (!densityNode) throw InputError(at.withField("density"), "the required key is missing", "e.g. \"2770 kg/m3\"");
  m.density = readValue(*densityNode, {"density", units::density, "kg/m3"},
                        at.withLine(lineOf(*densityNode)).withField("density"));
  if (m.density <= 0) throw InputError(at.withLine(lineOf(*densityNode)).withField("density"), "must be positive");

  for (const auto& [keyNode, node] : root) {
    const std::string key(keyNode.str());
    if (key == "name" || key == "source" || key == "density" || key == "notes") continue;
    const auto here = at.withLine(lineOf(node)).withField(key);
    auto table = node.as_table();
    if (!table) throw InputError(here, "unknown top-level key", "name, source, density, notes, or a section");
    if (!findSpec(key, "") && allowedModels(key).empty())
      throw InputError(here, "unknown section", allowedSections());
    MaterialSection section;
    if (auto modelNode = table->get("model")) {
      if (!modelNode->as_string()) throw InputError(here.withField(key + ".model"), "must be a string");
      section.model = modelNode->as_string()->get();
    }
    const ModelSpec* spec = findSpec(key, section.model);
    if (!spec) {
      const std::string models = allowedModels(key);
      throw InputError(here.withField(key + ".model"),
                       section.model.empty() ? "the section needs a model" : "unknown model '" + section.model + "'",
                       models.empty() ? "no model key in this section" : models);
    }
    for (const auto& [pKeyNode, pNode] : *table) {
      const std::string pKey(pKeyNode.str());
      if (pKey == "model") continue;
      const auto pHere = at.withLine(lineOf(pNode)).withField(key + "." + pKey);
      auto ps = std::find_if(spec->params.begin(), spec->params.end(), [&](const ParamSpec& p) { return pKey == p.key; });
      if (ps == spec->params.end()) {
        std::string allowed;
        for (const auto& p : spec->params) allowed += (allowed.empty() ? "" : ", ") + std::string(p.key);
        throw InputError(pHere, "unknown parameter", allowed.empty() ? "none" : allowed);
      }
      section.params[pKey] = readValue(pNode, *ps, pHere);
      section.lines[pKey] = lineOf(pNode);
    }
    m.sections[key] = std::move(section);
  }
  return m;
}

Material loadMaterial(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError(InputLocation::file(path), "cannot open the material file");
  std::stringstream buffer;
  buffer << in.rdbuf();
  return parseMaterial(buffer.str(), path, std::filesystem::path(path).stem().string());
}

std::string materialToToml(const Material& m) {
  std::ostringstream out;
  auto quote = [](const std::string& s) {
    std::string q = "\"";
    for (char c : s) {
      if (c == '"' || c == '\\') {
        q += '\\';
        q += c;
      } else if (c == '\n') {
        q += "\\n";
      } else if (c == '\t') {
        q += "\\t";
      } else {
        q += c;
      }
    }
    return q + "\"";
  };
  out << "name = " << quote(m.name) << "\n";
  out << "source = " << quote(m.source) << "\n";
  if (!m.notes.empty()) out << "notes = " << quote(m.notes) << "\n";
  out << "density = " << quote(units::format(m.density, "kg/m3", 8)) << "\n";
  for (const auto& [secName, sec] : m.sections) {
    out << "\n[" << secName << "]\n";
    if (!sec.model.empty()) out << "model = " << quote(sec.model) << "\n";
    const ModelSpec* spec = findSpec(secName, sec.model);
    for (const auto& [key, value] : sec.params) {
      const char* unit = "";
      if (spec)
        for (const auto& p : spec->params)
          if (key == p.key) unit = p.unit;
      if (*unit) {
        out << key << " = " << quote(units::format(value, unit, 8)) << "\n";
      } else {
        char buf[64];
        std::snprintf(buf, sizeof buf, "%.8g", value);
        out << key << " = " << buf << "\n";
      }
    }
  }
  return out.str();
}

std::string MaterialLibrary::defaultDirectory() {
  if (const char* env = std::getenv("BLT_MATERIALS_DIR")) return env;
  return std::string(BLT_DATA_DIR) + "/materials";
}

MaterialLibrary MaterialLibrary::load(const std::string& directory) {
  namespace fs = std::filesystem;
  MaterialLibrary lib;
  lib.directory_ = directory;
  if (!fs::is_directory(directory))
    throw InputError(InputLocation::file(directory), "the material directory does not exist");
  std::vector<fs::path> files;
  for (const auto& entry : fs::directory_iterator(directory))
    if (entry.is_regular_file() && entry.path().extension() == ".toml") files.push_back(entry.path());
  std::sort(files.begin(), files.end());
  for (const auto& f : files) {
    // Files without a density are other data kept beside the materials (e.g. the MLI stacking).
    toml::table probe;
    try {
      probe = toml::parse_file(f.string());
    } catch (const toml::parse_error& e) {
      throw InputError(InputLocation::file(f.string(), static_cast<int>(e.source().begin.line)),
                       "not valid TOML: " + std::string(e.description()));
    }
    if (!probe.contains("density")) continue;
    Material m = loadMaterial(f.string());
    lib.materials_[m.id] = std::move(m);
  }
  return lib;
}

Material MaterialLibrary::get(const std::string& id) && { return static_cast<const MaterialLibrary&>(*this).get(id); }

const Material& MaterialLibrary::get(const std::string& id) const& {
  auto it = materials_.find(id);
  if (it == materials_.end()) {
    std::string present;
    for (const auto& [k, v] : materials_) present += (present.empty() ? "" : ", ") + k;
    throw InputError(InputLocation::file(directory_, std::nullopt, id), "no material of that name",
                     present.empty() ? "(the library is empty)" : present);
  }
  return it->second;
}

std::vector<std::string> MaterialLibrary::ids() const {
  std::vector<std::string> out;
  for (const auto& [k, v] : materials_) out.push_back(k);
  return out;
}

}  // namespace blt
