#include "blt/sim/cases.hpp"

#include <algorithm>
#include <cmath>

#include "blt/sim/geometry.hpp"

namespace blt::sim {

std::unique_ptr<Solver<2>> makeTaylorBarAxisymmetric(const TaylorBarCase& c, const Material& copper,
                                                     SolverOptions options) {
  const double s = c.diameter / c.particlesPerDiameter;
  const double h = c.particlesPerCell * s;
  const double radius = 0.5 * c.diameter;
  GridSpec<2> grid;
  grid.cellSize = h;
  grid.lower = Vec<2>(0.0, 0.0);
  // Room for the footprint to spread to about twice the radius, and for the bar's length.
  grid.upper = Vec<2>(2.5 * radius + 2 * h, c.length + 2 * h);
  grid.boundary = {BoundaryKind::symmetry, BoundaryKind::free, BoundaryKind::symmetry, BoundaryKind::free};
  options.axisymmetric = true;
  auto solver = std::make_unique<Solver<2>>(grid, options, std::vector<SolidMaterial>{makeSolidMaterial(copper)});
  BodyFill<2> fill;
  fill.spacing = s;
  fill.velocity = Vec<2>(0.0, -c.velocity);
  fillBox<2>(solver->particles(), solver->materials()[0], fill, Vec<2>(0.0, 0.0), Vec<2>(radius, c.length));
  solver->initialise();
  return solver;
}

std::unique_ptr<Solver<3>> makeTaylorBar3d(const TaylorBarCase& c, const Material& copper, SolverOptions options) {
  const double s = c.diameter / c.particlesPerDiameter;
  const double h = c.particlesPerCell * s;
  const double radius = 0.5 * c.diameter;
  const double reach = 2.5 * radius + 2 * h;
  GridSpec<3> grid;
  grid.cellSize = h;
  grid.lower = c.quarter ? Vec<3>(0.0, 0.0, 0.0) : Vec<3>(-reach, -reach, 0.0);
  grid.upper = Vec<3>(reach, reach, c.length + 2 * h);
  const BoundaryKind side = c.quarter ? BoundaryKind::symmetry : BoundaryKind::free;
  grid.boundary = {side, BoundaryKind::free, side, BoundaryKind::free, BoundaryKind::symmetry, BoundaryKind::free};
  auto solver = std::make_unique<Solver<3>>(grid, options, std::vector<SolidMaterial>{makeSolidMaterial(copper)});
  BodyFill<3> fill;
  fill.spacing = s;
  fill.velocity = Vec<3>(0.0, 0.0, -c.velocity);
  if (c.quarter)
    fillRegion<3>(solver->particles(), solver->materials()[0], fill, Vec<3>(0, 0, 0), Vec<3>(radius, radius, c.length),
                  [&](const Vec<3>& x) { return x[0] * x[0] + x[1] * x[1] <= radius * radius; });
  else
    fillCylinder<3>(solver->particles(), solver->materials()[0], fill, Vec<3>(0, 0, 0), radius, c.length);
  solver->initialise();
  return solver;
}

template <int D>
TaylorBarShape measureTaylorBar(const Solver<D>& solver) {
  const auto& P = solver.particles();
  TaylorBarShape shape;
  const double zMin = solver.grid().lower[D - 1];  // the wall
  for (std::size_t p = 0; p < P.size(); ++p) {
    const Mat3 b = P.deformationGradient[p] * P.deformationGradient[p].transpose();
    const double halfZ = P.halfSize[p][D - 1] * std::sqrt(b(D - 1, D - 1));
    shape.length = std::max(shape.length, P.position[p][D - 1] + halfZ);
    if (P.position[p][D - 1] - zMin < P.halfSize[p][D - 1]) {  // the layer on the wall
      double r = 0;
      if constexpr (D == 2) {
        r = P.position[p][0] + P.halfSize[p][0] * std::sqrt(b(0, 0));
      } else {
        const double rc = std::hypot(P.position[p][0], P.position[p][1]);
        const double stretch = rc > 0 ? std::sqrt((P.position[p][0] * P.position[p][0] * b(0, 0) +
                                                   2 * P.position[p][0] * P.position[p][1] * b(0, 1) +
                                                   P.position[p][1] * P.position[p][1] * b(1, 1))) / rc
                                      : 1.0;
        r = rc + P.halfSize[p][0] * stretch;
      }
      shape.footprintDiameter = std::max(shape.footprintDiameter, 2.0 * r);
    }
  }
  return shape;
}

template TaylorBarShape measureTaylorBar<2>(const Solver<2>&);
template TaylorBarShape measureTaylorBar<3>(const Solver<3>&);

std::unique_ptr<Solver<2>> makePlateImpactAxisymmetric(const PlateImpactCase& c, const Material& projectile,
                                                       const Material& plate, SolverOptions options) {
  const double s = c.spacing, h = 2 * s;
  GridSpec<2> grid;
  grid.cellSize = h;
  grid.lower = Vec<2>(0.0, -c.plateThickness - 2 * h);
  grid.upper = Vec<2>(c.plateRadius + 2 * h, c.projectileLength + 2 * h);
  grid.boundary = {BoundaryKind::symmetry, BoundaryKind::free, BoundaryKind::free, BoundaryKind::free};
  options.axisymmetric = true;
  auto solver = std::make_unique<Solver<2>>(
      grid, options, std::vector<SolidMaterial>{makeSolidMaterial(projectile), makeSolidMaterial(plate)});
  BodyFill<2> fp;
  fp.spacing = s;
  fp.velocity = Vec<2>(0.0, -c.velocity);
  fillBox<2>(solver->particles(), solver->materials()[0], fp, Vec<2>(0.0, 0.0),
             Vec<2>(0.5 * c.projectileDiameter, c.projectileLength));
  BodyFill<2> ft;
  ft.spacing = s;
  ft.material = 1;
  ft.body = 1;
  fillBox<2>(solver->particles(), solver->materials()[1], ft, Vec<2>(0.0, -c.plateThickness),
             Vec<2>(c.plateRadius, 0.0));
  solver->initialise();
  return solver;
}

std::unique_ptr<Solver<3>> makePlateImpact3d(const PlateImpactCase& c, const Material& projectile,
                                             const Material& plate, SolverOptions options) {
  const double s = c.spacing, h = 2 * s;
  GridSpec<3> grid;
  grid.cellSize = h;
  grid.lower = Vec<3>(0.0, 0.0, -c.plateThickness - 2 * h);
  grid.upper = Vec<3>(c.plateRadius + 2 * h, c.plateRadius + 2 * h, c.projectileLength + 2 * h);
  grid.boundary = {BoundaryKind::symmetry, BoundaryKind::free, BoundaryKind::symmetry,
                   BoundaryKind::free, BoundaryKind::free, BoundaryKind::free};
  auto solver = std::make_unique<Solver<3>>(
      grid, options, std::vector<SolidMaterial>{makeSolidMaterial(projectile), makeSolidMaterial(plate)});
  BodyFill<3> fp;
  fp.spacing = s;
  fp.velocity = Vec<3>(0.0, 0.0, -c.velocity);
  const double r = 0.5 * c.projectileDiameter;
  fillRegion<3>(solver->particles(), solver->materials()[0], fp, Vec<3>(0, 0, 0), Vec<3>(r, r, c.projectileLength),
                [&](const Vec<3>& x) { return x[0] * x[0] + x[1] * x[1] <= r * r; });
  BodyFill<3> ft;
  ft.spacing = s;
  ft.material = 1;
  ft.body = 1;
  // A cylindrical plate so that 3D and axisymmetric runs model the same target.
  const double R = c.plateRadius;
  fillRegion<3>(solver->particles(), solver->materials()[1], ft, Vec<3>(0, 0, -c.plateThickness), Vec<3>(R, R, 0.0),
                [&](const Vec<3>& x) { return x[0] * x[0] + x[1] * x[1] <= R * R; });
  solver->initialise();
  return solver;
}

template <int D>
double penetrationDepth(const Solver<D>& solver, double plateTop) {
  const auto& P = solver.particles();
  double lowest = plateTop;
  for (std::size_t p = 0; p < P.size(); ++p)
    if (P.body[p] == 0 && P.active[p]) lowest = std::min(lowest, P.position[p][D - 1] - P.halfSize[p][D - 1]);
  return plateTop - lowest;
}

template double penetrationDepth<2>(const Solver<2>&, double);
template double penetrationDepth<3>(const Solver<3>&, double);

}  // namespace blt::sim
