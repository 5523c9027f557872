#pragma once
// Built-in cases with known answers, shared by the verification tests, `blt bench sim` and `blt sim example`:
// the Taylor bar (Zerilli and Armstrong, J. Appl. Phys. 61 (1987) 1816: OFHC copper, L0 = 25.4 mm,
// D0 = 7.62 mm onto a rigid wall), and a normal impact of a cylinder on a thick plate for comparing 3D and
// axisymmetric runs. Lengths in m, speeds in m/s.

#include <memory>

#include "blt/core/materials.hpp"
#include "blt/sim/solver.hpp"

namespace blt::sim {

struct TaylorBarCase {
  double velocity = 190.0;      // m/s, onto the wall
  double length = 25.4e-3;      // m
  double diameter = 7.62e-3;    // m
  int particlesPerDiameter = 20;  // lattice spacing = diameter / particlesPerDiameter
  int particlesPerCell = 2;       // per axis: cell = particlesPerCell x spacing
  bool quarter = false;         // 3D only: a quarter model with two symmetry planes instead of the full bar
};

// The bar stands on the wall z = 0 (a symmetry face, frictionless) and moves towards it.
std::unique_ptr<Solver<2>> makeTaylorBarAxisymmetric(const TaylorBarCase& c, const Material& copper,
                                                     SolverOptions options = {});
std::unique_ptr<Solver<3>> makeTaylorBar3d(const TaylorBarCase& c, const Material& copper, SolverOptions options = {});

struct TaylorBarShape {
  double length = 0;             // m, top of the bar above the wall
  double footprintDiameter = 0;  // m, largest diameter of the layer touching the wall
};
// Measured on the particles' deformed domains (half-size scaled by the stretch along the axis).
template <int D>
TaylorBarShape measureTaylorBar(const Solver<D>& solver);

struct PlateImpactCase {
  double projectileDiameter = 4e-3, projectileLength = 4e-3;  // m, a cylinder along z
  double plateRadius = 10e-3, plateThickness = 12e-3;           // m (3D: half-width of a square plate)
  double velocity = 1000.0;                                     // m/s
  double spacing = 0.5e-3;                                      // m; cell = 2 x spacing
};
// Projectile (body 0) above a cylindrical plate (body 1) with free edges, moving in -z. 3D is a quarter model
// with symmetry planes x = 0 and y = 0, so both runs model the same solid of revolution.
std::unique_ptr<Solver<2>> makePlateImpactAxisymmetric(const PlateImpactCase& c, const Material& projectile,
                                                       const Material& plate, SolverOptions options = {});
std::unique_ptr<Solver<3>> makePlateImpact3d(const PlateImpactCase& c, const Material& projectile,
                                             const Material& plate, SolverOptions options = {});
// Depth of the crater: how far below the original plate surface the lowest projectile particle has gone, m.
template <int D>
double penetrationDepth(const Solver<D>& solver, double plateTop);

}  // namespace blt::sim
