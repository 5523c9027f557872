// blt analytic chen-li: Chen-Li ballistic limit (and residual velocity) of a thick ductile plate.
#include <cmath>
#include <cstdio>
#include <memory>
#include <optional>
#include <sstream>
#include <stdexcept>

#include "blt/analytic/chen_li.hpp"
#include "blt/core/materials.hpp"
#include "cli_support.hpp"
#include "commands.hpp"

namespace blt::cli {

namespace {

struct ChenLiOptions {
  double thickness = 0, diameter = 0, mass = 0, density = 0, yield = 0;
  double noseAngle = 0, crh = 0, youngsModulus = 0, poissonRatio = 0, cavityConstant = 0, velocity = 0;
  std::string nose = "flat";
  std::string material;
  bool json = false;
};

void requireGiven(const CLI::App& cmd, const std::string& flag, const std::string& what, const std::string& allowed) {
  if (cmd.count(flag) == 0) throw InputError(InputLocation::flag(flag), what + " is required", allowed);
}

std::string plain(double value) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", value);
  return buf;
}

// unit "" for dimensionless values.
void requirePositive(double si, const std::string& flag, const std::string& unit, const std::string& what) {
  if (!(si > 0))
    throw InputError(InputLocation::flag(flag),
                     what + " must be positive, got " + (unit.empty() ? plain(si) : units::format(si, unit)),
                     "a value > 0");
}

analytic::NoseShape parseNose(const std::string& text) {
  if (text == "flat" || text == "blunt") return analytic::NoseShape::Flat;
  if (text == "hemispherical") return analytic::NoseShape::Hemispherical;
  if (text == "conical") return analytic::NoseShape::Conical;
  if (text == "ogival") return analytic::NoseShape::Ogival;
  throw InputError(InputLocation::flag("--nose"), "unknown nose shape '" + text + "'",
                   "flat (or blunt), hemispherical, conical, ogival");
}

void run(const CLI::App& cmd, const ChenLiOptions& o) {
  requireGiven(cmd, "--thickness", "the plate thickness", "e.g. --thickness 12mm");
  requireGiven(cmd, "--diameter", "the projectile diameter", "e.g. --diameter 20mm");
  requireGiven(cmd, "--mass", "the projectile mass", "e.g. --mass 0.197kg");
  requirePositive(o.thickness, "--thickness", "mm", "the plate thickness");
  requirePositive(o.diameter, "--diameter", "mm", "the projectile diameter");
  requirePositive(o.mass, "--mass", "kg", "the projectile mass");

  analytic::ChenLiInput in;
  in.plateThickness = o.thickness;
  in.projectileDiameter = o.diameter;
  in.projectileMass = o.mass;

  // Plate properties: a material card first, then any flag given overrides it.
  std::string yieldSource = "--yield";
  std::string densitySource = "--density";
  std::string elasticSource = "nu: default 0.3";
  double cardShearModulus = 0;
  if (!o.material.empty()) {
    const Material card = MaterialLibrary::load().get(o.material);
    const analytic::PlateProperties p = analytic::plateProperties(card);
    in.plateDensity = p.density;
    densitySource = "material " + o.material;
    in.plateYieldStress = p.yieldStress;
    yieldSource = "material " + o.material + " " + p.yieldSource;
    in.plateYoungsModulus = p.youngsModulus;
    cardShearModulus = p.shearModulus;
    if (p.poissonRatio > 0) {
      in.platePoissonRatio = p.poissonRatio;
      elasticSource = "nu: material " + o.material;
    }
  }
  if (cmd.count("--density")) {
    requirePositive(o.density, "--density", "kg/m3", "the plate density");
    in.plateDensity = o.density;
    densitySource = "--density";
  }
  if (cmd.count("--yield")) {
    requirePositive(o.yield, "--yield", "MPa", "the plate yield stress");
    in.plateYieldStress = o.yield;
    yieldSource = "--yield";
  }
  if (!(in.plateDensity > 0))
    throw InputError(InputLocation::flag("--density"), "the plate density is required",
                     "--density 7850kg/m3, or --material ID of a card with a density");
  if (!(in.plateYieldStress > 0))
    throw InputError(InputLocation::flag("--yield"), "the plate yield stress is required",
                     "--yield 490MPa, or --material ID of a card with [properties] yield_stress or a johnson-cook A");

  in.nose.shape = parseNose(o.nose);
  const bool conical = in.nose.shape == analytic::NoseShape::Conical;
  const bool ogival = in.nose.shape == analytic::NoseShape::Ogival;
  const bool sharp = in.nose.shape != analytic::NoseShape::Flat;
  if (cmd.count("--nose-angle") && !conical)
    throw InputError(InputLocation::flag("--nose-angle"), "a cone half-angle was given for a " + o.nose + " nose",
                     "--nose-angle only with --nose conical");
  if (cmd.count("--crh") && !ogival)
    throw InputError(InputLocation::flag("--crh"), "a caliber-radius-head was given for a " + o.nose + " nose",
                     "--crh only with --nose ogival");
  if (conical) {
    requireGiven(cmd, "--nose-angle", "the cone half-angle of a conical nose", "e.g. --nose-angle 30deg");
    const double deg = units::toUnit(o.noseAngle, "deg");
    if (!(deg > 0 && deg < 90))
      throw InputError(InputLocation::flag("--nose-angle"),
                       "the cone half-angle must lie between 0 and 90 deg, got " + units::format(o.noseAngle, "deg"),
                       "0 deg < angle < 90 deg, measured from the projectile axis");
    in.nose.coneHalfAngle = o.noseAngle;
  }
  if (ogival) {
    requireGiven(cmd, "--crh", "the caliber-radius-head of an ogival nose", "e.g. --crh 3");
    if (!(o.crh >= 0.5))
      throw InputError(InputLocation::flag("--crh"), "the caliber-radius-head must be at least 0.5, got " +
                           plain(o.crh), "psi >= 0.5 (0.5 is a hemisphere)");
    in.nose.caliberRadiusHead = o.crh;
  }

  if (cmd.count("--youngs-modulus")) {
    requirePositive(o.youngsModulus, "--youngs-modulus", "GPa", "the plate Young's modulus");
    in.plateYoungsModulus = o.youngsModulus;
  }
  if (cmd.count("--poisson-ratio")) {
    if (!(o.poissonRatio >= 0 && o.poissonRatio < 0.5))
      throw InputError(InputLocation::flag("--poisson-ratio"),
                       "the Poisson ratio must lie in [0, 0.5), got " + plain(o.poissonRatio),
                       "0 <= nu < 0.5");
    in.platePoissonRatio = o.poissonRatio;
    elasticSource = "nu: --poisson-ratio";
  }
  if (cmd.count("--youngs-modulus")) {
    elasticSource = "E: --youngs-modulus; " + elasticSource;
  } else if (in.plateYoungsModulus > 0) {
    elasticSource = "E: material " + o.material + "; " + elasticSource;
  } else if (cardShearModulus > 0) {
    // Cards of seed 002 give only G; E follows from the Poisson ratio chosen above.
    in.plateYoungsModulus = 2 * cardShearModulus * (1 + in.platePoissonRatio);
    elasticSource = "E = 2G(1+nu), G: material " + o.material + "; " + elasticSource;
  }
  if (cmd.count("--cavity-constant")) {
    requirePositive(o.cavityConstant, "--cavity-constant", "", "the cavity-expansion constant A");
    in.cavityConstant = o.cavityConstant;
  }
  if (sharp && !(in.cavityConstant > 0) && !(in.plateYoungsModulus > 0))
    throw InputError(InputLocation::flag("--youngs-modulus"),
                     "the " + o.nose + " nose (hole enlargement) needs the plate's Young's modulus for the "
                     "cavity-expansion constant A",
                     "--youngs-modulus 200GPa, --cavity-constant A, or --material ID of a card with [elastic]");

  std::optional<double> impactVelocity;
  if (cmd.count("--velocity")) {
    if (o.velocity < 0)
      throw InputError(InputLocation::flag("--velocity"),
                       "the impact velocity must not be negative, got " + units::format(o.velocity, "m/s"),
                       "a value >= 0");
    impactVelocity = o.velocity;
  }

  analytic::ChenLiResult r;
  try {
    r = analytic::chenLiBallisticLimit(in);
  } catch (const std::invalid_argument& e) {
    // Only combinations the flag checks above cannot see end here (e.g. E too small for the yield stress).
    throw InputError(InputLocation::flag(sharp ? "--youngs-modulus" : "--yield"), e.what());
  }
  const bool plugging = r.mechanism == analytic::PerforationMechanism::ShearPlugging;
  const std::string model = plugging ? "chen-li shear plugging" : "chen-li hole enlargement (cavity expansion)";

  if (o.json) {
    nlohmann::json doc = {
        {"model", model},
        {"nose", analytic::noseShapeName(in.nose.shape)},
        {"nose_factor", r.noseFactor},
        {"chi", r.chi},
        {"eta", r.eta},
        {"v_bl_m_s", r.ballisticLimit},
        {"thickness_m", in.plateThickness},
        {"diameter_m", in.projectileDiameter},
        {"mass_kg", in.projectileMass},
        {"density_kg_m3", in.plateDensity},
        {"yield_stress_Pa", in.plateYieldStress},
        {"yield_source", yieldSource},
    };
    if (!o.material.empty()) doc["material"] = o.material;
    if (conical) doc["nose_half_angle_deg"] = units::toUnit(in.nose.coneHalfAngle, "deg");
    if (ogival) doc["crh"] = in.nose.caliberRadiusHead;
    if (!plugging) {
      doc["cavity_constant_A"] = r.cavityConstant;
      doc["cavity_inertia_B"] = in.cavityInertia;
      doc["geometry_function_N"] = r.geometryFunction;
      doc["impact_function_at_limit"] = r.impactFunctionAtLimit;
      if (in.cavityConstant <= 0) {
        doc["youngs_modulus_Pa"] = in.plateYoungsModulus;
        doc["poisson_ratio"] = in.platePoissonRatio;
        doc["elastic_source"] = elasticSource;
      }
    }
    if (impactVelocity) {
      doc["impact_velocity_m_s"] = *impactVelocity;
      doc["v_r_m_s"] = analytic::chenLiResidualVelocity(r, *impactVelocity);
      doc["perforated"] = *impactVelocity > r.ballisticLimit;
    }
    printJson(doc);
    return;
  }

  std::ostringstream out;
  out << "Chen-Li, " << (plugging ? "shear plugging" : "ductile hole enlargement (cavity expansion)") << ", "
      << analytic::noseShapeName(in.nose.shape) << " nose";
  if (conical) out << " (half-angle " << units::format(in.nose.coneHalfAngle, "deg", 4) << ")";
  if (ogival) out << " (CRH " << in.nose.caliberRadiusHead << ")";
  out << "\n  plate " << units::format(in.plateThickness, "mm", 4) << ", density "
      << units::format(in.plateDensity, "kg/m3", 5) << " (" << densitySource << "), yield "
      << units::format(in.plateYieldStress, "MPa", 4) << " (" << yieldSource << ")\n"
      << "  projectile d = " << units::format(in.projectileDiameter, "mm", 4) << ", M = "
      << units::format(in.projectileMass, "kg", 4) << "\n"
      << "  chi = H/d = " << r.chi << ", eta = plug/projectile mass = " << r.eta << ", N* = " << r.noseFactor << "\n";
  if (!plugging && in.cavityConstant <= 0)
    out << "  E = " << units::format(in.plateYoungsModulus, "GPa", 4) << ", nu = " << in.platePoissonRatio << " ("
        << elasticSource << ")\n";
  if (!plugging)
    out << "  A = " << r.cavityConstant << ", B = " << in.cavityInertia << ", N = M/(N* rho d^3) = " << r.geometryFunction
        << ", I_BL = " << r.impactFunctionAtLimit << "\n";
  out << "  ballistic limit V_BL = " << units::format(r.ballisticLimit, "m/s", 4) << "\n";
  if (impactVelocity) {
    const double vr = analytic::chenLiResidualVelocity(r, *impactVelocity);
    out << "  at " << units::format(*impactVelocity, "m/s", 4) << ": "
        << (*impactVelocity > r.ballisticLimit ? "perforated, residual velocity V_r = " + units::format(vr, "m/s", 4)
                                               : std::string("no perforation (V_r = 0)"))
        << "\n";
  }
  std::cout << out.str();
}

}  // namespace

