#include "blt/analytic/laminate.hpp"

#include <nlopt.h>

#include <toml++/toml.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>
#include <stdexcept>

#include "blt/core/error.hpp"
#include "blt/core/units.hpp"

namespace blt::analytic {

// ---- Reading and writing stack files ------------------------------------------------------------------------

namespace {

int lineOf(const toml::node& n) { return static_cast<int>(n.source().begin.line); }

const toml::node& requireNode(const toml::table& t, const std::string& key, const InputLocation& at,
                              const std::string& field, const std::string& allowed) {
  const toml::node* node = t.get(key);
  if (!node) throw InputError(at.withField(field), "the required key is missing", allowed);
  return *node;
}

std::string readString(const toml::table& t, const std::string& key, const InputLocation& at,
                       const std::string& field) {
  const toml::node& node = requireNode(t, key, at, field, "a string");
  if (auto s = node.as_string()) return s->get();
  throw InputError(at.withLine(lineOf(node)).withField(field), "must be a string", "a string in quotes");
}

// A value with a unit ("0.018 mm") for a dimensioned key; a plain number (or a unitless string) for a
// dimensionless one. A dimensioned value given as a bare number is refused: the unit would be a guess.
double readQuantity(const toml::table& t, const std::string& key, units::Dimension dim, const InputLocation& at,
                    const std::string& field) {
  const toml::node& node = requireNode(t, key, at, field,
                                       dim == units::dimensionless
                                           ? std::string("a number")
                                           : "a " + units::describe(dim) + " such as \"" + units::example(dim) + "\"");
  const InputLocation here = at.withLine(lineOf(node)).withField(field);
  if (auto s = node.as_string()) return units::parse(s->get(), dim, here);
  if (auto v = node.value<double>()) {
    if (dim == units::dimensionless) return *v;
    char buf[64];
    std::snprintf(buf, sizeof buf, "%g", *v);
    throw InputError(here, std::string("the number ") + buf + " has no unit; a unit is required",
                     "a " + units::describe(dim) + " as a string, e.g. \"" + units::example(dim) + "\"");
  }
  throw InputError(here, "not a number or a quantity",
                   dim == units::dimensionless ? "a number" : "a string such as \"" + units::example(dim) + "\"");
}

std::string show(double si, units::Dimension dim) {
  if (dim == units::pressure) return units::format(si, "MPa");
  if (dim == units::length) return units::format(si, "mm");
  char buf[64];
  std::snprintf(buf, sizeof buf, "%g", si);
  return buf;
}

void requireRange(double value, bool ok, units::Dimension dim, const InputLocation& where, const std::string& allowed) {
  if (!ok) throw InputError(where, "the value " + show(value, dim) + " is out of range", allowed);
}

InputLocation keyLocation(const toml::table& t, const std::string& key, const InputLocation& at,
                          const std::string& field) {
  const toml::node* node = t.get(key);
  return node ? at.withLine(lineOf(*node)).withField(field) : at.withField(field);
}

void checkKnownKeys(const toml::table& t, const std::vector<std::string>& known, const InputLocation& at,
                    const std::string& prefix) {
  for (const auto& [keyNode, node] : t) {
    const std::string key(keyNode.str());
    if (std::find(known.begin(), known.end(), key) != known.end()) continue;
    std::string allowed;
    for (const auto& k : known) {
      if (!allowed.empty()) allowed += ", ";
      allowed += k;
    }
    throw InputError(at.withLine(lineOf(node)).withField(prefix + key), "unknown key", allowed);
  }
}

Layer readLayer(const toml::table& t, size_t index, const InputLocation& file) {
  const std::string p = "layer[" + std::to_string(index + 1) + "].";
  const InputLocation at = file.withLine(lineOf(t));
  checkKnownKeys(t,
                 {"material", "thickness", "youngs_modulus", "poisson_ratio", "yield_stress", "tangent_modulus",
                  "failure_strain"},
                 at, p);
  Layer layer;
  layer.line = lineOf(t);
  LayerMaterial& m = layer.material;
  m.name = readString(t, "material", at, p + "material");
  layer.thickness = readQuantity(t, "thickness", units::length, at, p + "thickness");
  m.youngsModulus = readQuantity(t, "youngs_modulus", units::pressure, at, p + "youngs_modulus");
  m.poissonRatio = readQuantity(t, "poisson_ratio", units::dimensionless, at, p + "poisson_ratio");
  m.yieldStress = readQuantity(t, "yield_stress", units::pressure, at, p + "yield_stress");
  m.tangentModulus = readQuantity(t, "tangent_modulus", units::pressure, at, p + "tangent_modulus");
  m.failureStrain = readQuantity(t, "failure_strain", units::dimensionless, at, p + "failure_strain");

  auto where = [&](const char* key) { return keyLocation(t, key, at, p + key); };
  requireRange(layer.thickness, layer.thickness > 0, units::length, where("thickness"), "a positive thickness");
  requireRange(m.youngsModulus, m.youngsModulus > 0, units::pressure, where("youngs_modulus"), "a positive modulus");
  requireRange(m.poissonRatio, m.poissonRatio > -1 && m.poissonRatio < 0.5, units::dimensionless,
               where("poisson_ratio"), "-1 < nu < 0.5");
  requireRange(m.yieldStress, m.yieldStress > 0, units::pressure, where("yield_stress"), "a positive stress");
  requireRange(m.tangentModulus, m.tangentModulus >= 0 && m.tangentModulus <= m.youngsModulus, units::pressure,
               where("tangent_modulus"), "0 <= E_t <= youngs_modulus (" + show(m.youngsModulus, units::pressure) + ")");
  requireRange(m.failureStrain, m.failureStrain > 0, units::dimensionless, where("failure_strain"),
               "a failure strain > 0");
  return layer;
}

CardData readCard(const toml::table& t, const InputLocation& file) {
  const InputLocation at = file.withLine(lineOf(t));
  checkKnownKeys(t, {"name", "source", "density", "c0", "s", "gamma0"}, at, "card.");
  CardData c;
  c.name = readString(t, "name", at, "card.name");
  c.source = readString(t, "source", at, "card.source");
  c.density = readQuantity(t, "density", units::density, at, "card.density");
  c.c0 = readQuantity(t, "c0", units::velocity, at, "card.c0");
  c.s = readQuantity(t, "s", units::dimensionless, at, "card.s");
  c.gamma0 = readQuantity(t, "gamma0", units::dimensionless, at, "card.gamma0");
  requireRange(c.density, c.density > 0, units::density, keyLocation(t, "density", at, "card.density"),
               "a positive density");
  requireRange(c.c0, c.c0 > 0, units::velocity, keyLocation(t, "c0", at, "card.c0"), "a positive sound speed");
  return c;
}

bool sameProperties(const LayerMaterial& a, const LayerMaterial& b) {
  return a.youngsModulus == b.youngsModulus && a.poissonRatio == b.poissonRatio && a.yieldStress == b.yieldStress &&
         a.tangentModulus == b.tangentModulus && a.failureStrain == b.failureStrain;
}

std::string quote(const std::string& s) {
  std::string q = "\"";
  for (char ch : s) {
    if (ch == '\n')
      q += "\\n";
    else
      q += (ch == '"' || ch == '\\') ? std::string("\\") + ch : std::string(1, ch);
  }
  return q + "\"";
}

std::string number(double v, int digits = 8) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*g", digits, v);
  return buf;
}

}  // namespace

