#pragma once
// Laminate equivalent model of the MLI (seed 000, §3, Eq. 1-8).
//
// The MLI blanket is a stack of thin, in-plane isotropic layers that carry no bending, so only the in-plane
// stiffness A = sum_k t_k Q_k counts (Eq. 2-3). Under a uniaxial in-plane load (N_x only, N_y = 0) the stack
// behaves as one isotropic plate of the same total thickness with an equivalent E and nu (Eq. 4).
//
// Progressive failure (Eq. 5-8) is followed under increasing strain eps_x: between two events every layer's
// stress grows with its *current* (tangent) stiffness, so the response is piecewise linear. A layer yields
// when its plane-stress von Mises stress reaches its yield stress (its Q_k is then scaled by E_t/E, Eq. 6)
// and fails when the laminate's largest principal strain reaches its failure strain (Q_k = 0). Yielded
// layers are assumed to keep loading (no unloading check): under a monotonic uniaxial pull the layer strains
// only grow.
//
// A stack is read from a TOML file (data/materials/mli_stack.toml is the MLI of seed 000); see loadStack.
// Everything here is SI (m, Pa).

#include <optional>
#include <string>
#include <vector>

#include "blt/core/materials.hpp"

namespace blt::analytic {

// The single-layer properties of seed 000 Table 2 (quasi-static tensile tests, bilinear behaviour).
struct LayerMaterial {
  std::string name;           // "aluminized film"; layers with the same name must share the properties
  double youngsModulus = 0;   // E, Pa
  double poissonRatio = 0;    // nu
  double yieldStress = 0;     // sigma_y, Pa (uniaxial; compared with the von Mises stress)
  double tangentModulus = 0;  // E_t, Pa; the post-yield slope of the layer's own stress-strain curve
  double failureStrain = 0;   // eps_f; compared with the laminate's largest principal strain
};

struct Layer {
  LayerMaterial material;
  double thickness = 0;  // t_k, m
  int line = 0;          // line of the layer in its file (0 when built in code), for messages
};

// What the equivalent material card needs that the laminate model cannot give (seed 000 Table 4).
struct CardData {
  std::string name;       // name of the written card
  std::string source;     // where density and EOS come from
  double density = 0;     // kg/m^3
  double c0 = 0;          // Mie-Grueneisen bulk sound speed, m/s
  double s = 0;           // Mie-Grueneisen slope of U_s(u_p)
  double gamma0 = 0;      // Grueneisen coefficient
};

struct Stack {
  std::string name;
  std::string source;
  std::string notes;            // free text kept with the file (e.g. why this layer order)
  std::string path;             // file it was read from ("" when built in code)
  std::vector<Layer> layers;    // in stacking order (the order does not change A, only the record)
  std::optional<CardData> card;

  double totalThickness() const;
};

// Reads a stack file. Top-level keys: name, source, notes (optional), [[layer]] tables (material, thickness,
// youngs_modulus, poisson_ratio, yield_stress, tangent_modulus, failure_strain; values with units where they
// have a dimension) and an optional [card] (name, source, density, c0, s, gamma0). There is deliberately no
// top-level 'density', so the material library skips the file. Throws InputError naming file, line and key
// for a missing file or key, a missing unit, a non-positive thickness, modulus, yield stress or failure
// strain, a Poisson ratio outside (-1, 0.5), E_t outside [0, E], or one material name with two property sets.
Stack loadStack(const std::string& path);
Stack parseStack(const std::string& text, const std::string& sourceName);
// Writes a stack file that parseStack reads back; `headerComment` lines are written as '#' comments.
std::string stackToToml(const Stack& stack, const std::string& headerComment = {});

// Equivalent isotropic properties of the stack for in-plane loading (Eq. 1-4).
struct EquivalentElastic {
  double youngsModulus = 0;  // E = (A11 A22 - A12^2) / (A22 t), Pa
  double poissonRatio = 0;   // nu = A12 / A22
  double thickness = 0;      // t = sum t_k, m
};
EquivalentElastic equivalentElastic(const std::vector<Layer>& layers);

enum class LayerEventKind { yield, failure };

// A kink of the stress-strain curve: one layer yields or fails.
struct LayerEvent {
  LayerEventKind kind = LayerEventKind::yield;
  size_t layer = 0;        // index into the stack's layers (0-based)
  std::string material;    // that layer's material name
  double strain = 0;       // laminate eps_x at the event
  double stress = 0;       // laminate average stress N_x / t just before the event, Pa
  double stressAfter = 0;  // just after (lower for a failure: the failed layer's stress is released)
};

struct CurvePoint {
  double strain = 0;    // eps_x
  double stress = 0;    // N_x / t, Pa
  std::string event;    // "" for the origin, else e.g. "yield layer 3 (aluminized film with gauze)"
};

struct LaminateResponse {
  EquivalentElastic elastic;
  // Yield stress of the equivalent material: the laminate stress at the first yield event (point a of
  // seed 000 Fig. 9). 0 when no layer yields before the first ply failure.
  double firstYieldStress = 0;
  double firstYieldStrain = 0;
  // Tangent modulus as seed 000 defines it (text after Fig. 9): the slope of the straight line from the
  // second yield point b to the first ply failure point d, (sigma_d - sigma_b) / (eps_d - eps_b), with
  // sigma_d taken just before the failure. When only one layer yields before d, the line starts at the first
  // yield point a instead; when none does, the tangent modulus is 0. `tangentFrom` says which was used.
  double tangentModulus = 0;
  std::string tangentFrom;  // "b (second yield)", "a (first yield)" or "none"
  // The first ply failure point d: the limit stress (sigma_d, before the drop) and its strain (the failure
  // strain of the equivalent material).
  double limitStress = 0;
  double failureStrain = 0;
  // Largest stress over the whole curve, for comparison: under strain control the remaining layers may
  // carry a little more after the first ply failure.
  double peakStress = 0;
  std::vector<LayerEvent> events;  // ordered by strain, until every layer has failed
  // Piecewise-linear curve: the origin, then one point per event; a failure adds a second point at the same
  // strain with the stress after the drop (the curve is driven by strain, so the drop is vertical).
  std::vector<CurvePoint> curve;

