#pragma once
// The explicit MPM solver: particles, a regular background grid with one velocity field per body, the
// constitutive update, contact and boundaries. The update scheme (MUSL or USL, update_scheme.hpp) calls the
// solver's stages by name; this class owns the data and the stages, nothing else. Running to an end time
// with output and instability checks is in run.hpp.
//
// D = 3: Cartesian 3D. D = 2: axisymmetric (r, z) by default (r = axis 0, the symmetry axis at r = 0 must be
// the grid's lower face on axis 0 with a symmetry boundary), or plane strain.

#include <algorithm>
#include <array>
#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "blt/sim/constitutive.hpp"
#include "blt/sim/particles.hpp"
#include "blt/sim/shape_function.hpp"

namespace blt::sim {

enum class UpdateSchemeKind { musl, usl };
enum class ContactMode { multiField, singleField };
// Which nodal velocities give a particle its strain increment in a MUSL step with the multi-field contact. The
// contact corrects the nodal velocities of the update only; the MUSL remap is not corrected.
// - perNode: the plain remap's, except at nodes the contact corrected in this step, which keep the corrected
//   velocity, the one that moved the particles. With FLIP and these strain velocities the contact cannot raise a
//   step's kinetic + internal energy, the slivers' correction aside (docs/validation/README.md, stop 43): two
//   elastic spheres rebound with at most 99.8 % of their energy, and in seed 003's T2T2 (two clamped plates in
//   contact, 150 m/s) it falls to 97.7 % by 100 us. Until stop 43 the remap was corrected as well, and the nodes
//   the update had left alone took that second correction, which no particle received: T2T2 then rose to
//   100.3 %, and T4T4T4 at 348.2 m/s gained 18 J (5 %) and went unstable at 435 us.
// - perParticle: a particle with a node of non-zero weight that the contact corrected in this step takes the
//   corrected (end-of-step grid) velocities at all its nodes, the velocities that moved it, and the others the
//   remap's. T2T2 at 150 m/s: 96.8 % at 100 us (stop 35). It takes more energy out of the plates than perNode and
//   moved the 3D and axisymmetric runs of the verification impact 7.4 % apart (stop 34), so perNode is the
//   default.
enum class ContactStrain { perNode, perParticle };
// Boundary of one grid face:
// - free: nothing imposed (material must stay inside the grid; a particle that leaves it is deactivated);
// - fixed: all velocity components zero (a clamped edge);
// - symmetry: the normal velocity is zero (a symmetry plane, the axis of an axisymmetric run, a rigid
//   frictionless wall);
// - nonReflecting: viscous dashpots, normal rho c_d and tangential rho c_s per unit area, absorb waves
//   leaving the domain (the transmitting lateral edges of seed 000 sec. 5.1).
enum class BoundaryKind { free, fixed, symmetry, nonReflecting };

const char* toString(ShapeFunctionKind k);
const char* toString(UpdateSchemeKind k);
const char* toString(BoundaryKind k);

struct ContactOptions {
  // multiField: one nodal velocity field per body, corrected where bodies meet so that they do not
  // interpenetrate but can slide and separate. singleField: all bodies share one field (they stick).
  ContactMode mode = ContactMode::multiField;
  double friction = 0.0;  // Coulomb coefficient between bodies
  ContactStrain strain = ContactStrain::perNode;
};

struct SolverOptions {
  ShapeFunctionKind shapeFunction = ShapeFunctionKind::uGimp;
  UpdateSchemeKind scheme = UpdateSchemeKind::musl;
  // dt = timeStepSafety * min over particles of cell / (c + |v|), seed 001 Eq. 8.
  double timeStepSafety = 0.3;
  // Particle velocity update: 1 = FLIP (v_p += sum N dv_I, little dissipation), 0 = PIC (v_p = sum N v_I).
  double flipFraction = 1.0;
  BulkViscosity viscosity;
  ContactOptions contact;
  // Erosion: a failed point whose volume has grown past this multiple of its initial volume is removed (made
  // inactive where it is). 0 (the default): never. At 10, the old default, it removed 57 % of the projectile's mass
  // by 12 us from a 1.4 mm, 3 km/s normal shot on the seed 000 target, and 78 % by 24 us from a 45 deg, 6 km/s
  // one (0.2 mm spacing): mass that should have loaded the wall. It is not needed for stability since expanded
  // failed material carries no pressure and inverted failed points are removed.
  double erosionExpansion = 0.0;
  // Erosion on the time step: a failed point whose sound speed exceeds this multiple of the fastest undeformed
  // wave speed of the model's materials is removed. Such points are crushed debris near the singularity of the
  // Mie-Grueneisen Hugoniot (1 - s eta -> 0; the MLI card's s = 1.4 at 0.267 g/cm3 reaches it at 0.29 of its
  // volume): at 0.1 mm in 3D their sound speed reached 230 km/s, their pressure 0.1-1 TPa (against some 60 GPa in
  // the projectile at 6 km/s), and they cut the step to a tenth. The sound speed alone is judged, not the viscosity's
  // share or the speed: shocked projectile points get those legitimately. Explicit FE codes erode on the time step
  // likewise (e.g. Ansys Explicit's "Timestep" erosion). Intact material is never removed; 0 switches it off.
  // The default of 4 is what the validation report (docs/validation) is made with: on the axisymmetric seed 000
  // runs it met Table 6 at all four speeds (9 km/s was -18 % without it) and both corrected-model plate holes of
  // Table 5 (one was +35 %), with Table 1 at 11 of 13 against 12 of 13.
  double erosionSoundSpeed = 4.0;
  // What erosion does with a point (either rule above, or a failed point turned inside out): false removes it, its
  // mass and momentum with it; true keeps it as a stress-free mass point (failed = kEroded) that still carries its
  // mass and momentum to the grid, so debris that erosion would delete still loads the layers behind, as in a
  // code without erosion (seed 000's MPM). Its last velocity, and the state it had before the step that eroded it,
  // are kept either way, so the energy history does not change at the moment of erosion. On seed 000's target it
  // hardly matters: a 3D run at the seed's 0.1 mm (0.975 mm, 6 km/s, 45 deg, 24 us) eroded 195 points, 0.1 mg of
  // MLI, and kept them to the same verdict.
  bool keepErodedMass = false;
  bool axisymmetric = true;  // D = 2 only; false gives plane strain
  // OpenMP threads; 0 keeps the OpenMP default (OMP_NUM_THREADS or all cores). Runs below 4000 particles stay
  // serial. Several runs sharing a machine should use 1 each: a thread waiting at a barrier for a descheduled
  // partner costs a whole time slice.
  int threads = 0;
};

template <int D>
struct GridSpec {
  Vec<D> lower = Vec<D>::Zero();  // m, position of node 0
  Vec<D> upper = Vec<D>::Zero();  // m, rounded up to whole cells
  double cellSize = 0;            // m
  // Faces in the order (axis 0 lower, axis 0 upper, axis 1 lower, ...).
  std::array<BoundaryKind, 2 * D> boundary{};
};

// Energies of the whole model (per radian in axisymmetric runs), J. Internal energy includes the elastic
// strain energy, the plastic work and the bulk viscosity heating; plastic and viscous work are shown apart
// as parts of it. contactDissipation and boundaryWork are the work that the multi-field contact correction (with
// the sliver correction) and the non-reflecting faces do: a particle's kinetic energy changes in a step by exactly
// m dv . (v_start + v_end) / 2, and each correction's share of dv gives its share. The contact's corrected nodal
// velocities also enter the strain increments (the MUSL remap keeps them, per node or per particle), so they
// make stress power that no force did work for; the contact tally takes that in too, as the internal forces' work
// over the corrected part of the strain velocities (-f_I . dv_I dt on the nodes, or (sigma - q) : dL V dt on the
// particles that take corrected velocities). It can be negative where the correction makes energy. Measured
// (first law: the total stays at the impact energy): an impedance-matched column across a non-reflecting face
// 100.0 %; a symmetric flyer plate across the contact 99.8 %; light spray stopped by a plate through the sliver
// correction 99.9 %; a 1 mm sphere at 3.09 km/s into seed 000's fabric target (multi-field, axisymmetric, 12 us)
// 99.8 % per-node and 100.3 % per-particle (84.4 % and 73.7 % with the kinetic shares of the main correction only);
// seed 003's T2T2 struck at 150 m/s (300 us) 100.0 % per-node (the remap corrected too, before stop 43; the
// contact then tallied -0.9 %) and 100.1 % per-particle; the same seed 000 shot in a coarse 3D quarter model
// (0.2 mm points, 5 us) 97.5 % (71.9 % before; single-field 96.6 %). USL loses energy by itself (that seed 000
// shot: 76.1 % single-field, 56.4 % multi-field with the same tally). Fixed faces and symmetry planes do no
// work. total = kinetic + internal + contact + boundary.
struct EnergyBalance {
  double kinetic = 0, internal = 0, plasticWork = 0, viscousWork = 0, contactDissipation = 0, boundaryWork = 0;
  double total() const { return kinetic + internal + contactDissipation + boundaryWork; }
};

// A particle's shape functions per axis: the weights with the stencil's first node, and apart from them the
// gradients, which grid to particles and the remap do not read (they stream half the bytes).
// size: nodes on each axis that carry weight, 2 or 3. Where a uGIMP particle's domain lies inside one cell along an
// axis, its third weight and gradient on that axis are exactly zero, and the stages skip them: material still on
// its initial lattice (two particles per cell) touches 2^D nodes, except where the rounding of its position
// leaves a sliver of weight (1e-30) on a third node, and material off it about 2.5^D, not 3^D.
template <int D>
struct Stencil {
  int node = 0;  // linear index of the stencil's first node
  std::uint8_t size[D] = {};
  double w[D][kStencil];
};
template <int D>
struct StencilGradient {
  double g[D][kStencil];
};

// The fields a particle scatters to one node of its body's field, kept together so that a scatter touches one
// record per node. gradient: sum of m_p grad N_I, for the contact normals.
template <int D>
struct ScatterNode {
  double mass = 0;
  Vec<D> momentum = Vec<D>::Zero();
  Vec<D> force = Vec<D>::Zero();
  Vec<D> gradient = Vec<D>::Zero();
};

// A box of grid nodes by index, bounds included; empty when lo > hi on an axis. The grid stages visit only the
// nodes of each body's box: in a clamped plate struck by a long rod most of the grid is empty at any step.
template <int D>
struct NodeBox {
  std::array<int, D> lo, hi;
  static NodeBox none() {
    NodeBox b;
    b.lo.fill(std::numeric_limits<int>::max());
    b.hi.fill(std::numeric_limits<int>::min());
    return b;
  }
  bool empty() const {
    for (int a = 0; a < D; ++a)
      if (lo[a] > hi[a]) return true;
    return false;
  }
  void include(const NodeBox& o) {
    for (int a = 0; a < D; ++a) {
      lo[a] = std::min(lo[a], o.lo[a]);
      hi[a] = std::max(hi[a], o.hi[a]);
    }
  }
  // Rows along axis 0: their number, and the indices of row k on the other axes.
  long rows() const {
    if (empty()) return 0;
    long r = 1;
    for (int a = 1; a < D; ++a) r *= hi[a] - lo[a] + 1;
    return r;
  }
  void rowIndex(long k, int* index) const {
    for (int a = 1; a < D; ++a) {
      const long span = hi[a] - lo[a] + 1;
      index[a] = lo[a] + static_cast<int>(k % span);
      k /= span;
    }
  }
  bool containsRow(const int* index) const {
    for (int a = 1; a < D; ++a)
      if (index[a] < lo[a] || index[a] > hi[a]) return false;
    return true;
  }
};

// Wall time spent in each stage of the step, s, summed since the solver was made (for `blt bench sim`; the
// clock is read twice a stage, a few hundred nanoseconds a step).
struct StageTimes {
  double reorder = 0, shapeFunctions = 0, particlesToGrid = 0, grid = 0, gridToParticles = 0, remap = 0, stress = 0;
};

template <int D>
class Solver {
 public:
  Solver(const GridSpec<D>& grid, const SolverOptions& options, std::vector<SolidMaterial> materials);
  ~Solver();

