#include "blt/sim/scenario.hpp"

#include <toml++/toml.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include "blt/analytic/laminate.hpp"
#include "blt/core/toml_keys.hpp"
#include "blt/core/units.hpp"

namespace blt::sim {

const char* toString(ProjectileShape s) { return s == ProjectileShape::sphere ? "sphere" : "cylinder"; }
const char* toString(NoseShape s) {
  switch (s) {
    case NoseShape::flat: return "flat";
    case NoseShape::hemispherical: return "hemispherical";
    case NoseShape::conical: return "conical";
    case NoseShape::ogival: return "ogival";
  }
  return "?";
}
const char* toString(ModelMode m) {
  switch (m) {
    case ModelMode::automatic: return "auto";
    case ModelMode::threeD: return "3d";
    case ModelMode::axisymmetric: return "axisymmetric";
  }
  return "?";
}

double TargetSpec::totalDepth() const {
  double d = 0;
  for (const auto& l : layers) d += l.gapBefore + l.thickness;
  return d;
}

ModelMode ImpactScenario::resolvedMode() const {
  if (run.mode != ModelMode::automatic) return run.mode;
  return std::fabs(projectile.angle) < 1e-9 && std::fabs(projectile.yaw) < 1e-9 ? ModelMode::axisymmetric
                                                                                 : ModelMode::threeD;
}
double ImpactScenario::projectileSpacing() const {
  return projectile.spacing > 0 ? projectile.spacing : resolution.particleSpacing;
}
double ImpactScenario::layerSpacing(std::size_t layer) const {
  const double s = target.layers.at(layer).spacing;
  return s > 0 ? s : resolution.particleSpacing;
}
double ImpactScenario::cellSize() const {
  return resolution.cellSize > 0 ? resolution.cellSize : 2.0 * resolution.particleSpacing;
}

namespace {

const std::vector<std::pair<std::string, BoundaryKind>> kEdges = {
    {"non-reflecting", BoundaryKind::nonReflecting}, {"free", BoundaryKind::free}, {"fixed", BoundaryKind::fixed}};

void readProjectile(TomlKeys r, ProjectileSpec& p) {
  p.shape = r.choice<ProjectileShape>("shape", {{"sphere", ProjectileShape::sphere}, {"cylinder", ProjectileShape::cylinder}},
                                      ProjectileShape::sphere);
  p.diameter = r.positive("diameter", units::length, 0, true);
  p.material = r.string("material", "", true);
  p.velocity = r.positive("velocity", units::velocity, 0, true);
  p.angle = r.nonNegative("angle", units::angle, 0);
  if (p.angle >= 0.5 * M_PI - 1e-9)
    throw InputError(r.at("angle"), "the angle from the target normal must be below 90 deg", "0 deg to 89 deg");
  p.spacing = r.positive("spacing", units::length, 0);
  p.aimOffset = r.quantity("aim_offset", units::length, 0);
  p.yaw = r.quantity("yaw", units::angle, 0);
  if (p.yaw != 0 && p.shape == ProjectileShape::sphere)
    throw InputError(r.at("yaw"), "a sphere has no axis to yaw", "yaw = \"0 deg\", or shape = \"cylinder\"");
  if (!(std::fabs(p.angle + p.yaw) < 0.5 * M_PI - 1e-9))
    throw InputError(r.at("yaw"), "the axis would lie in the target plane or beyond (angle + yaw at 90 deg or more)",
                     "|angle + yaw| below 90 deg");
  if (p.shape == ProjectileShape::cylinder) {
    p.length = r.positive("length", units::length, 0, true);
    p.nose = r.choice<NoseShape>("nose", {{"flat", NoseShape::flat}, {"hemispherical", NoseShape::hemispherical},
                                          {"conical", NoseShape::conical}, {"ogival", NoseShape::ogival}},
                                 NoseShape::flat);
    const double radius = 0.5 * p.diameter;
    if (p.nose == NoseShape::conical) p.noseLength = r.positive("nose_length", units::length, 0, true);
    if (p.nose == NoseShape::ogival) {
      p.noseCaliberRadius = r.quantity("nose_caliber_radius", units::dimensionless, 3.0);
      if (!(p.noseCaliberRadius >= 0.5))
        throw InputError(r.at("nose_caliber_radius"), "a tangent ogive needs at least half a caliber", "0.5 or more");
      const double R = p.noseCaliberRadius * p.diameter;
      p.noseLength = std::sqrt(R * R - (R - radius) * (R - radius));
    }
    if (p.nose == NoseShape::hemispherical) p.noseLength = radius;
    if (p.noseLength >= p.length)
      throw InputError(r.at("length"), "the nose is as long as the projectile or longer",
                       "a length above the nose length (" + units::format(p.noseLength, "mm", 4) + ")");
  }
  r.finish();
}

void readLayer(TomlKeys r, LayerSpec& l, std::size_t index) {
  l.name = r.string("name", "layer " + std::to_string(index + 1));
  l.material = r.string("material", "", true);
  l.thickness = r.positive("thickness", units::length, 0, true);
  l.gapBefore = r.nonNegative("gap_before", units::length, 0);
  l.spacing = r.positive("spacing", units::length, 0);
  r.finish();
}

void readTarget(TomlKeys r, TargetSpec& t) {
  t.lateralSize = r.positive("lateral_size", units::length, 0, true);
  t.edge = r.choice<BoundaryKind>("edge", kEdges, BoundaryKind::nonReflecting);
  const toml::node* layers = r.get("layer");
  const toml::array* list = layers ? layers->as_array() : nullptr;
  if (!list || list->empty())
    throw InputError(r.at("layer"), "the target needs at least one layer", "[[target.layer]] tables, front to rear");
  for (std::size_t i = 0; i < list->size(); ++i) {
    const toml::table* lt = (*list)[i].as_table();
    if (!lt) throw InputError(r.at("layer"), "every layer must be a table", "[[target.layer]]");
    LayerSpec l;
    readLayer(TomlKeys(*lt, r.child("layer." + std::to_string(i + 1)), r.source()), l, i);
    t.layers.push_back(l);
  }
  r.finish();
}

void readResolution(TomlKeys r, ResolutionSpec& s) {
  s.particleSpacing = r.positive("particle_spacing", units::length, 0, true);
  s.cellSize = r.positive("cell_size", units::length, 0);
  s.gridOffset = r.nonNegative("grid_offset", units::dimensionless, 0);
  if (!(s.gridOffset < 1))
    throw InputError(r.at("grid_offset"), "the grid offset is a fraction of a cell", "0 to below 1");
  r.finish();
}

void readRun(TomlKeys r, RunSpec& s) {
  s.mode = r.choice<ModelMode>("mode", {{"auto", ModelMode::automatic}, {"3d", ModelMode::threeD},
                                        {"axisymmetric", ModelMode::axisymmetric}},
                               ModelMode::automatic);
  s.maxTime = r.positive("max_time", units::time, 0, true);
  s.stopWhenSettled = r.boolean("stop_when_settled", true);
  s.frames = r.integer("frames", 10, 0);
  r.finish();
}

void readVerdict(TomlKeys r, VerdictOptions& v) {
  v.separationCells = r.positive("separation_cells", units::dimensionless, v.separationCells);
  v.debrisMassFraction = r.positive("debris_mass_fraction", units::dimensionless, v.debrisMassFraction);
  v.settledKineticFraction = r.positive("settled_kinetic_fraction", units::dimensionless, v.settledKineticFraction);
  r.finish();
}

void readSolver(TomlKeys r, SolverOptions& o) {
  o.shapeFunction = r.choice<ShapeFunctionKind>(
      "shape_function", {{"ugimp", ShapeFunctionKind::uGimp}, {"linear", ShapeFunctionKind::linear}}, o.shapeFunction);
  o.scheme = r.choice<UpdateSchemeKind>("scheme", {{"musl", UpdateSchemeKind::musl}, {"usl", UpdateSchemeKind::usl}},
                                        o.scheme);
  o.contact.mode = r.choice<ContactMode>(
      "contact", {{"multi-field", ContactMode::multiField}, {"single-field", ContactMode::singleField}}, o.contact.mode);
  o.contact.friction = r.nonNegative("friction", units::dimensionless, o.contact.friction);
  o.contact.strain = r.choice<ContactStrain>(
      "contact_strain", {{"per-node", ContactStrain::perNode}, {"per-particle", ContactStrain::perParticle}},
      o.contact.strain);
  // Under USL the strain already comes from the corrected velocities, and the single field has no contact to
  // correct: the option would change nothing, and a run would be taken for one made with it.
  if (o.contact.strain == ContactStrain::perParticle &&
      (o.scheme == UpdateSchemeKind::usl || o.contact.mode == ContactMode::singleField))
    throw InputError(r.at("contact_strain"),
                     std::string("per-particle changes nothing with solver.") +
                         (o.scheme == UpdateSchemeKind::usl ? "scheme = usl" : "contact = single-field"),
                     "per-particle with scheme = musl and contact = multi-field; otherwise per-node");
  o.timeStepSafety = r.positive("time_step_safety", units::dimensionless, o.timeStepSafety);
  if (o.timeStepSafety > 1) throw InputError(r.at("time_step_safety"), "above the stability limit", "0 < safety <= 1");
  o.flipFraction = r.nonNegative("flip_fraction", units::dimensionless, o.flipFraction);
  if (o.flipFraction > 1) throw InputError(r.at("flip_fraction"), "out of range", "0 (PIC) to 1 (FLIP)");
  o.viscosity.linear = r.nonNegative("viscosity_linear", units::dimensionless, o.viscosity.linear);
  o.viscosity.quadratic = r.nonNegative("viscosity_quadratic", units::dimensionless, o.viscosity.quadratic);
  o.erosionExpansion = r.nonNegative("erosion_expansion", units::dimensionless, o.erosionExpansion);
  o.erosionSoundSpeed = r.nonNegative("erosion_sound_speed", units::dimensionless, o.erosionSoundSpeed);
  o.keepErodedMass = r.boolean("keep_eroded_mass", o.keepErodedMass);
  r.finish();
}

// "key=value" onto the document. Layers are addressed as target.layer.N (1-based) or target.layer.NAME.
void applySetting(toml::table& root, const std::string& setting) {
  const auto flag = [&](const std::string& key) { return InputLocation{"--set", std::nullopt, key}; };
  const auto eq = setting.find('=');
  if (eq == std::string::npos || eq == 0)
    throw InputError(InputLocation::flag("--set"), "'" + setting + "' is not key=value",
                     "e.g. --set projectile.diameter=1.2mm");
  const std::string key = setting.substr(0, eq), text = setting.substr(eq + 1);
  std::vector<std::string> parts;
  std::stringstream ss(key);
  for (std::string p; std::getline(ss, p, '.');) parts.push_back(p);
  toml::table* t = &root;
  for (std::size_t i = 0; i + 1 < parts.size(); ++i) {
    toml::node* n = t->get(parts[i]);
    if (n && n->is_array()) {  // target.layer.N or target.layer.NAME
      toml::array& arr = *n->as_array();
      if (i + 2 >= parts.size())
        throw InputError(flag(key), "a layer needs a key after its number or name", "e.g. target.layer.2.gap_before");
      const std::string& which = parts[++i];
      toml::table* found = nullptr;
      char* end = nullptr;
      const long number = std::strtol(which.c_str(), &end, 10);
      if (end && *end == '\0' && number >= 1 && number <= static_cast<long>(arr.size())) {
        found = arr[static_cast<std::size_t>(number - 1)].as_table();
      } else {
        for (auto& e : arr)
          if (auto lt = e.as_table(); lt && lt->get("name") && lt->get("name")->value<std::string>() == which)
            found = lt;
      }
      if (!found)
        throw InputError(flag(key), "no layer '" + which + "'",
                         "a number from 1 to " + std::to_string(arr.size()) + " or a layer's name");
      t = found;
      continue;
    }
    if (!n) n = t->insert_or_assign(parts[i], toml::table{}).first->second.as_table();
    if (!n || !n->is_table()) throw InputError(flag(key), "'" + parts[i] + "' is not a table");
    t = n->as_table();
  }
  // The value as TOML if it is TOML (numbers, booleans, quoted strings), else the text itself (1.2mm).
  toml::node_view<toml::node> value;
  toml::table parsed;
  try {
    parsed = toml::parse("value = " + text);
  } catch (const toml::parse_error&) {
    parsed = toml::table{};
    parsed.insert("value", text);
  }
  // Nodes copied from the parsed snippet keep its line 1; re-create them so that errors name the flag.
  toml::node& v = *parsed.get("value");
  if (auto s = v.as_string()) t->insert_or_assign(parts.back(), std::string(s->get()));
  else if (auto i = v.as_integer()) t->insert_or_assign(parts.back(), i->get());
  else if (auto d = v.as_floating_point()) t->insert_or_assign(parts.back(), d->get());
  else if (auto b = v.as_boolean()) t->insert_or_assign(parts.back(), b->get());
  else throw InputError(flag(key), "unsupported value '" + text + "'", "a number, true/false, or text such as 1.2mm");
}

}  // namespace

ImpactScenario parseScenario(const std::string& text, const std::string& sourceName,
                             const std::vector<std::string>& settings) {
  toml::table root = parseTomlText(text, sourceName);
  for (const auto& s : settings) applySetting(root, s);

  ImpactScenario sc;
  sc.path = sourceName;
  sc.settings = settings;
  TomlKeys r(root, "", sourceName);
  sc.name = r.string("name", std::filesystem::path(sourceName).stem().string());
  sc.description = r.string("description", "");
  sc.source = r.string("source", "");
  const auto section = [&](const std::string& key, bool required) -> const toml::table* {
    const toml::table* t = r.table(key);
    if (!t && required) throw InputError(r.at(key), "the required table is missing", "[" + key + "]");
    return t;
  };
  readProjectile(TomlKeys(*section("projectile", true), "projectile", sourceName), sc.projectile);
  readTarget(TomlKeys(*section("target", true), "target", sourceName), sc.target);
  readResolution(TomlKeys(*section("resolution", true), "resolution", sourceName), sc.resolution);
  readRun(TomlKeys(*section("run", true), "run", sourceName), sc.run);
  if (auto t = section("verdict", false)) readVerdict(TomlKeys(*t, "verdict", sourceName), sc.verdict);
  if (auto t = section("solver", false)) readSolver(TomlKeys(*t, "solver", sourceName), sc.solver);
  r.finish();

  if (sc.run.mode == ModelMode::axisymmetric && sc.projectile.angle > 1e-9)
    throw InputError(r.at("run"), "an oblique impact cannot run axisymmetric",
                     "mode = \"3d\" or \"auto\", or projectile.angle = \"0 deg\"");
  if (sc.run.mode == ModelMode::axisymmetric && std::fabs(sc.projectile.yaw) > 1e-9)
    throw InputError(r.at("run"), "a yawed projectile cannot run axisymmetric",
                     "mode = \"3d\" or \"auto\", or projectile.yaw = \"0 deg\"");
  if (sc.projectile.aimOffset != 0) {
    const InputLocation aim = InputLocation::file(sourceName, std::nullopt, "projectile.aim_offset");
    if (sc.resolvedMode() == ModelMode::axisymmetric || (sc.projectile.angle < 1e-9 && std::fabs(sc.projectile.yaw) < 1e-9))
      throw InputError(aim, "an off-centre aim needs a 3D half model: a normal impact is modelled about its axis",
                       "aim_offset = \"0 mm\", or an oblique or yawed shot");
    if (std::fabs(sc.projectile.aimOffset) >= 0.5 * sc.target.lateralSize)
      throw InputError(aim, "the shot line would meet the front face off the target",
                       "|aim_offset| below half the lateral size, " + units::format(0.5 * sc.target.lateralSize, "mm", 4));
  }
  const double h = sc.cellSize();
  if (sc.projectileSpacing() > h)
    throw InputError(InputLocation::file(sourceName, std::nullopt, "projectile.spacing"),
                     "the particle spacing is larger than the cell", "at most the cell size " + units::format(h, "mm", 4));
  for (std::size_t i = 0; i < sc.target.layers.size(); ++i)
    if (sc.layerSpacing(i) > sc.target.layers[i].thickness + 1e-12)
      throw InputError(InputLocation::file(sourceName, std::nullopt, "target.layer." + std::to_string(i + 1) + ".spacing"),
                       "layer '" + sc.target.layers[i].name + "' is thinner than one particle spacing",
                       "a spacing of at most the thickness " + units::format(sc.target.layers[i].thickness, "mm", 4));
  return sc;
}

ImpactScenario loadScenario(const std::string& path, const std::vector<std::string>& settings) {
  std::ifstream in(path);
  if (!in) throw InputError(InputLocation::file(path), "cannot open the scenario file");
  std::stringstream text;
  text << in.rdbuf();
  return parseScenario(text.str(), path, settings);
}

Material resolveMaterial(const std::string& name, const InputLocation& where) {
  static const std::string kLaminate = "laminate:";
  if (name.rfind(kLaminate, 0) == 0) {
    std::string stack = name.substr(kLaminate.size());
    const std::string path = stack.find(".toml") != std::string::npos
                                 ? stack
                                 : MaterialLibrary::defaultDirectory() + "/" + stack + ".toml";
    if (!std::filesystem::exists(path))
      throw InputError(where, "no laminate stack file " + path, "laminate:mli_stack, or laminate:PATH.toml");
    const analytic::Stack s = analytic::loadStack(path);
    return analytic::equivalentMaterialCard(s, analytic::analyseLaminate(s.layers), name);
  }
  if (name.find(".toml") != std::string::npos) return loadMaterial(name);
  const MaterialLibrary library = MaterialLibrary::load();
  try {
    return library.get(name);
  } catch (const InputError& e) {
    throw InputError(where, "unknown material '" + name + "'", e.what());
  }
}

}  // namespace blt::sim