double Stack::totalThickness() const {
  double t = 0;
  for (const auto& l : layers) t += l.thickness;
  return t;
}

Stack parseStack(const std::string& text, const std::string& sourceName) {
  const InputLocation file = InputLocation::file(sourceName);
  toml::table root;
  try {
    root = toml::parse(text, sourceName);
  } catch (const toml::parse_error& e) {
    throw InputError(file.withLine(static_cast<int>(e.source().begin.line)),
                     "not valid TOML: " + std::string(e.description()));
  }
  checkKnownKeys(root, {"name", "source", "notes", "layer", "card"}, file, "");
  Stack stack;
  stack.path = sourceName;
  stack.name = readString(root, "name", file, "name");
  stack.source = readString(root, "source", file, "source");
  if (root.get("notes")) stack.notes = readString(root, "notes", file, "notes");

  const toml::node& layersNode =
      requireNode(root, "layer", file, "layer", "one [[layer]] table per layer, in stacking order");
  const toml::array* layers = layersNode.as_array();
  if (!layers || layers->empty())
    throw InputError(file.withLine(lineOf(layersNode)).withField("layer"), "must be a non-empty array of tables",
                     "one [[layer]] table per layer, in stacking order");
  std::map<std::string, size_t> firstOfName;
  for (size_t i = 0; i < layers->size(); ++i) {
    const toml::node& node = *layers->get(i);
    const toml::table* t = node.as_table();
    if (!t)
      throw InputError(file.withLine(lineOf(node)).withField("layer[" + std::to_string(i + 1) + "]"),
                       "must be a table", "a [[layer]] table");
    Layer layer = readLayer(*t, i, file);
    auto [it, inserted] = firstOfName.emplace(layer.material.name, i);
    if (!inserted && !sameProperties(stack.layers[it->second].material, layer.material))
      throw InputError(file.withLine(layer.line).withField("layer[" + std::to_string(i + 1) + "].material"),
                       "material '" + layer.material.name + "' has other properties than in layer " +
                           std::to_string(it->second + 1),
                       "one set of properties per material name (rename the material if it differs)");
    stack.layers.push_back(std::move(layer));
  }
  if (const toml::node* cardNode = root.get("card")) {
    const toml::table* t = cardNode->as_table();
    if (!t) throw InputError(file.withLine(lineOf(*cardNode)).withField("card"), "must be a table", "a [card] table");
    stack.card = readCard(*t, file);
  }
  return stack;
}

