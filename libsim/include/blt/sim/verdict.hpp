#pragma once
// The perforation verdict of an impact model and the measurements that go with it.
//
// Definition. The rear wall (the last layer) is PERFORATED when either
//  (a) material lies behind the wall's deformed rear surface (in a hole: behind its original rear face),
//      separated from it by at least VerdictOptions::separationCells cells and moving rearward (or gone out of
//      the grid through its rear face), with a mass of at least VerdictOptions::debrisMassFraction of the
//      projectile's mass; such material has left the wall and nothing pulls it back; or
//  (b) the wall's material, failed points included, leaves a through-thickness opening on the shot line.
// The wall's material is the largest connected piece of it (by mass): its particles' deformed domains marked
// on a voxel grid of the wall's particle spacing, connected through voxel faces. A plug or a spall fragment that
// has come loose is therefore not part of the wall, wherever it is.
// SETTLED: (a) holds (a perforation), or the kinetic energy of the whole model has fallen below
// VerdictOptions::settledKineticFraction of the initial one with neither (a) nor (b) (a stop). A run that stops
// when settled (impact.hpp) also waits, after a perforation, until the mass behind the wall and the residual
// velocity have stopped changing between two checks. A run that ends unsettled takes the verdict of its last
// state.
//
// Hole size of a layer: the opening of its intact (not failed) connected material, projected on the layer's
// plane, around the shot line; two perpendicular extents as in seed 000 Table 5 (D_h along x, in the plane of
// incidence, D_v along y). Axisymmetric runs give the diameter twice. Its opening: the same for all of its
// connected material, failed points included (where nothing of the layer is left; smaller than the hole by
// the ring of failed material around it, as a photograph of a torn fabric shows it).
// Residual velocity (perforated only): the speed of the projectile's largest connected piece when it holds at
// least half its mass (ordnance); otherwise that of the largest connected fragment behind the rear wall (a
// debris cloud).

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
  std::vector<LayerHole> holes;   // front to rear; empty unless asked for
};

// initialKinetic: the model's kinetic energy at t = 0 (J, in the model's units). measureHoles: also the hole of
// every layer (the run's stop test leaves them out).
template <int D>
PerforationVerdict assessPerforation(const ImpactModel<D>& model, const VerdictOptions& options,
                                     double initialKinetic, bool measureHoles);

}  // namespace blt::sim
