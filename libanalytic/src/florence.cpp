// Florence's ceramic/metal two-plate ballistic limit; the model and its assumptions are in florence.hpp.
#include "blt/analytic/florence.hpp"

#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

namespace blt::analytic {

namespace {

void requirePositive(double value, const char* what) {
  if (!(value > 0) || !std::isfinite(value))
    throw std::invalid_argument(std::string("Florence: ") + what + " must be positive and finite");
}

}  // namespace

FlorenceResult florenceBallisticLimit(const FlorenceInput& in) {
  requirePositive(in.projectileRadius, "projectile radius");
  requirePositive(in.projectileMass, "projectile mass");
  if (!(in.ceramicThickness >= 0) || !std::isfinite(in.ceramicThickness))
    throw std::invalid_argument("Florence: ceramic thickness must be zero or positive");
  if (in.ceramicThickness > 0) requirePositive(in.ceramicDensity, "ceramic density");
  requirePositive(in.backingThickness, "backing thickness");
  requirePositive(in.backingDensity, "backing density");
  requirePositive(in.backingTensileStrength, "backing tensile strength");
  requirePositive(in.backingFailureStrain, "backing failure strain");

  FlorenceResult r;
  const double m = in.projectileMass;
  r.loadedRadius = in.projectileRadius + 2 * in.ceramicThickness;
  r.loadedArea = std::numbers::pi * r.loadedRadius * r.loadedRadius;
  r.targetMass = (in.ceramicDensity * in.ceramicThickness + in.backingDensity * in.backingThickness) * r.loadedArea;
  const double vSquared = in.backingFailureStrain * in.backingTensileStrength * in.backingThickness * r.loadedArea *
                          (r.targetMass + m) / (0.91 * m * m);
  r.ballisticLimit = std::sqrt(vSquared);
  return r;
}

}  // namespace blt::analytic