Stack loadStack(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError(InputLocation::file(path), "cannot open the stack file", "a readable TOML file");
  std::stringstream buffer;
  buffer << in.rdbuf();
  return parseStack(buffer.str(), path);
}

std::string stackToToml(const Stack& stack, const std::string& headerComment) {
  std::ostringstream out;
  std::istringstream comment(headerComment);
  for (std::string line; std::getline(comment, line);) out << (line.empty() ? "#" : "# " + line) << "\n";
  if (!headerComment.empty()) out << "\n";
  out << "name = " << quote(stack.name) << "\n";
  out << "source = " << quote(stack.source) << "\n";
  if (!stack.notes.empty()) {
    if (stack.notes.find("'''") == std::string::npos)
      out << "notes = '''\n" << stack.notes << (stack.notes.back() == '\n' ? "" : "\n") << "'''\n";
    else
      out << "notes = " << quote(stack.notes) << "\n";
  }
  for (size_t i = 0; i < stack.layers.size(); ++i) {
    const Layer& l = stack.layers[i];
    const LayerMaterial& m = l.material;
    out << "\n[[layer]]  # " << i + 1 << "\n";
    out << "material = " << quote(m.name) << "\n";
    out << "thickness = " << quote(units::format(l.thickness, "mm", 10)) << "\n";
    out << "youngs_modulus = " << quote(units::format(m.youngsModulus, "MPa", 8)) << "\n";
    out << "poisson_ratio = " << number(m.poissonRatio) << "\n";
    out << "yield_stress = " << quote(units::format(m.yieldStress, "MPa", 8)) << "\n";
    out << "tangent_modulus = " << quote(units::format(m.tangentModulus, "MPa", 8)) << "\n";
    out << "failure_strain = " << number(m.failureStrain) << "\n";
  }
  if (stack.card) {
    const CardData& c = *stack.card;
    out << "\n[card]\n";
    out << "name = " << quote(c.name) << "\n";
    out << "source = " << quote(c.source) << "\n";
    out << "density = " << quote(units::format(c.density, "g/cm3", 8)) << "\n";
    out << "c0 = " << quote(units::format(c.c0, "m/s", 8)) << "\n";
    out << "s = " << number(c.s) << "\n";
    out << "gamma0 = " << number(c.gamma0) << "\n";
  }
  return out.str();
}

// ---- Stiffness ------------------------------------------------------------------------------------------------

namespace {

// Plane-stress stiffness of an isotropic layer (Eq. 3), scaled by `factor` (1 elastic, E_t/E yielded, 0
// failed, Eq. 6). Only Q11 = Q22 and Q12 matter: an isotropic stack under N_x alone has no shear strain.
struct PlaneStiffness {
  double q11 = 0, q12 = 0;
};

PlaneStiffness stiffness(const LayerMaterial& m, double factor) {
  const double d = 1.0 - m.poissonRatio * m.poissonRatio;
  return {factor * m.youngsModulus / d, factor * m.poissonRatio * m.youngsModulus / d};
}

// A = sum t_k Q_k (Eq. 2 per unit width). A11 = A22 for in-plane isotropic layers.
struct InPlaneStiffness {
  double a11 = 0, a12 = 0;
};

}  // namespace

