#pragma once
// The solver model of an impact scenario: the grid, the materials, the projectile (body 0) and the target's
// layers (bodies 1..n, front to rear) filled with particles, and what the verdict needs to know about them.
// Geometry (data/scenarios/README.md): the target's front face is z = 0 and the layers follow towards -z; the
// projectile moves along (sin theta, 0, -cos theta). D = 2 is axisymmetric (r, z); D = 3 a half model with the
// symmetry plane y = 0, or a quarter model (also x = 0) for a normal impact.

#include <memory>
#include <string>
#include <vector>

#include "blt/sim/scenario.hpp"
#include "blt/sim/solver.hpp"

namespace blt::sim {

struct LayerBody {
  std::string name;
  int body = 0;          // solver body id (1 = front layer)
  double front = 0;      // m, z of the layer's original front face
  double rear = 0;       // m, z of its original rear face
  double spacing = 0;    // m, particle spacing
};

template <int D>
struct ImpactModel {
  std::unique_ptr<Solver<D>> solver;
  std::vector<LayerBody> layers;          // front to rear; layers.back() is the rear wall
  Vec<D> direction = Vec<D>::Zero();      // unit vector of the projectile's velocity
  Vec<D> projectileStart = Vec<D>::Zero(); // m, centre of mass at t = 0
  double projectileMass = 0;              // kg, of the modelled part (half, quarter or per radian)
  double projectileDiameter = 0;          // m
  double projectileSpacing = 0;           // m
  // 3D: symmetry planes through the shot line: y = 0 always, x = 0 too for a normal impact (quarter model).
  bool mirrorX = false, mirrorY = false;
  // Share of the whole target that the model holds: 1/2, 1/4, or 1/(2 pi) (per radian) in axisymmetric runs.
  double modelledFraction = 1.0;

  // Where the shot line (through the projectile's initial centre of mass along `direction`) crosses the
  // plane z; the in-plane coordinates (x, y; r in axisymmetric runs).
  Vec<D> shotLineAt(double z) const;
};

// Builds the model, with particles in place and the solver initialised. `threads` as SolverOptions::threads.
// Throws InputError for a material that cannot be resolved or a model with more bodies than contact allows.
template <int D>
ImpactModel<D> buildImpactModel(const ImpactScenario& scenario, int threads = 0);

}  // namespace blt::sim