  Particles<D>& particles() { return particles_; }
  const Particles<D>& particles() const { return particles_; }
  const std::vector<SolidMaterial>& materials() const { return materials_; }
  const GridSpec<D>& grid() const { return spec_; }
  const SolverOptions& options() const { return options_; }
  const Eigen::Array<int, D, 1>& nodeCounts() const { return nodes_; }

  // Sizes the grid fields and caches once the particles are in place; call before the first step.
  void initialise();
  // One step of the configured update scheme. Afterwards time() has advanced by the step's dt.
  void step();

  double time() const { return time_; }
  double timeStep() const { return dt_; }  // the step about to be taken
  long stepCount() const { return steps_; }
  int bodyCount() const { return bodies_; }
  std::size_t activeParticles() const { return activeCount_; }
  const StageTimes& stageTimes() const { return stageTimes_; }
  // Each particle's stencil as the last computeShapeFunctions left it.
  const std::vector<Stencil<D>>& stencils() const { return stencil_; }
  const std::vector<StencilGradient<D>>& stencilGradients() const { return stencilGradient_; }
  EnergyBalance energies() const;
  // Bytes held by particles, grid and caches.
  std::size_t memoryBytes() const;
  // First particle with a non-finite position, velocity or stress, or -1.
  long firstNonFiniteParticle() const;
  // Whether position x lies off the grid, where computeShapeFunctions takes a point out of the model (more than
  // half a cell beyond a face, or not finite).
  bool offGrid(const Vec<D>& x) const;
  // The face a point off the grid went through: 2 axis + (0 lower, 1 upper), the axis it is farthest beyond the
  // grid along; -1 when x is on the grid or not finite.
  int exitFace(const Vec<D>& x) const;