void registerChenLiCommand(CLI::App& analytic) {
  auto* cmd = analytic.add_subcommand(
      "chen-li",
      "Chen-Li ballistic limit of a thick ductile plate hit normally by a rigid projectile: shear plugging for a "
      "flat nose (seed 002 Eq. 20-21, theta = 0), cavity-expansion hole enlargement for sharp noses.\n"
      "Example: blt analytic chen-li --thickness 12mm --diameter 20mm --mass 0.197kg --density 7850kg/m3 "
      "--yield 490MPa --velocity 250m/s");
  auto o = std::make_shared<ChenLiOptions>();
  addQuantity(*cmd, "--thickness", o->thickness, units::length, "plate thickness H (required)");
  addQuantity(*cmd, "--diameter", o->diameter, units::length, "projectile diameter d (required)");
  addQuantity(*cmd, "--mass", o->mass, units::mass, "projectile mass M (required)");
  addQuantity(*cmd, "--density", o->density, units::density, "plate density rho (or from --material)");
  addQuantity(*cmd, "--yield", o->yield, units::pressure, "plate yield stress sigma_y (or from --material)");
  cmd->add_option("--material", o->material,
                  "plate material id in the material library (density, yield stress, E, nu); flags override it");
  cmd->add_option("--nose", o->nose, "nose shape: flat (default), hemispherical, conical, ogival");
  addQuantity(*cmd, "--nose-angle", o->noseAngle, units::angle, "cone half-angle from the axis (conical nose)");
  addQuantity(*cmd, "--crh", o->crh, units::dimensionless, "caliber-radius-head psi of an ogival nose (>= 0.5)");
  addQuantity(*cmd, "--youngs-modulus", o->youngsModulus, units::pressure,
              "plate Young's modulus E, for the cavity-expansion constant A (sharp noses)");
  addQuantity(*cmd, "--poisson-ratio", o->poissonRatio, units::dimensionless, "plate Poisson ratio (default 0.3)");
  addQuantity(*cmd, "--cavity-constant", o->cavityConstant, units::dimensionless,
              "cavity-expansion constant A, instead of (2/3)(1 + ln(E/(3(1-nu)sigma_y)))");
  addQuantity(*cmd, "--velocity", o->velocity, units::velocity, "impact velocity, for the residual velocity");
  addJsonFlag(*cmd, o->json);
  cmd->callback([cmd, o] { run(*cmd, *o); });
}

}  // namespace blt::cli