  // Stress on the curve at a strain (linear between points; after the last point 0). At a failure strain the
  // value just before the drop.
  double stressAt(double strain) const;
};

// Runs the progressive-failure analysis (Eq. 5-8). Throws std::invalid_argument for an empty stack.
LaminateResponse analyseLaminate(const std::vector<Layer>& layers);

// The equivalent material card (library format, see blt/core/materials.hpp) of an analysed stack: [elastic]
// E and nu, [strength] "bilinear" with the first-yield stress and the bd tangent modulus, [failure]
// "max-principal-strain" at the first ply failure strain, [eos] "mie-grueneisen" and the density from the
// stack's [card], and [properties] thickness, yield stress, failure strain and tensile strength (the limit
// stress). Throws InputError naming the stack file's 'card' when the stack has no [card], and when the stack
// does not yield or fail before all layers are gone (no bilinear card can describe it).
Material equivalentMaterialCard(const Stack& stack, const LaminateResponse& response, const std::string& id);

// ---- Recovering the stacking from the equivalent properties (seed 000 Table 4) -----------------------------

struct StackTarget {
  double youngsModulus = 0;  // Pa
  double poissonRatio = 0;
  double thickness = 0;      // m
};

struct StackRecoveryOptions {
  // Relative weights of the squared residuals (E/E* - 1), (nu - nu*)/nu*, (t/t* - 1).
  double weightModulus = 1.0;
  double weightPoisson = 1.0;
  double weightThickness = 1.0;
  double relativeTolerance = 1e-12;  // NLopt xtol_rel on the thicknesses
  int maxEvaluations = 20000;
};

struct StackRecovery {
  std::vector<LayerMaterial> materials;  // the distinct materials, in order of first appearance
  std::vector<double> totalThickness;    // recovered total thickness per material, m
  EquivalentElastic achieved;
  double residualModulus = 0;    // E/E* - 1
  double residualPoisson = 0;    // nu - nu*
  double residualThickness = 0;  // t/t* - 1
  int evaluations = 0;
  std::string algorithm;         // NLopt algorithm used
};

// Finds the total thickness of each material so that the stack's equivalent E, nu and t match the target
// (bounded NLopt LN_BOBYQA over [0, t*] per material, starting from an equal split; deterministic). Only the
// totals are identifiable: A depends on them, not on how a material is split into layers or ordered. E, nu
// and t are three equations for three thicknesses, so with three materials the fit is exact when a
// solution exists; the plastic figures (yield, E_t, eps_f) are then predictions, not fitted.
// Throws std::invalid_argument when there are no materials.
StackRecovery recoverStacking(const std::vector<LayerMaterial>& materials, const StackTarget& target,
                              const StackRecoveryOptions& options = {});

// The distinct materials of a stack, in order of first appearance (grouped by name).
std::vector<LayerMaterial> distinctMaterials(const std::vector<Layer>& layers);

// Lays recovered totals out on a layer pattern: every layer keeps its material and position, and each
// material's total is split equally among its layers. Throws std::invalid_argument when a material of the
// pattern is not in the recovery.
std::vector<Layer> layOut(const std::vector<Layer>& pattern, const StackRecovery& recovery);

}  // namespace blt::analytic
