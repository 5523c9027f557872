#pragma once
// An impact scenario: a projectile, a layered target, the resolution, the model mode and when to stop, read
// from a TOML file (data/scenarios/README.md gives the format) with optional `key=value` settings on top
// (`--set projectile.diameter=1.2mm`). Values carry units in the file and in settings; inside, SI. Every key
// is checked: an unknown key, a missing unit or a value out of range is an InputError naming the file and line
// (or the --set flag) and the key, and saying what is allowed.

#include <string>
#include <vector>

#include "blt/core/materials.hpp"
#include "blt/sim/solver.hpp"

namespace blt::sim {

enum class ProjectileShape { sphere, cylinder };
// Nose of a cylindrical projectile. Conical: a cone of `noseLength`; ogival: a tangent ogive whose radius is
// `noseCaliberRadius` diameters (its length follows from it); hemispherical: a half sphere of the cylinder's
// radius.
enum class NoseShape { flat, hemispherical, conical, ogival };
// automatic: axisymmetric when the impact is normal (every part here is a solid of revolution about the shot
// line then), otherwise a 3D half model with the plane of incidence as its symmetry plane.
enum class ModelMode { automatic, threeD, axisymmetric };

const char* toString(ProjectileShape s);
const char* toString(NoseShape s);
const char* toString(ModelMode m);

struct ProjectileSpec {
  ProjectileShape shape = ProjectileShape::sphere;
  NoseShape nose = NoseShape::flat;  // cylinder only
  double diameter = 0;               // m
  double length = 0;                 // m, cylinder only: overall length, nose included
  double noseLength = 0;             // m, conical nose only
  double noseCaliberRadius = 3.0;    // ogival nose only: ogive radius / diameter (CRH)
  std::string material;              // library id, a card path, or "laminate:STACK" (see resolveMaterial)
  double velocity = 0;               // m/s
  double angle = 0;                  // rad, from the target normal, in the plane of incidence (x, z)
  // rad, cylinder only: the axis's angle from the flight path, in the plane of incidence; the axis makes
  // angle + yaw with the target normal (positive: the nose turned further from the normal).
  double yaw = 0;
  // m: where the shot line meets the target's front face, along x (downrange positive) from the target's centre.
  // An oblique shot's debris runs downrange between the layers; aiming upstream keeps more of it on the model's
  // lateral extent. 3D half models only (an oblique or yawed shot).
  double aimOffset = 0;
  double spacing = 0;                // m, particle spacing; 0: resolution.particle_spacing
};

struct LayerSpec {
  std::string name;      // for output and settings (target.layer.NAME.key); defaults to "layer N"
  std::string material;  // as ProjectileSpec::material
  double thickness = 0;  // m
  double gapBefore = 0;  // m, empty space between the previous layer (or nothing, for the first) and this one
  double spacing = 0;    // m, particle spacing; 0: resolution.particle_spacing
};

struct TargetSpec {
  // m: the side of the square target in 3D, the diameter of the disc that stands for it in axisymmetric runs.
  double lateralSize = 0;
  BoundaryKind edge = BoundaryKind::nonReflecting;  // the lateral edges
  std::vector<LayerSpec> layers;                     // front (struck first) to rear; the last is the rear wall
  double totalDepth() const;                         // m, thicknesses and gaps
};

struct ResolutionSpec {
  double particleSpacing = 0;  // m, default spacing of every part
  double cellSize = 0;         // m; 0: twice the particle spacing (seed 000 sec. 5.1: 0.1 mm and 0.2 mm)
  // Shift of the grid along the target normal, as a fraction of a cell in [0, 1): the same physical model on
  // another alignment of nodes and particles. Runs at several offsets show how much of a verdict near the
  // ballistic limit is discretisation (blt sim run --ensemble).
  double gridOffset = 0;
};

// The perforation verdict (verdict.hpp) reads these.
struct VerdictOptions {
  // Material counts as behind the rear wall once it is this many cells past the wall's deformed rear surface
  // and moves rearward: it has separated and nothing will pull it back.
  double separationCells = 2.0;
  // Perforated when the mass behind the rear wall reaches this share of the projectile's mass. Not lower: a few
  // stray points of failed fabric spray must not count as a perforation.
  double debrisMassFraction = 0.05;
  // Settled without perforation once the rearward kinetic energy (verdict.hpp) has fallen below this share of
  // its initial value. Not higher: at 2 %, 2 of the 71 normal-impact runs of blt validate (seed 000, 7 and
  // 9 km/s, within 0.03 mm of d_c) stopped while the rear wall's bulge still moved at 1.5-2 % and was about to
  // shed a spall that perforates it.
  double settledKineticFraction = 0.005;
};

struct RunSpec {
  ModelMode mode = ModelMode::automatic;
  double maxTime = 0;             // s
  bool stopWhenSettled = true;    // end the run as soon as the verdict is settled
  int frames = 10;                // particle frames written over the run (with --out)
};

struct ImpactScenario {
  std::string name, description, source;
  std::string path;                    // the file it was read from
  std::vector<std::string> settings;   // the key=value settings applied on top, in order
  ProjectileSpec projectile;
  TargetSpec target;
  ResolutionSpec resolution;
  RunSpec run;
  VerdictOptions verdict;
  SolverOptions solver;                // shape function, scheme, contact, viscosity (the [solver] table)

  // The mode a run uses: `run.mode` with automatic resolved.
  ModelMode resolvedMode() const;
  double projectileSpacing() const;
  double layerSpacing(std::size_t layer) const;
  double cellSize() const;
};

// Reads a scenario file and applies `settings` ("key=value", key a dotted path such as projectile.velocity or
// target.layer.2.gap_before; layers by 1-based number or by name). A value is read as TOML when it parses
// as TOML (true, 0.3, "text") and as a string otherwise (1.2mm, al_2a12). Throws InputError.
ImpactScenario loadScenario(const std::string& path, const std::vector<std::string>& settings = {});
ImpactScenario parseScenario(const std::string& text, const std::string& sourceName,
                             const std::vector<std::string>& settings = {});

// A material by name: a library id (data/materials), a path to a card (*.toml), or "laminate:STACK", the
// equivalent card of a laminate stack (seed 000 sec. 3; STACK a library stack id such as mli_stack, or a path)
// derived by the laminate model. Throws InputError naming `where`.
Material resolveMaterial(const std::string& name, const InputLocation& where);

}  // namespace blt::sim
