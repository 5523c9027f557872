#pragma once
// The perforation verdict of an impact model and the measurements that go with it.
//
// Definition. The rear wall (the last layer) is PERFORATED when either
//  (a) material lies behind the deformed rear surface of the wall's intact (not failed) material (where none is
//      left: behind its original rear face), separated from it by at least VerdictOptions::separationCells
//      cells and moving rearward (or gone out of the grid through its rear face), with a mass of at least
//      VerdictOptions::debrisMassFraction of the projectile's mass; such material has left the wall and nothing
//      pulls it back (failed material drawn out behind the wall does not hold it); or
//  (b) the wall's material, failed points included, leaves a through-thickness opening on the shot line.
// The wall's material is the largest connected piece of it (by mass): its particles' deformed domains marked
// on a voxel grid of the wall's particle spacing, connected through voxel faces. A plug or a spall fragment that
// has come loose is therefore not part of the wall, wherever it is.
// SETTLED: (a) holds (a perforation), or, with neither (a) nor (b) (a stop), the REARWARD kinetic energy has
// fallen below VerdictOptions::settledKineticFraction of its initial value: sum of m v_z^2 / 2 over the material
// that is not behind the wall and moves towards the rear (v_z < 0). Only that material can still load the rear
// wall; debris sliding along the plate or thrown back out of the crater (most of an oblique shot's energy, for
// tens of microseconds) cannot, and the total kinetic energy would keep such a run going to its end time. A run
// that stops when settled (impact.hpp) also waits, after a perforation, until the mass behind the wall, the
// residual velocity and every layer's hole have not changed over the last half of the time run. A "not
// perforated" stop also waits until no check over that last half was perforated: near the limit a rear wall's
// opening can close again (verdictHeld in impact.hpp). A run that ends unsettled takes the verdict of its last
// state, except that, as for a stop, a wall found perforated at any check over the last half of the run is
// perforated (perforatedLately).
//
// Hole size of a layer: the opening of its intact (not failed) connected material, projected on the layer's
// plane, around the shot line; two perpendicular extents as in seed 000 Table 5 (D_h along x, in the plane of
// incidence, D_v along y). Axisymmetric runs give the diameter twice. Its opening: the same for all of its
// connected material, failed points included (where nothing of the layer is left; smaller than the hole by
// the ring of failed material around it, as a photograph of a torn fabric shows it).
// Residual velocity (perforated only): the speed of the projectile's largest connected piece when it holds at
// least half its mass (ordnance); otherwise that of the largest connected fragment behind the rear wall (a
// debris cloud). Only while that piece moves rearward: a projectile thrown back out of an opened wall gives none (0).

#include <string>
#include <vector>

#include "blt/sim/impact_model.hpp"

namespace blt::sim {

struct LayerHole {
  std::string name;
  double horizontal = 0;  // m, D_h
  double vertical = 0;    // m, D_v
  double openingHorizontal = 0, openingVertical = 0;  // m, of all its material, failed included
};

struct PerforationVerdict {
  bool perforated = false;
  bool settled = false;
  std::string reason;             // why perforated / not, in words
  double massBehind = 0;          // kg, of the whole target (the modelled share scaled up)
  double massBehindFraction = 0;  // of the projectile's mass
  bool rearOpening = false;       // (b) above
  double residualVelocity = 0;    // m/s, 0 when nothing has come through
  double residualFragmentMass = 0;  // kg, whole: the projectile's piece or the fragment that gives it
  std::string residualFrom;         // "projectile" or "largest fragment" (empty when nothing came through)
  double kineticFraction = 0;     // kinetic energy / initial kinetic energy
  double rearwardKineticFraction = 0;  // rearward kinetic energy (SETTLED above) / its initial value
  std::vector<LayerHole> holes;   // front to rear; empty unless asked for
};

// The kinetic energies the verdict compares with, taken at t = 0 (J, in the model's units: per radian in
// axisymmetric runs, of the modelled half or quarter in 3D).
struct KineticReference {
  double total = 0;
  double rearward = 0;  // of the motion towards -z: V^2 cos^2(theta) / 2 per unit mass for the projectile
};

template <int D>
KineticReference kineticReference(const ImpactModel<D>& model);

// measureHoles: also the hole of every layer (the run's stop test leaves them out).
template <int D>
PerforationVerdict assessPerforation(const ImpactModel<D>& model, const VerdictOptions& options,
                                     const KineticReference& initial, bool measureHoles);

}  // namespace blt::sim