EquivalentElastic equivalentElastic(const std::vector<Layer>& layers) {
  InPlaneStiffness a;
  double t = 0;
  for (const auto& l : layers) {
    const PlaneStiffness q = stiffness(l.material, 1.0);
    a.a11 += l.thickness * q.q11;
    a.a12 += l.thickness * q.q12;
    t += l.thickness;
  }
  EquivalentElastic e;
  e.thickness = t;
  if (a.a11 <= 0 || t <= 0) return e;
  // Eq. 4: A = t [E/(1-nu^2), nu E/(1-nu^2)] gives nu = A12/A11 and E = (A11^2 - A12^2)/(A11 t).
  e.poissonRatio = a.a12 / a.a11;
  e.youngsModulus = (a.a11 * a.a11 - a.a12 * a.a12) / (a.a11 * t);
  return e;
}

// ---- Progressive failure ---------------------------------------------------------------------------------------

namespace {

enum class LayerState { elastic, yielded, failed };

struct LayerTrack {
  LayerState state = LayerState::elastic;
  double sx = 0, sy = 0;  // layer stresses, Pa (no shear under N_x alone)
};

double tangentFactor(const Layer& l, LayerState s) {
  switch (s) {
    case LayerState::elastic: return 1.0;
    case LayerState::yielded: return l.material.tangentModulus / l.material.youngsModulus;
    case LayerState::failed: return 0.0;
  }
  return 0.0;
}

double vonMisesSquared(double sx, double sy) { return sx * sx + sy * sy - sx * sy; }

// Smallest increment h >= 0 of the laminate strain eps_x at which the layer's von Mises stress, growing as
// (sx, sy) + h (gx, gy), reaches `yield`; infinity when it never does.
double strainToYield(double sx, double sy, double gx, double gy, double yield) {
  const double c = vonMisesSquared(sx, sy) - yield * yield;
  if (c >= 0) return 0.0;
  const double a = gx * gx + gy * gy - gx * gy;  // >= 0: the von Mises form is positive semi-definite
  const double b = 2 * sx * gx + 2 * sy * gy - sx * gy - sy * gx;
  if (a <= 0) return std::numeric_limits<double>::infinity();
  // c < 0 < a: one positive root.
  return (-b + std::sqrt(b * b - 4 * a * c)) / (2 * a);
}

std::string layerList(const std::vector<size_t>& layers) {
  std::string s;
  for (size_t i : layers) {
    if (!s.empty()) s += ' ';
    s += std::to_string(i + 1);
  }
  return s;
}

}  // namespace

double LaminateResponse::stressAt(double strain) const {
  if (curve.empty() || strain <= curve.front().strain) return curve.empty() ? 0.0 : curve.front().stress;
  for (size_t i = 1; i < curve.size(); ++i) {
    const CurvePoint& p0 = curve[i - 1];
    const CurvePoint& p1 = curve[i];
    if (strain <= p1.strain) {
      if (p1.strain == p0.strain) return p0.stress;
      return p0.stress + (p1.stress - p0.stress) * (strain - p0.strain) / (p1.strain - p0.strain);
    }
  }
  return 0.0;  // beyond the last failure nothing carries load
}