  // Stages, called by the update scheme in its order.
  void computeShapeFunctions();  // stencils at the particles' current positions; bins particles for threads
  void particlesToGrid();        // mass, momentum, internal force, mass gradient per body
  void integrateGrid();          // nodal velocities at the end of the step, boundaries, contact
  void gridToParticles();        // particle velocities (FLIP/PIC) and positions
  void remapMomentum();          // MUSL: nodal velocities from the updated particle momenta
  void updateStress();           // velocity gradient, deformation, constitutive update, next dt
  // Erosion of point p: removed, or (keepErodedMass) made a stress-free mass point; true when it stays.
  bool erode(int p);

  // Restores the clock of a checkpoint (run.hpp); grid fields are rebuilt each step and not stored.
  void setClock(double time, long steps, double dt) { time_ = time; steps_ = steps; dt_ = dt; }
  void setEnergyTallies(double contact, double boundary) { contactDissipation_ = contact; boundaryWork_ = boundary; }
  std::pair<double, double> energyTallies() const { return {contactDissipation_, boundaryWork_}; }

 private:
  void applyVelocityConditions(bool integrate);
  void sortParticles();
  void bodyWaveSpeeds();
  // The radius the hoop terms divide by: the particle's own, but not less than its radial half-width. A point
  // that drifted onto the axis (its domain then reaches across it) would otherwise see v_r / r and V / r blow up:
  // a failed projectile point 6 um off the axis got tr D = -7e7 1/s and 1 TPa of bulk viscosity in one step.
  double hoopRadius(int p) const { return std::max(particles_.position[p][0], particles_.halfSize[p][0]); }
  template <class F>
  void scatterByColour(F&& body);
  template <class T>
  void clearInBoxes(std::vector<T>& field, const T& zero);

