// Chen-Li thick-plate perforation: shear plugging for blunt noses, cavity-expansion hole enlargement for
// sharp ones. The equations and their derivation are in chen_li.hpp.
#include "blt/analytic/chen_li.hpp"

#include <cmath>
#include <numbers>
#include <stdexcept>

namespace blt::analytic {

namespace {

void requirePositive(double value, const char* what) {
  if (!(value > 0) || !std::isfinite(value))
    throw std::invalid_argument(std::string("Chen-Li: ") + what + " must be positive and finite");
}

}  // namespace

std::string noseShapeName(NoseShape shape) {
  switch (shape) {
    case NoseShape::Flat: return "flat";
    case NoseShape::Hemispherical: return "hemispherical";
    case NoseShape::Conical: return "conical";
    case NoseShape::Ogival: return "ogival";
  }
  return "unknown";
}

double noseShapeFactor(const NoseGeometry& nose) {
  switch (nose.shape) {
    case NoseShape::Flat: return 1.0;
    case NoseShape::Hemispherical: return 0.5;
    case NoseShape::Conical: {
      const double theta = nose.coneHalfAngle;
      if (!(theta > 0 && theta < std::numbers::pi / 2))
        throw std::invalid_argument("Chen-Li: cone half-angle must lie strictly between 0 and 90 deg");
      const double s = std::sin(theta);
      return s * s;
    }
    case NoseShape::Ogival: {
      const double psi = nose.caliberRadiusHead;
      if (!(psi >= 0.5) || !std::isfinite(psi))
        throw std::invalid_argument("Chen-Li: caliber-radius-head must be at least 0.5");
      return (8 * psi - 1) / (24 * psi * psi);
    }
  }
  throw std::invalid_argument("Chen-Li: unknown nose shape");
}

double sphericalCavityConstant(double youngsModulus, double poissonRatio, double yieldStress) {
  requirePositive(youngsModulus, "Young's modulus");
  requirePositive(yieldStress, "yield stress");
  if (!(poissonRatio >= 0 && poissonRatio < 1))
    throw std::invalid_argument("Chen-Li: Poisson ratio must lie in [0, 1)");
  const double ratio = youngsModulus / (3 * (1 - poissonRatio) * yieldStress);
  // Below ratio = 1/e the formula would give A <= 0: the target would not be elastic-plastic in any sense.
  if (ratio <= std::exp(-1.0))
    throw std::invalid_argument("Chen-Li: E/(3(1-nu) sigma_y) is too small for the cavity-expansion model");
  return (2.0 / 3.0) * (1 + std::log(ratio));
}

ChenLiResult chenLiBallisticLimit(const ChenLiInput& in) {
  requirePositive(in.plateThickness, "plate thickness");
  requirePositive(in.projectileDiameter, "projectile diameter");
  requirePositive(in.projectileMass, "projectile mass");
  requirePositive(in.plateDensity, "plate density");
  requirePositive(in.plateYieldStress, "plate yield stress");

  const double pi = std::numbers::pi;
  const double H = in.plateThickness, d = in.projectileDiameter, M = in.projectileMass;
  const double rho = in.plateDensity, sigmaY = in.plateYieldStress;

  ChenLiResult r;
  r.chi = H / d;
  r.eta = rho * pi * d * d * H / (4 * M);
  r.noseFactor = noseShapeFactor(in.nose);

  if (in.nose.shape == NoseShape::Flat) {
    r.mechanism = PerforationMechanism::ShearPlugging;
    r.ballisticLimit = 2 * std::sqrt(2 * r.chi * r.eta * (1 + r.eta) / std::sqrt(3.0)) * std::sqrt(sigmaY / rho);
    return r;
  }

  r.mechanism = PerforationMechanism::HoleEnlargement;
  requirePositive(in.cavityInertia, "cavity-expansion inertia coefficient B");
  if (in.cavityConstant > 0) {
    r.cavityConstant = in.cavityConstant;
  } else {
    if (!(in.plateYoungsModulus > 0))
      throw std::invalid_argument("Chen-Li: a sharp nose needs the plate's Young's modulus or the constant A");
    r.cavityConstant = sphericalCavityConstant(in.plateYoungsModulus, in.platePoissonRatio, sigmaY);
  }
  const double A = r.cavityConstant, B = in.cavityInertia;
  r.geometryFunction = M / (r.noseFactor * rho * d * d * d);
  r.velocityDecayExponent = pi * B * r.chi / (2 * r.geometryFunction);
  // expm1 keeps the light-inertia limit (exponent -> 0) accurate.
  r.impactFunctionAtLimit = (r.geometryFunction / B) * std::expm1(r.velocityDecayExponent);
  r.ballisticLimit = std::sqrt(r.impactFunctionAtLimit * A * sigmaY * d * d * d / M);
  return r;
}

double chenLiResidualVelocity(const ChenLiResult& limit, double impactVelocity) {
  const double vi = impactVelocity, vbl = limit.ballisticLimit;
  if (!(vi > vbl)) return 0.0;
  const double excess = vi * vi - vbl * vbl;
  if (limit.mechanism == PerforationMechanism::ShearPlugging) return std::sqrt(excess) / (1 + limit.eta);
  return std::sqrt(excess * std::exp(-limit.velocityDecayExponent));
}

PlateProperties plateProperties(const Material& material) {
  PlateProperties p;
  p.density = material.density;
  if (material.has("properties", "yield_stress")) {
    p.yieldStress = material.param("properties", "yield_stress");
    p.yieldSource = "properties.yield_stress";
  } else if (material.has("strength", "A") && material.section("strength").model == "johnson-cook") {
    p.yieldStress = material.param("strength", "A");
    p.yieldSource = "strength.A (johnson-cook)";
  } else if (material.has("strength", "yield_stress")) {
    p.yieldStress = material.param("strength", "yield_stress");
    p.yieldSource = "strength.yield_stress (" + material.section("strength").model + ")";
  }
  if (material.has("elastic", "poisson_ratio")) p.poissonRatio = material.param("elastic", "poisson_ratio");
  if (material.has("elastic", "youngs_modulus")) p.youngsModulus = material.param("elastic", "youngs_modulus");
  if (material.has("elastic", "shear_modulus")) p.shearModulus = material.param("elastic", "shear_modulus");
  return p;
}

}  // namespace blt::analytic