LaminateResponse analyseLaminate(const std::vector<Layer>& layers) {
  if (layers.empty()) throw std::invalid_argument("analyseLaminate: the stack has no layers");
  LaminateResponse r;
  r.elastic = equivalentElastic(layers);
  const double t = r.elastic.thickness;
  const size_t n = layers.size();
  std::vector<LayerTrack> track(n);
  double ex = 0, ey = 0;
  r.curve.push_back({0.0, 0.0, ""});

  auto averageStress = [&] {
    double nx = 0;
    for (size_t k = 0; k < n; ++k) nx += layers[k].thickness * track[k].sx;
    return nx / t;
  };
  auto tangentStiffness = [&] {
    std::vector<PlaneStiffness> q(n);
    InPlaneStiffness a;
    for (size_t k = 0; k < n; ++k) {
      q[k] = stiffness(layers[k].material, tangentFactor(layers[k], track[k].state));
      a.a11 += layers[k].thickness * q[k].q11;
      a.a12 += layers[k].thickness * q[k].q12;
    }
    return std::pair{q, a};
  };

  // Each pass advances to the next event(s) with the current tangent stiffness (Eq. 7-8), so every layer's
  // stress is the sum of its increments, never Q_k times the total strain.
  for (;;) {
    auto [q, a] = tangentStiffness();
    if (a.a11 <= 0) break;  // every layer has failed
    // N_y = 0 for the increment: d eps_y = -(A12/A22) d eps_x.
    const double ratio = -a.a12 / a.a11;
    struct Candidate {
      double step;
      size_t layer;
      LayerEventKind kind;
    };
    std::vector<Candidate> candidates;
    for (size_t k = 0; k < n; ++k) {
      if (track[k].state == LayerState::failed) continue;
      const double gx = q[k].q11 + q[k].q12 * ratio;
      const double gy = q[k].q12 + q[k].q11 * ratio;
      if (track[k].state == LayerState::elastic)
        candidates.push_back({strainToYield(track[k].sx, track[k].sy, gx, gy, layers[k].material.yieldStress), k,
                              LayerEventKind::yield});
      // Largest principal strain of the laminate: max(eps_x, eps_y) with no shear strain.
      const double ef = layers[k].material.failureStrain;
      double step = std::max(ef - ex, 0.0);
      if (ratio > 0) step = std::min(step, std::max((ef - ey) / ratio, 0.0));
      candidates.push_back({step, k, LayerEventKind::failure});
    }
    double h = std::numeric_limits<double>::infinity();
    for (const auto& c : candidates) h = std::min(h, c.step);
    if (!std::isfinite(h)) break;

    // Advance to the event strain.
    for (size_t k = 0; k < n; ++k) {
      if (track[k].state == LayerState::failed) continue;
      track[k].sx += h * (q[k].q11 + q[k].q12 * ratio);
      track[k].sy += h * (q[k].q12 + q[k].q11 * ratio);
    }
    ex += h;
    ey += h * ratio;
    const double before = averageStress();

    // Layers reaching their limit together (same material, or a coincidence) make one kink. Yields are applied
    // before failures so a layer that does both at once ends failed.
    const double tol = 1e-12 * std::max(ex, 1e-12);
    std::map<std::pair<int, std::string>, std::vector<size_t>> groups;  // (kind, material) -> layers
    std::vector<size_t> failedNow;
    for (int pass = 0; pass < 2; ++pass) {
      const LayerEventKind kind = pass == 0 ? LayerEventKind::yield : LayerEventKind::failure;
      for (const auto& c : candidates) {
        if (c.kind != kind || c.step > h + tol) continue;
        if (kind == LayerEventKind::yield) {
          track[c.layer].state = LayerState::yielded;
        } else {
          track[c.layer].state = LayerState::failed;
          failedNow.push_back(c.layer);
        }
        groups[{pass, layers[c.layer].material.name}].push_back(c.layer);
      }
    }
    // A failed layer drops its stress. Its share of N_y is released too, so eps_y re-settles (at fixed eps_x)
    // on the remaining layers' tangent stiffness to keep N_y = 0.
    if (!failedNow.empty()) {
      for (size_t k : failedNow) track[k].sx = track[k].sy = 0;
      auto [q2, a2] = tangentStiffness();
      if (a2.a11 > 0) {
        double ny = 0;
        for (size_t k = 0; k < n; ++k) ny += layers[k].thickness * track[k].sy;
        const double dey = -ny / a2.a11;
        for (size_t k = 0; k < n; ++k) {
          if (track[k].state == LayerState::failed) continue;
          track[k].sx += q2[k].q12 * dey;
          track[k].sy += q2[k].q11 * dey;
        }
        ey += dey;
      }
    }
    const double after = averageStress();

    std::string label;
    for (const auto& [key, members] : groups) {
      const LayerEventKind kind = key.first == 0 ? LayerEventKind::yield : LayerEventKind::failure;
      for (size_t k : members)
        r.events.push_back({kind, k, key.second, ex, before, kind == LayerEventKind::failure ? after : before});
      if (!label.empty()) label += "; ";
      label += (kind == LayerEventKind::yield ? "yield " : "failure ") +
               key.second + " (layer" + (members.size() > 1 ? "s " : " ") + layerList(members) + ")";
    }
    r.curve.push_back({ex, before, label});
    if (!failedNow.empty()) r.curve.push_back({ex, after, "after " + label});
  }

  // Figures of the equivalent material (seed 000 §3.3).
  std::vector<const LayerEvent*> yieldKinks;  // first event of each distinct yield strain before d
  const LayerEvent* firstFailure = nullptr;
  for (const auto& e : r.events) {
    if (e.kind == LayerEventKind::failure) {
      firstFailure = &e;
      break;
    }
    if (yieldKinks.empty() || e.strain > yieldKinks.back()->strain) yieldKinks.push_back(&e);
  }
  for (const auto& p : r.curve) r.peakStress = std::max(r.peakStress, p.stress);
  if (firstFailure) {
    r.limitStress = firstFailure->stress;
    r.failureStrain = firstFailure->strain;
  }
  if (!yieldKinks.empty()) {
    r.firstYieldStress = yieldKinks.front()->stress;
    r.firstYieldStrain = yieldKinks.front()->strain;
  }
  if (firstFailure && !yieldKinks.empty()) {
    const LayerEvent* from = yieldKinks.size() >= 2 ? yieldKinks[1] : yieldKinks[0];
    r.tangentFrom = yieldKinks.size() >= 2 ? "b (second yield)" : "a (first yield)";
    r.tangentModulus = (firstFailure->stress - from->stress) / (firstFailure->strain - from->strain);
  } else {
    r.tangentFrom = "none";
  }
  return r;
}

