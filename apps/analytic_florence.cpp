// blt analytic florence: Florence's ballistic limit of a ceramic front plate on a ductile back plate.
#include <cstdio>
#include <memory>
#include <optional>
#include <sstream>
#include <stdexcept>

#include "blt/analytic/florence.hpp"
#include "blt/core/materials.hpp"
#include "cli_support.hpp"
#include "commands.hpp"

namespace blt::cli {

namespace {

struct FlorenceOptions {
  double projectileRadius = 0, projectileMass = 0;
  double ceramicThickness = 0, ceramicDensity = 0;
  double backingThickness = 0, backingDensity = 0, backingStrength = 0, backingFailureStrain = 0;
  double velocity = 0;
  std::string ceramicMaterial, backingMaterial;
  bool json = false;
};

std::string plain(double value) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", value);
  return buf;
}

// A value that must be present (from its flag, or from a material card when `fromCard` holds one) and
// positive (or, with allowZero, not negative). unit "" for dimensionless values.
double required(const CLI::App& cmd, const std::string& flag, double flagValue, std::optional<double> fromCard,
                const std::string& what, const std::string& unit, const std::string& example, bool allowZero = false) {
  double value = 0;
  if (cmd.count(flag)) {
    value = flagValue;
  } else if (fromCard) {
    value = *fromCard;
  } else {
    throw InputError(InputLocation::flag(flag), what + " is required", "e.g. " + flag + " " + example);
  }
  const bool ok = allowZero ? value >= 0 : value > 0;
  if (!ok)
    throw InputError(InputLocation::flag(flag),
                     what + " must be " + (allowZero ? "zero or positive" : "positive") + ", got " +
                         (unit.empty() ? plain(value) : units::format(value, unit)),
                     allowZero ? "a value >= 0" : "a value > 0");
  return value;
}

std::optional<double> cardValue(const Material* card, const std::string& section, const std::string& key) {
  if (card && card->has(section, key)) return card->param(section, key);
  return std::nullopt;
}

void run(const CLI::App& cmd, const FlorenceOptions& o) {
  std::optional<MaterialLibrary> library;
  auto card = [&](const std::string& id) -> const Material* {
    if (id.empty()) return nullptr;
    if (!library) library = MaterialLibrary::load();
    return &library->get(id);
  };
  const Material* ceramic = card(o.ceramicMaterial);
  const Material* backing = card(o.backingMaterial);
  auto density = [](const Material* m) { return m ? std::optional<double>(m->density) : std::nullopt; };

  analytic::FlorenceInput in;
  in.projectileRadius = required(cmd, "--projectile-radius", o.projectileRadius, std::nullopt, "the projectile radius",
                                 "mm", "10mm");
  in.projectileMass =
      required(cmd, "--projectile-mass", o.projectileMass, std::nullopt, "the projectile mass", "kg", "0.197kg");
  in.ceramicThickness = required(cmd, "--ceramic-thickness", o.ceramicThickness, std::nullopt,
                                 "the ceramic (front plate) thickness", "mm", "6mm", /*allowZero=*/true);
  if (in.ceramicThickness > 0)
    in.ceramicDensity = required(cmd, "--ceramic-density", o.ceramicDensity, density(ceramic),
                                 "the ceramic density", "kg/m3", "3227kg/m3");
  in.backingThickness = required(cmd, "--backing-thickness", o.backingThickness, std::nullopt,
                                 "the backing (back plate) thickness", "mm", "4mm");
  in.backingDensity = required(cmd, "--backing-density", o.backingDensity, density(backing), "the backing density",
                               "kg/m3", "2810kg/m3");
  in.backingTensileStrength =
      required(cmd, "--backing-strength", o.backingStrength, cardValue(backing, "properties", "tensile_strength"),
               "the backing's ultimate tensile strength", "MPa", "572MPa");
  in.backingFailureStrain = required(cmd, "--backing-failure-strain", o.backingFailureStrain,
                                     cardValue(backing, "properties", "failure_strain"),
                                     "the backing's breaking strain", "", "0.11");
  std::optional<double> impactVelocity;
  if (cmd.count("--velocity"))
    impactVelocity = required(cmd, "--velocity", o.velocity, std::nullopt, "the impact velocity", "m/s", "400m/s",
                              /*allowZero=*/true);

  const analytic::FlorenceResult r = analytic::florenceBallisticLimit(in);

  if (o.json) {
    nlohmann::json doc = {
        {"model", "florence"},
        {"v_bl_m_s", r.ballisticLimit},
        {"loaded_radius_m", r.loadedRadius},
        {"loaded_area_m2", r.loadedArea},
        {"target_mass_kg", r.targetMass},
        {"projectile_radius_m", in.projectileRadius},
        {"projectile_mass_kg", in.projectileMass},
        {"ceramic_thickness_m", in.ceramicThickness},
        {"ceramic_density_kg_m3", in.ceramicDensity},
        {"backing_thickness_m", in.backingThickness},
        {"backing_density_kg_m3", in.backingDensity},
        {"backing_strength_Pa", in.backingTensileStrength},
        {"backing_failure_strain", in.backingFailureStrain},
    };
    if (ceramic) doc["ceramic_material"] = o.ceramicMaterial;
    if (backing) doc["backing_material"] = o.backingMaterial;
    if (impactVelocity) {
      // Florence's model gives no residual velocity, so only the verdict is reported.
      doc["impact_velocity_m_s"] = *impactVelocity;
      doc["perforated"] = *impactVelocity > r.ballisticLimit;
    }
    printJson(doc);
    return;
  }

  std::ostringstream out;
  out << "Florence, ceramic " << units::format(in.ceramicThickness, "mm", 4) << " ("
      << units::format(in.ceramicDensity, "kg/m3", 5) << ") on backing " << units::format(in.backingThickness, "mm", 4)
      << " (" << units::format(in.backingDensity, "kg/m3", 5) << ", "
      << units::format(in.backingTensileStrength, "MPa", 4) << ", breaking strain " << in.backingFailureStrain << ")\n"
      << "  projectile R = " << units::format(in.projectileRadius, "mm", 4)
      << ", m = " << units::format(in.projectileMass, "kg", 4) << "\n"
      << "  load spread over radius R + 2 b1 = " << units::format(r.loadedRadius, "mm", 4)
      << ", target mass set in motion " << units::format(r.targetMass, "kg", 4) << "\n"
      << "  ballistic limit v_bl = " << units::format(r.ballisticLimit, "m/s", 4) << "\n";
  if (impactVelocity)
    out << "  at " << units::format(*impactVelocity, "m/s", 4) << ": "
        << (*impactVelocity > r.ballisticLimit ? "perforated" : "stopped")
        << " (Florence's model gives no residual velocity)\n";
  std::cout << out.str();
}

}  // namespace

