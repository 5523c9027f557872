#pragma once
// Chen-Li ballistic limit of a thick ductile plate struck normally by a rigid projectile (Chen & Li 2003,
// as quoted in seed 002 Eq. 20-21; REFERENCE.md §4). Two perforation mechanisms, chosen by the nose:
//
//   flat (blunt) nose  -> shear plugging            (seed 002 Eq. 20-21 with its undefined theta set to 0)
//   hemispherical, conical, ogival (sharp) nose -> ductile hole enlargement (dynamic cavity expansion)
//
// Notation (SI): H plate thickness, d projectile diameter, M projectile mass, rho plate density, sigma_y plate
// yield stress.  chi = H/d,  eta = rho pi d^2 H / (4 M)  (mass of a plug of the projectile's diameter over M).
//
// ---- Shear plugging (flat nose): derivation of the implemented formulas ---------------------------------
//  1. The plug is the cylinder of plate under the projectile, mass m = rho pi d^2 H / 4 = eta M.
//  2. Impact: projectile and plug take a common velocity at once (perfectly plastic collision, momentum kept):
//     V0 = V_i / (1 + eta).  Kinetic energy left: (1/2) M V_i^2 / (1 + eta); the rest is lost in the impact.
//  3. Plugging: the plug is sheared out on its side surface pi d H by tau = sigma_y / sqrt(3) (von Mises pure
//     shear), taken to act on that whole area while the plug moves through a distance H:  W = tau pi d H^2.
//  4. Ballistic limit: (1/2) M V_BL^2 / (1 + eta) = W.  With pi d H^2 / M = 4 eta chi / rho this gives
//        V_BL = 2 sqrt( 2 chi eta (1 + eta) / sqrt(3) ) sqrt( sigma_y / rho )           (seed Eq. 20, theta = 0)
//  5. Above it projectile and plug leave together: (1/2)(1 + eta) M V_r^2 = (1/2) M V_i^2 / (1 + eta) - W, so
//        V_r = sqrt( V_i^2 - V_BL^2 ) / (1 + eta)                                     (seed Eq. 21, theta = 0)
//  Remark: if the sheared area shrank in proportion to the remaining ligament, W would halve and V_BL drop by
//  sqrt(2) (122 m/s instead of 173 m/s for the 12 mm Weldox 460E case of REFERENCE §4, measured 184.5 m/s);
//  seed Eq. 20 corresponds to the full-area version of step 3.  The seed's theta (which enters as eta + theta)
//  is not defined there and is not modelled here.
//
// ---- Ductile hole enlargement (sharp noses): what is implemented --------------------------------------
//  Normal stress on the nose from the spherical dynamic cavity expansion of an elastic-perfectly plastic
//  target:  sigma_n = A sigma_y + B rho v_n^2, v_n the normal component of the surface velocity.
//    A = (2/3) (1 + ln( E / (3 (1 - nu) sigma_y) ))   quasi-static spherical cavity pressure (Hill 1950);
//    B = 3/2                                           incompressible dynamic spherical cavity (Forrestal et al.)
//  A frictionless nose of revolution then feels the axial force F = (pi d^2 / 4)(A sigma_y + B N* rho V^2),
//  with the nose-shape factor N* = (2/a^2) * integral_0^a n_x(r)^2 r dr (a = d/2, n_x the axial component of
//  the surface normal):  1 flat, 1/2 hemispherical, sin^2(theta0) cone of half-angle theta0,
//  (8 psi - 1)/(24 psi^2) tangent ogive of caliber-radius-head psi (the known Forrestal expression; checked
//  against the integral in tests/test_chen_li.cpp).
//  Each layer of the plate is opened once from radius 0 to d/2, so the quasi-static work per unit thickness
//  is (pi d^2/4) A sigma_y whatever the nose length; the equation of motion M V dV/dx = -F is therefore
//  integrated over a travel H.  With Chen and Li's dimensionless groups
//    impact function I = M V^2 / (A sigma_y d^3),   geometry function N = M / (N* rho d^3),
//  this gives
//    I_BL = (N / B) [ exp( pi B chi / (2 N) ) - 1 ],   i.e.  V_BL^2 = A sigma_y / (B N* rho) [exp(pi B chi/(2N)) - 1]
//    V_r^2 = (V_i^2 - V_BL^2) exp( -pi B chi / (2 N) )
//  For light inertia (N -> infinity) I_BL -> pi chi / 2: (1/2) M V_BL^2 = A sigma_y pi d^2 H / 4.
//  Assumptions and range: rigid projectile, normal impact, thick plate (chi of order 0.5 or more, nose
//  length below H), no friction, no global bending or dishing of the plate, sigma_y a single flow stress (no
//  hardening or rate effects beyond what the user puts into it).  The reduced resistance near the free
//  surfaces (front crater, rear bulge, petals or a final plug) is ignored, which tends to raise V_BL.
//  Not verified (the Chen & Li 2003 paper is not among our sources): whether their sharp-nose formula has
//  additional terms for the rear plug or structural response, which cavity-expansion constant A they use
//  for metals, and whether their N* already contains B.  The equations above are our own reconstruction
//  from the cavity-expansion model; treat the sharp-nose figures as an estimate.