// ---- Recovering the stacking -------------------------------------------------------------------------------------

std::vector<LayerMaterial> distinctMaterials(const std::vector<Layer>& layers) {
  std::vector<LayerMaterial> out;
  for (const auto& l : layers)
    if (std::none_of(out.begin(), out.end(), [&](const LayerMaterial& m) { return m.name == l.material.name; }))
      out.push_back(l.material);
  return out;
}

namespace {

struct RecoveryProblem {
  const std::vector<LayerMaterial>* materials;
  StackTarget target;
  StackRecoveryOptions options;
  int evaluations = 0;
};

std::vector<Layer> slabs(const std::vector<LayerMaterial>& materials, const double* thickness) {
  std::vector<Layer> layers;
  for (size_t i = 0; i < materials.size(); ++i) layers.push_back({materials[i], thickness[i], 0});
  return layers;
}

// x_i is material i's total thickness divided by the target thickness, so all variables are O(1).
double recoveryObjective(unsigned count, const double* x, double* grad, void* data) {
  (void)grad;  // derivative-free algorithm
  auto* p = static_cast<RecoveryProblem*>(data);
  ++p->evaluations;
  std::vector<double> t(x, x + count);
  for (double& ti : t) ti *= p->target.thickness;
  const EquivalentElastic e = equivalentElastic(slabs(*p->materials, t.data()));
  if (e.youngsModulus <= 0) return 1e3;  // an empty stack: far from any target
  const double rE = e.youngsModulus / p->target.youngsModulus - 1.0;
  const double rNu = (e.poissonRatio - p->target.poissonRatio) / p->target.poissonRatio;
  const double rT = e.thickness / p->target.thickness - 1.0;
  return p->options.weightModulus * rE * rE + p->options.weightPoisson * rNu * rNu +
         p->options.weightThickness * rT * rT;
}

}  // namespace

