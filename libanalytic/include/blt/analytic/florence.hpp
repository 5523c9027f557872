#pragma once
// Florence (1969) ballistic limit of a two-component armour: a ceramic front plate (1) on a ductile back
// plate (2), struck normally by a rigid projectile (seed 002 Eq. 22; REFERENCE.md §4).
//
//   v_bl^2 = eps2 sigma2 b2 z [ (rho1 b1 + rho2 b2) z + m ] / (0.91 m^2),   z = pi (R + 2 b1)^2      (SI)
//
// b1, b2 plate thicknesses; rho1, rho2 densities; sigma2 the back plate's ultimate tensile strength; eps2 its
// breaking strain; R the projectile radius; m the projectile mass.
//
// What the formula assumes:
//  - The ceramic breaks under the projectile into a fracture cone whose half-angle is about 63 deg
//    (tan = 2), so the load reaches the back plate spread over a disc of radius R + 2 b1 (area z).
//  - The projectile's momentum is shared with the cone and the back plate disc, of mass (rho1 b1 + rho2 b2) z;
//    the kinetic energy left after that exchange is what the back plate must absorb.
//  - The back plate absorbs it as a membrane stretched to its breaking strain eps2 at stress sigma2; the
//    factor 0.91 comes from the deflection profile assumed in Florence's analysis (taken as quoted in the
//    seed, not re-derived here).
//  - Rigid projectile (no erosion or mushrooming), normal impact, no energy spent in comminuting the ceramic.
// Units check: eps2 sigma2 b2 z kg / kg^2 = Pa m^3 / kg = m^2/s^2.
//
// There is no residual-velocity model in Florence's analysis; none is offered here.
// Seed 002 Eq. 24 is a "simplified" version with numbers inserted, but it puts the bracket
// [(rho1 b1 + rho2 b2) z + m] in the denominator, which is not dimensionally consistent with Eq. 22; its
// figures (38-44 m/s) are not used as a reference.

namespace blt::analytic {

struct FlorenceInput {
  double projectileRadius = 0;        // R, m
  double projectileMass = 0;          // m, kg
  double ceramicThickness = 0;        // b1, m (0 allowed: the back plate alone, z = pi R^2)
  double ceramicDensity = 0;          // rho1, kg/m^3
  double backingThickness = 0;        // b2, m
  double backingDensity = 0;          // rho2, kg/m^3
  double backingTensileStrength = 0;  // sigma2, Pa (ultimate tensile strength)
  double backingFailureStrain = 0;    // eps2, breaking strain (dimensionless)
};

struct FlorenceResult {
  double ballisticLimit = 0;    // v_bl, m/s
  double loadedRadius = 0;      // R + 2 b1, m: radius of the ceramic cone's base on the back plate
  double loadedArea = 0;        // z = pi (R + 2 b1)^2, m^2
  double targetMass = 0;        // (rho1 b1 + rho2 b2) z, kg: mass set in motion with the projectile
};

// Throws std::invalid_argument for a non-positive input (the ceramic thickness may be 0).
FlorenceResult florenceBallisticLimit(const FlorenceInput& input);

}  // namespace blt::analytic