  GridSpec<D> spec_;
  SolverOptions options_;
  std::vector<SolidMaterial> materials_;
  Particles<D> particles_;
  std::unique_ptr<class UpdateSchemeBase> scheme_;

  // Grid: fields per body, laid out [body][node].
  Eigen::Array<int, D, 1> nodes_;
  Eigen::Array<long, D, 1> strides_;
  std::size_t nodeCount_ = 0;
  int bodies_ = 1;
  std::vector<ScatterNode<D>> scatter_;  // what particles-to-grid accumulates, one record per node and body
  std::vector<Vec<D>> velocity_, velocityChange_;
  // The MUSL remap's nodal momenta, apart from scatter_ so that its clearing and scatter stream 24 of 80 bytes.
  std::vector<Vec<D>> remappedMomentum_;
  std::vector<Vec<D>> contactDelta_, boundaryDelta_;  // velocity changes made by contact and by dashpots
  // The end-of-step (contact-corrected) nodal velocities, kept through the MUSL remap for ContactStrain::perParticle.
  std::vector<Vec<D>> correctedVelocity_;
  // Per node and body, which of contactDelta_ and boundaryDelta_ hold this step's change (kByContact,
  // kByBoundary); unmarked entries are stale. Few nodes are corrected, so grid to particles reads the deltas
  // only there, and the grid update need not clear them everywhere.
  std::vector<std::uint8_t> corrected_;
  // Per body: the nodes this step's stencils reach (computeShapeFunctions), those the last particles-to-grid
  // wrote, and their hull, which the grid stages of this step visit. Every entry outside the hull has no mass
  // and holds zeros, as nothing wrote it since it was last cleared.
  std::vector<NodeBox<D>> stencilBox_, writtenBox_, gridBox_;
  std::vector<NodeBox<D>> threadBox_;  // computeShapeFunctions' per-thread boxes, [thread][body]
  bool trackBoundary_ = false;
  std::array<bool, 2 * D> walls_{};  // faces that material may not cross (fixed, symmetry)
  std::vector<double> bodyWaveSpeed_, bodyShearSpeed_;
  std::vector<double> bodyDensity_;  // kg/m^3, of each body's material (the contact's volume shares)

  // Per-particle caches and thread bins.
  std::vector<Stencil<D>> stencil_;
  std::vector<StencilGradient<D>> stencilGradient_;
  std::vector<int> slabOf_;
  std::vector<int> order_;      // active particles sorted by slab
  std::vector<int> slabStart_;  // slab s holds order_[slabStart_[s] .. slabStart_[s+1])
  std::vector<int> cursor_;
  std::vector<long> sortKey_;
  int slabAxis_ = 0, slabCount_ = 0;
  std::size_t activeCount_ = 0;
  int threads_ = 1;
  bool parallel_ = false;

  double time_ = 0, dt_ = 0;
  long steps_ = 0;
  double massEpsilon_ = 0;
  double erosionSoundSpeedLimit_ = 0;  // m/s; failed points whose sound speed exceeds it are removed (0: never)
  double contactDissipation_ = 0, boundaryWork_ = 0;
  StageTimes stageTimes_;
};

extern template class Solver<2>;
extern template class Solver<3>;

}  // namespace blt::sim