StackRecovery recoverStacking(const std::vector<LayerMaterial>& materials, const StackTarget& target,
                              const StackRecoveryOptions& options) {
  if (materials.empty()) throw std::invalid_argument("recoverStacking: no materials");
  if (!(target.youngsModulus > 0) || !(target.thickness > 0) || target.poissonRatio == 0)
    throw std::invalid_argument("recoverStacking: the target needs E > 0, t > 0 and nu != 0");
  const unsigned count = static_cast<unsigned>(materials.size());
  RecoveryProblem problem{&materials, target, options, 0};

  nlopt_opt opt = nlopt_create(NLOPT_LN_BOBYQA, count);
  std::vector<double> lower(count, 0.0), upper(count, 1.0), x(count, 1.0 / count);
  nlopt_set_lower_bounds(opt, lower.data());
  nlopt_set_upper_bounds(opt, upper.data());
  nlopt_set_min_objective(opt, recoveryObjective, &problem);
  nlopt_set_xtol_rel(opt, options.relativeTolerance);
  nlopt_set_ftol_abs(opt, 1e-30);
  nlopt_set_maxeval(opt, options.maxEvaluations);
  std::vector<double> step(count, 0.1);
  nlopt_set_initial_step(opt, step.data());
  double best = 0;
  const nlopt_result status = nlopt_optimize(opt, x.data(), &best);
  nlopt_destroy(opt);
  if (status < 0) throw std::runtime_error("recoverStacking: NLopt failed with code " + std::to_string(status));

  StackRecovery r;
  r.materials = materials;
  for (double xi : x) r.totalThickness.push_back(xi * target.thickness);
  r.achieved = equivalentElastic(slabs(materials, r.totalThickness.data()));
  r.residualModulus = r.achieved.youngsModulus / target.youngsModulus - 1.0;
  r.residualPoisson = r.achieved.poissonRatio - target.poissonRatio;
  r.residualThickness = r.achieved.thickness / target.thickness - 1.0;
  r.evaluations = problem.evaluations;
  r.algorithm = "NLopt LN_BOBYQA";
  return r;
}

std::vector<Layer> layOut(const std::vector<Layer>& pattern, const StackRecovery& recovery) {
  std::vector<Layer> out = pattern;
  for (size_t i = 0; i < recovery.materials.size(); ++i) {
    const std::string& name = recovery.materials[i].name;
    const auto count = std::count_if(pattern.begin(), pattern.end(),
                                     [&](const Layer& l) { return l.material.name == name; });
    for (auto& l : out)
      if (l.material.name == name) l.thickness = recovery.totalThickness[i] / static_cast<double>(count);
  }
  for (const auto& l : out)
    if (std::none_of(recovery.materials.begin(), recovery.materials.end(),
                     [&](const LayerMaterial& m) { return m.name == l.material.name; }))
      throw std::invalid_argument("layOut: material '" + l.material.name + "' is not in the recovery");
  return out;
}

}  // namespace blt::analytic

namespace blt::analytic {

Material equivalentMaterialCard(const Stack& stack, const LaminateResponse& response, const std::string& id) {
  const InputLocation file = InputLocation::file(stack.path.empty() ? std::string("(stack)") : stack.path);
  if (!stack.card)
    throw InputError(file.withField("card"), "the stack has no [card] table, so density and EOS are unknown",
                     "a [card] table with name, source, density, c0, s, gamma0");
  if (response.firstYieldStress <= 0 || response.failureStrain <= 0)
    throw InputError(file.withField("layer"), "no layer yields before the first ply failure",
                     "a stack whose layers yield before they fail (bilinear card)");
  const CardData& c = *stack.card;
  Material m;
  m.id = id;
  m.name = c.name;
  m.source = "laminate equivalent (seed 000 §3, Eq. 1-8) of " + (stack.path.empty() ? stack.name : stack.path) +
             "; density and EOS: " + c.source;
  m.path = stack.path;
  m.density = c.density;
  MaterialSection elastic;
  elastic.params = {{"youngs_modulus", response.elastic.youngsModulus},
                    {"poisson_ratio", response.elastic.poissonRatio}};
  MaterialSection strength;
  strength.model = "bilinear";
  strength.params = {{"yield_stress", response.firstYieldStress}, {"tangent_modulus", response.tangentModulus}};
  MaterialSection failure;
  failure.model = "max-principal-strain";
  failure.params = {{"max_principal_strain", response.failureStrain}};
  MaterialSection eos;
  eos.model = "mie-grueneisen";
  eos.params = {{"c0", c.c0}, {"s", c.s}, {"gamma0", c.gamma0}};
  MaterialSection properties;
  properties.params = {{"thickness", response.elastic.thickness},
                       {"yield_stress", response.firstYieldStress},
                       {"failure_strain", response.failureStrain},
                       {"tensile_strength", response.limitStress}};
  m.sections = {{"elastic", elastic}, {"strength", strength}, {"failure", failure}, {"eos", eos},
                {"properties", properties}};
  return m;
}

}  // namespace blt::analytic