void registerFlorenceCommand(CLI::App& analytic) {
  auto* cmd = analytic.add_subcommand(
      "florence",
      "Florence (1969) ballistic limit of a ceramic front plate on a ductile back plate, rigid projectile, normal "
      "impact (seed 002 Eq. 22).\n"
      "Example: blt analytic florence --projectile-radius 10mm --projectile-mass 0.197kg --ceramic-thickness 6mm "
      "--ceramic-density 3227kg/m3 --backing-thickness 4mm --backing-density 2810kg/m3 --backing-strength 572MPa "
      "--backing-failure-strain 0.11");
  auto o = std::make_shared<FlorenceOptions>();
  addQuantity(*cmd, "--projectile-radius", o->projectileRadius, units::length, "projectile radius R (required)");
  addQuantity(*cmd, "--projectile-mass", o->projectileMass, units::mass, "projectile mass m (required)");
  addQuantity(*cmd, "--ceramic-thickness", o->ceramicThickness, units::length,
              "front (ceramic) plate thickness b1 (required; 0 allowed)");
  addQuantity(*cmd, "--ceramic-density", o->ceramicDensity, units::density, "ceramic density rho1");
  addQuantity(*cmd, "--backing-thickness", o->backingThickness, units::length,
              "back (ductile) plate thickness b2 (required)");
  addQuantity(*cmd, "--backing-density", o->backingDensity, units::density, "back plate density rho2");
  addQuantity(*cmd, "--backing-strength", o->backingStrength, units::pressure,
              "back plate ultimate tensile strength sigma2");
  addQuantity(*cmd, "--backing-failure-strain", o->backingFailureStrain, units::dimensionless,
              "back plate breaking strain eps2");
  cmd->add_option("--ceramic-material", o->ceramicMaterial, "ceramic material id (gives its density)");
  cmd->add_option("--backing-material", o->backingMaterial,
                  "back plate material id (density, [properties] tensile_strength and failure_strain)");
  addQuantity(*cmd, "--velocity", o->velocity, units::velocity,
              "impact velocity: reports perforation or not (the model has no residual velocity)");
  addJsonFlag(*cmd, o->json);
  cmd->callback([cmd, o] { run(*cmd, *o); });
}

}  // namespace blt::cli