#include <string>

#include "blt/core/materials.hpp"

namespace blt::analytic {

enum class NoseShape { Flat, Hemispherical, Conical, Ogival };

// "flat", "hemispherical", "conical", "ogival".
std::string noseShapeName(NoseShape shape);

struct NoseGeometry {
  NoseShape shape = NoseShape::Flat;
  double coneHalfAngle = 0;         // rad, conical only: angle between cone surface and axis, in (0, pi/2)
  double caliberRadiusHead = 0;     // psi = ogive radius / d, ogival only, >= 0.5 (0.5 is a hemisphere)
};

// Chen and Li's nose-shape factor N* (see above). Throws std::invalid_argument for an angle or CRH out of range.
double noseShapeFactor(const NoseGeometry& nose);

// Hill's quasi-static spherical cavity-expansion pressure over the yield stress,
// A = (2/3)(1 + ln(E / (3 (1 - nu) sigma_y))).
double sphericalCavityConstant(double youngsModulus, double poissonRatio, double yieldStress);

struct ChenLiInput {
  double plateThickness = 0;       // H, m
  double projectileDiameter = 0;   // d, m
  double projectileMass = 0;       // M, kg
  double plateDensity = 0;         // rho, kg/m^3
  double plateYieldStress = 0;     // sigma_y, Pa
  NoseGeometry nose;               // default: flat (shear plugging)
  // Sharp noses only. A is taken from cavityConstant when > 0, else from E and nu (then E is required).
  double plateYoungsModulus = 0;   // E, Pa
  double platePoissonRatio = 0.3;  // nu
  double cavityConstant = 0;       // A; 0 = compute from E, nu, sigma_y
  double cavityInertia = 1.5;      // B; incompressible spherical cavity expansion
};

enum class PerforationMechanism { ShearPlugging, HoleEnlargement };

struct ChenLiResult {
  PerforationMechanism mechanism = PerforationMechanism::ShearPlugging;
  double ballisticLimit = 0;  // V_BL, m/s
  double chi = 0;             // H/d
  double eta = 0;             // plug mass / projectile mass
  double noseFactor = 1;      // N*
  // Hole enlargement only (0 for plugging):
  double cavityConstant = 0;            // A
  double geometryFunction = 0;          // N = M / (N* rho d^3)
  double impactFunctionAtLimit = 0;     // I_BL = M V_BL^2 / (A sigma_y d^3)
  double velocityDecayExponent = 0;     // pi B chi / (2 N): V_r^2 = (V_i^2 - V_BL^2) exp(-this)
};

// Ballistic limit and the dimensionless groups. Throws std::invalid_argument for non-positive sizes,
// masses, densities or strengths, or a sharp nose without A or E.
ChenLiResult chenLiBallisticLimit(const ChenLiInput& input);

// Residual velocity of the projectile (and plug, for plugging) at impact velocity vi; 0 at or below V_BL.
double chenLiResidualVelocity(const ChenLiResult& limit, double impactVelocity);

// Plate properties read from a material card, with where each came from (for the output).
struct PlateProperties {
  double density = 0;
  double yieldStress = 0;      // 0 when the card has none
  double youngsModulus = 0;    // 0 when the card has none
  double shearModulus = 0;     // 0 when the card has none
  double poissonRatio = 0;     // 0 when the card has none
  std::string yieldSource;     // "properties.yield_stress", "strength.A (johnson-cook)", ...
};

// Density; yield stress from [properties] yield_stress, else the Johnson-Cook A, else the bilinear
// yield_stress; E, G and nu from [elastic] as given (E is not derived here: a card with only G needs a nu,
// which the caller chooses, E = 2 G (1 + nu)).
PlateProperties plateProperties(const Material& material);

}  // namespace blt::analytic
